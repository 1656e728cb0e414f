"""vade-bench --short, in-process through the CLI: the files, and the figures in them.

The short run uses two sub-step counts (1 and 4 per 60 Hz frame), 2 s swings and flights, one
repeat. The errors below are the ones the default schemes must reach against the benchmark's
own references; timings are not asserted (the machine is shared and noisy).
"""

from __future__ import annotations

import csv
import json
import math

import pytest

from vade_replay.bench import report
from vade_replay.cli import bench


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    assert bench.main(["--short", "-o", str(out)]) == 0
    doc = json.loads((out / "physics.json").read_text())
    return out, doc


def _row(doc, motion, integrator, substeps, rate=60):
    found = [r for r in doc["rows"] if (r["motion"], r["integrator"], r["substeps"],
                                         r["rate_hz"]) == (motion, integrator, substeps, rate)]
    assert len(found) == 1, (motion, integrator, substeps)
    return found[0]


def test_files_are_written_and_agree(short_run):
    out, doc = short_run
    assert (out / "physics.csv").stat().st_size > 0
    with open(out / "physics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(doc["rows"]) > 100
    assert {r["motion"] for r in rows} == {
        "free_translation", "tumbling_box", "spinning_bar", "gear_damped", "gear_undamped",
        "gear_energy_undamped", "gear_period_undamped", "tilted_shaft_turn", "incline",
        "incline_static", "incline_across", "plane_turning_base", "plane_turning_fast",
        "incline_onset", "tilted_shaft_slide"}
    for r, j in zip(rows, doc["rows"]):
        assert float(r["ms_per_sim_s"]) == j["ms_per_sim_s"] > 0.0
    assert doc["machine"]["python"] and doc["short"] is True
    assert doc["command"].startswith("vade-bench --short")
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        assert not (out / "work_precision.png").exists()
    else:
        assert (out / "work_precision.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_best_schemes_are_accurate_against_the_references(short_run):
    _, doc = short_run
    # Free flight: the closed form to round-off; velocity Verlet is exact for constant g too.
    assert _row(doc, "free_translation", "closed_form", 1)["error"] < 1e-13
    assert _row(doc, "free_translation", "verlet", 1)["error"] < 1e-12
    assert _row(doc, "free_translation", "euler", 1)["error"] > 1e-3
    # Tumbling box, 2 s: order-6 splitting in one step per frame, RK4 in four.
    assert _row(doc, "tumbling_box", "split6", 1)["error"] < 1e-8
    assert _row(doc, "tumbling_box", "rk4", 4)["error"] < 1e-8
    assert _row(doc, "tumbling_box", "paper", 1)["error"] > 0.1      # it does not tumble
    # A flat bar spun fast about its long axis: stiff. The exact axis flows of the splitting
    # keep it at one step per frame; RK4 with four sub-steps is far off.
    bar_split = _row(doc, "spinning_bar", "split6", 1)["error"]
    assert bar_split < 1e-5
    assert _row(doc, "spinning_bar", "rk4", 4)["error"] > 10 * bar_split
    # Gear pendulum, 2 s: yoshida6 at 1/240 s (x4; the default is x2).
    for motion in ("gear_damped", "gear_undamped", "tilted_shaft_turn"):
        assert _row(doc, motion, "yoshida6", 4)["error"] < 1e-7, motion
        assert _row(doc, motion, "paper", 1)["error"] > 0.1, motion
    assert _row(doc, "gear_energy_undamped", "yoshida6", 4)["error"] < 1e-8
    assert _row(doc, "gear_period_undamped", "yoshida6", 4)["error"] < 1e-7
    # Sliding: exact under a still base, second order while it turns; never creeps.
    for motion in ("incline", "incline_across", "tilted_shaft_slide"):
        assert _row(doc, motion, "analytic", 4)["error"] < 1e-12, motion
    assert _row(doc, "plane_turning_base", "analytic", 4)["error"] < 1e-5
    # analytic4: also exact under a still base, fourth order while it turns.
    for motion in ("incline", "incline_across", "tilted_shaft_slide"):
        assert _row(doc, motion, "analytic4", 1)["error"] < 1e-12, motion
    for motion in ("plane_turning_base", "plane_turning_fast", "incline_onset"):
        assert _row(doc, motion, "analytic4", 1)["error"] < 1e-3 * _row(
            doc, motion, "analytic", 1)["error"], motion
    assert all(r["error"] == 0.0 for r in doc["rows"] if r["motion"] == "incline_static")


def test_orders_show_in_the_rows(short_run):
    _, doc = short_run
    # From 1 to 4 sub-steps the error falls by about 4^order (first order Euler: 4x).
    ratio = (_row(doc, "gear_damped", "euler", 1)["error"]
             / _row(doc, "gear_damped", "euler", 4)["error"])
    assert 2.5 < ratio < 6
    ratio = (_row(doc, "incline_across", "euler", 1)["error"]
             / _row(doc, "incline_across", "euler", 4)["error"])
    assert 3 < ratio < 5
    ratio = (_row(doc, "plane_turning_fast", "analytic4", 1)["error"]
             / _row(doc, "plane_turning_fast", "analytic4", 4)["error"])
    assert math.log(ratio, 4) > 3.7
    ratio = (_row(doc, "tumbling_box", "rk4", 1)["error"]
             / _row(doc, "tumbling_box", "rk4", 4)["error"])
    assert math.log(ratio, 4) > 3.3


def test_references_are_checked_and_far_below_the_errors_they_judge(short_run):
    _, doc = short_run
    refs = {r["motion"]: r for r in doc["references"]}
    for motion in ("tumbling_box", "gear_damped", "gear_undamped", "tilted_shaft_turn",
                   "incline_across", "plane_turning_base", "plane_turning_fast"):
        assert refs[motion]["value"] < 1e-10, motion
    # DOP853's period against the elliptic integral: the crossing finder is good to 1e-8.
    assert refs["gear_period_undamped"]["value"] < 1e-7


def test_the_defaults_on_the_goldens_sessions_are_as_accurate_as_on_the_test_motions(
        short_run):
    """Real motion (a part starting to slip as the user tilts the base, stopping, blocked)
    at the defaults, against a converged run whose own error the second one bounds."""
    from pathlib import Path
    _, doc = short_run
    rows = {r["golden"]: r for r in doc["goldens"]}
    goldens = Path(__file__).resolve().parents[1] / "recordings"
    assert set(rows) == {p.stem for p in goldens.glob("*.json")}
    for name, r in rows.items():
        assert r["converged_events_agree"] and r["events_as_converged"], name
        assert r["converged_runs_agree_m"] < 1e-7 and r["converged_runs_agree_rad"] < 1e-6, name
        assert r["position_error_m"] < 1e-7 and r["rotation_error_rad"] < 1e-6, name
    # The sliding goldens: where the onset of slipping used to cost ~1 mm.
    for name in ("plane_block_edge", "plane_block_wall", "shaft_slide_off"):
        assert 0.0 < rows[name]["position_error_m"] < 1e-8, name


def test_defaults_and_targets(short_run):
    _, doc = short_run
    defaults = {d["motion"]: d for d in doc["defaults"]}
    assert set(defaults) == {"turn", "slide", "free rotation", "free translation"}
    assert all(d["meets_bounds"] for d in defaults.values())
    assert defaults["free translation"]["chosen"] == "closed_form x1"
    targets = doc["targets"]
    assert len(targets) == 4
    assert all(set(t) >= {"target", "measured", "limit", "met"} for t in targets)
    # Accuracy targets are met whatever the machine's speed; the static block never moves.
    assert targets[3]["met"] is True and targets[1]["met"] is True


def test_pareto_rows_are_not_dominated(short_run):
    _, doc = short_run
    for r in doc["rows"]:
        if r["pareto"]:
            # JSON keeps a diverged scheme's error as "inf"
            assert not any(o["motion"] == r["motion"] and o["ms_per_sim_s"] < r["ms_per_sim_s"]
                           and float(o["error"]) < float(r["error"]) for o in doc["rows"])
    diverged = [r for r in doc["rows"] if r["motion"] == "spinning_bar"
                and r["integrator"] == "euler"]
    assert diverged and all(float(r["error"]) == float("inf") and not r["pareto"]
                            for r in diverged)


def test_writers_are_generic(tmp_path):
    rows = [{"name": "a", "x": 1.5, "ok": True}, {"name": "b", "y": float("nan")}]
    text = report.table(rows)
    assert text.splitlines()[0].split() == ["name", "x", "ok", "y"]
    report.write_csv(rows, tmp_path / "r.csv")
    report.write_json(tmp_path / "r.json", rows=rows, targets=[
        {"target": "t", "measured": 1.0, "limit": 2.0, "met": True}])
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["rows"][1]["y"] is None and doc["targets"][0]["met"] is True


def test_replay_without_its_module_is_a_clear_error(tmp_path, capsys, monkeypatch):
    import sys

    import vade_replay.bench as package
    from vade_replay.cli._common import run

    monkeypatch.setitem(sys.modules, "vade_replay.bench.replay", None)  # the import fails
    monkeypatch.delattr(package, "replay", raising=False)
    assert run(bench.main, ["--replay", "--short", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "replay benchmark is not available" in err and "Traceback" not in err


def test_bad_options_exit_2(tmp_path, capsys):
    from vade_replay.cli._common import run

    blocker = tmp_path / "file"
    blocker.write_text("")
    assert run(bench.main, ["--short", "-o", str(blocker / "sub")]) == 2
    assert run(bench.main, ["--repeats", "0", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("error:") == 2


def test_a_diverged_run_is_never_on_the_front_even_when_fastest():
    """A scheme that blew up stops computing (its numbers are NaN), so it can time as the
    fastest row of its motion; the front must still leave it out (a CI run found this)."""
    from vade_replay.bench.physics import _mark_pareto
    rows = [{"motion": "m", "ms_per_sim_s": 0.01, "error": float("inf")},
            {"motion": "m", "ms_per_sim_s": 0.10, "error": 1e-3},
            {"motion": "m", "ms_per_sim_s": 0.20, "error": 1e-6},
            {"motion": "m", "ms_per_sim_s": 0.30, "error": 1e-3}]
    _mark_pareto(rows)
    assert [r["pareto"] for r in rows] == [False, True, True, False]
