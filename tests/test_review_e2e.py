"""vade-replay --rerun on real recordings: the review holds what the recording holds."""

from __future__ import annotations

import pytest

pytest.importorskip("rerun")

from conftest import RECORDINGS, run_cli  # noqa: E402
from mcap_edit import nudge_pose  # noqa: E402
from test_view import read_rrd, rows  # noqa: E402
from vade_replay.recording import Recording  # noqa: E402
from vade_replay.replay import recorded_records  # noqa: E402


def _transitions(path):
    out = {}
    for frame in recorded_records(Recording(path)):
        for event in frame.events:
            if event.kind == "ModeChanged":
                out.setdefault(event.part, []).append((frame.frame, event.to_mode))
    return out


def test_review_of_a_matching_replay(tmp_path):
    golden = RECORDINGS / "throw_and_catch.mcap"
    rrd = tmp_path / "review.rrd"
    result = run_cli("vade-replay", str(golden), "--rerun", str(rrd))
    assert result.returncode == 0, result.stderr
    store = read_rrd(rrd)
    frames = Recording(golden).frame_count
    poses = rows(store, "/world/recorded/parts/cylinder", "Transform3D:translation")
    assert len(poses) == frames
    lane = rows(store, "/states/recorded/cylinder", "StateChange:state")
    assert lane == [(0, "STATIC")] + _transitions(golden)["cylinder"]
    assert "/markers/divergence" not in store  # nothing diverged, nothing marked


def test_the_energy_plot_is_conserved_in_free_flight_under_its_scaled_gravity(tmp_path):
    """A researcher's trial: the review's potential energy took full g while a part flies
    under ``gravity_scale_free`` (0.25), so a throw's plotted total rose 26 % to its apex
    with nothing acting on it. In flight the total is now constant: 0.5 m v^2 + 0.5 w.I.w
    - m (0.25 g).x_cm for the golden's thrown cylinder, to round-off."""
    golden = RECORDINGS / "throw_and_catch.mcap"
    rrd = tmp_path / "review.rrd"
    assert run_cli("vade-replay", str(golden), "--rerun", str(rrd)).returncode == 0
    store = read_rrd(rrd)
    total = dict(rows(store, "/plots/energy/recorded/cylinder/total", "Scalars:scalars"))
    flying = [r.frame for r in recorded_records(Recording(golden))
              for p in r.parts if p.name == "cylinder" and p.mode == "INSPACE"]
    assert len(flying) > 20
    # (The first flying frame's snapshot is at the release: its velocity the fit's.)
    values = [total[f] for f in flying[1:]]
    assert max(values) - min(values) < 1e-9 * max(abs(v) for v in values), values
    # Held, the plot still takes full g: the potential changes scale at the release.
    potential = dict(rows(store, "/plots/energy/recorded/cylinder/potential", "Scalars:scalars"))
    held = flying[0] - 1
    assert potential[held] != pytest.approx(potential[flying[0]], rel=0.5)


def test_review_marks_the_first_divergence(tmp_path):
    target = 90
    tampered = tmp_path / "t.mcap"
    nudge_pose(RECORDINGS / "drop_on_table.mcap", tampered, frame=target, axis=0, delta=1e-9)
    rrd = tmp_path / "diverged.rrd"
    result = run_cli("vade-replay", str(tampered), "--rerun", str(rrd))
    assert result.returncode == 1
    store = read_rrd(rrd)
    assert rows(store, "/markers/divergence", "StateChange:state") == [(target, "DIVERGED")]
    ghost = rows(store, "/world/replayed/parts/peg", "Transform3D:translation")
    assert ghost and ghost[0][0] == target


def test_what_if_review_shows_both_runs_and_their_difference(tmp_path):
    rrd = tmp_path / "whatif.rrd"
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--set",
                     "physics.gravity_scale_free=1.0", "--rerun", str(rrd))
    assert result.returncode == 0, result.stderr
    store = read_rrd(rrd)
    whatif = [e for e in store if e.startswith("/world/what_if/parts/peg")]
    assert whatif, sorted(store)
    diff = rows(store, "/plots/difference/position_m/peg", "Scalars:scalars")
    assert len(diff) == 151
    # Identical until the release, then the full-gravity drop pulls away.
    assert all(v == [0.0] or v == 0.0 for f, v in diff if f <= 84)
    assert max((v[0] if isinstance(v, list) else v) for _, v in diff) > 0.01


def test_session_colours_reach_the_review(tmp_path):
    # drop_on_table.json colours the peg (70, 130, 220) and the table (150, 110, 70).
    rrd = tmp_path / "c.rrd"
    assert run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--rerun",
                   str(rrd)).returncode == 0
    store = read_rrd(rrd)
    peg = rows(store, "/world/recorded/parts/peg", "Mesh3D:albedo_factor", static=True)
    table = rows(store, "/world/environment/table", "Mesh3D:albedo_factor", static=True)
    assert peg == [(None, 0x4682DCFF)] and table == [(None, 0x966E46FF)]
