"""vade-bench --instructions: callgrind's dumps read in order, the stages' arithmetic, a
clear error without valgrind, and (``VADE_STRESS=full``, with valgrind) a real count that
repeats."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from types import SimpleNamespace

import pytest

from conftest import RECORDINGS
from strategies import FULL
from vade_replay.bench import instructions
from vade_replay.cli import bench
from vade_replay.cli._common import run
from vade_replay.errors import VadeError


def _dump(path, total: int) -> None:
    # The head of a callgrind dump, as valgrind 3.19 writes it.
    path.write_text(f"# callgrind format\nversion: 1\ncreator: callgrind-3.19.0\n"
                    f"cmd: python\npart: 1\n\nevents: Ir\n\nsummary: {total}\n\n"
                    f"fn=main\n1 {total}\n\ntotals: {total}\n")


def test_dumps_are_read_in_the_order_callgrind_wrote_them(tmp_path):
    prefix = tmp_path / "callgrind.out"
    # .10 after .9 (not after .1, as the names sort), the unnumbered file last.
    for k in range(1, 12):
        _dump(tmp_path / f"callgrind.out.{k}", 1000 * k)
    _dump(prefix, 7)
    (tmp_path / "callgrind.out.notes").write_text("not a dump")
    assert instructions.dump_totals(prefix) == [1000 * k for k in range(1, 12)] + [7]


def test_a_dump_without_a_total_is_an_error(tmp_path):
    prefix = tmp_path / "callgrind.out"
    (tmp_path / "callgrind.out.1").write_text("# callgrind format\nevents: Ir\n")
    with pytest.raises(RuntimeError, match=r"callgrind.out.1: no instruction total"):
        instructions.dump_totals(prefix)


def test_each_stage_is_its_own_dump_and_the_step_is_what_stepping_adds():
    # warm-up, then per session: floor, open, setup, frames, stepped, replay; then the rest.
    totals = [10**9,
              1000, 50, 250, 400, 900, 1500,     # a: 10 frames
              2000, 20, 80, 800, 1700, 3000,     # b: 20 frames
              5]
    a, b = instructions.rows_from(["a", "b"], [10, 20], totals)
    assert (a["session"], a["frames"]) == ("a", 10)
    assert a["setup"] == 300  # the open and the scene, once
    assert a["floor_per_frame"] == 100 and a["frames_read_per_frame"] == 40
    # Stepping counted once: what it adds to opening, setting up and reading.
    assert a["step_per_frame"] == (900 - 50 - 250 - 400) / 10 == 20
    assert a["check_and_loop_per_frame"] == (1500 - 900) / 10
    assert a["replay_per_frame"] == 150
    assert a["replay_over_floor"] == 1.5 and a["after_setup_over_floor"] == 1.2
    assert b["step_per_frame"] == (1700 - 100 - 800) / 20 and b["replay_over_floor"] == 1.5
    # One dump more or fewer than the stages make (a stray marker call, other valgrind
    # options) shifts every stage: refused.
    for wrong in (totals[:-1], totals + [7]):
        with pytest.raises(VadeError, match=f"callgrind wrote {len(wrong)} dumps where 14 "
                                            "were expected"):
            instructions.rows_from(["a", "b"], [10, 20], wrong)


def test_the_script_marks_each_stage_once_and_replays_what_it_counts(tmp_path):
    """The script callgrind runs, run as plain Python with the marker counted: one marker
    after the warm-up and one after each stage of each recording, and the frame counts of
    replays that matched."""
    paths = [str(RECORDINGS / "drop_on_table.mcap"), str(RECORDINGS / "tumbling_box.mcap")]
    wrapper = ("import zlib\nmarks = [0]\n_adler = zlib.adler32\n"
               "def counted(data):\n    marks[0] += 1\n    return _adler(data)\n"
               "zlib.adler32 = counted\n"
               f"exec(compile({instructions._SCRIPT!r}, 'script', 'exec'))\n"
               "print(marks[0])\n")
    done = subprocess.run([sys.executable, "-c", wrapper, *paths], capture_output=True,
                          text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    frames, marks = done.stdout.strip().splitlines()[-2:]
    assert json.loads(frames) == [151, 181]
    assert int(marks) == 1 + len(instructions.STAGES) * len(paths)


def test_without_valgrind_it_says_so_and_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(instructions, "shutil", SimpleNamespace(which=lambda name: None))
    code = run(bench.main, ["--instructions", "--short", "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "--instructions" in err and "valgrind" in err and "Traceback" not in err
    assert not (tmp_path / "instructions.json").exists()


@pytest.mark.stress
@pytest.mark.skipif(not FULL, reason="two runs under valgrind, ~2 min: VADE_STRESS=full")
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind")
def test_a_count_repeats_and_its_stages_add_up(tmp_path):
    """Two counts of the same golden in separate processes (hash seed fixed): the per-frame
    figures agree within 1 % (seen: equal, or 0.05-0.3 % apart, where timed runs move by a
    third); every stage is there and none is negative."""
    path = RECORDINGS / "drop_on_table.mcap"
    first, = instructions.count([path])
    second, = instructions.count([path])
    per_frame = [k for k in first if k.endswith("_per_frame")]
    for k in per_frame:
        assert abs(first[k] - second[k]) <= 0.01 * first[k], (k, first[k], second[k])
    assert first["frames"] == 151 and first["setup"] > 0
    assert all(first[k] > 0 for k in per_frame)
    # A replay does at least what reading does, and more than stepping alone adds.
    assert first["replay_per_frame"] > first["floor_per_frame"]
    assert first["replay_per_frame"] > first["step_per_frame"] + first["check_and_loop_per_frame"]
    json.dumps(first)  # the row is what the JSON file holds


def _row(session: str, scale: float = 1.0) -> dict:
    return {"table": "instructions", "session": session, "frames": 10,
            **{k: int(1000 * scale) for k in instructions.COMPARED}}


def test_against_gives_each_stage_as_a_ratio_to_the_count_before(tmp_path):
    path = tmp_path / "instructions.json"
    path.write_text(json.dumps({"rows": [_row("a"), _row("gone")]}))
    before = instructions.earlier(path)
    new = _row("a", 0.9)
    new["step_per_frame"] = 1100
    a, b = instructions.against([new, _row("new")], before)
    assert a["step_vs_before"] == 1.1 and a["replay_vs_before"] == 0.9
    assert a["setup_vs_before"] == 0.9 and a["check_and_loop_vs_before"] == 0.9
    assert not any(k.endswith("_vs_before") for k in b)  # not counted before
    assert instructions.unmatched([new, _row("new")], before) == ["new"]
    zero = {"a": {**_row("a"), "setup": 0}}
    assert instructions.against([_row("a")], zero)[0]["setup_vs_before"] is None


def test_the_resting_parts_ratio_is_the_crowds_count_over_the_lone_parts():
    # The moving part alone: 100 frames, 4,000 instructions of setup; among 200 resting
    # parts: 30,000 of setup.
    alone = {"session": "one_moving_0_resting", "frames": 100, "setup": 4000,
             "replay_per_frame": 200, "step_per_frame": 50}
    crowd = {"session": f"one_moving_{instructions.RESTING}_resting", "frames": 100,
             "setup": 30000, "replay_per_frame": 500, "step_per_frame": 60}
    ratio = instructions.resting_ratio([_row("a"), alone, crowd])
    assert ratio == {"replay": 2.5, "after_setup": (500 - 300) / (200 - 40), "step": 1.2}
    assert instructions.resting_ratio([_row("a"), alone]) is None
    idle = instructions.resting_ratio([{**alone, "step_per_frame": 0}, crowd])
    assert idle["step"] is None and idle["replay"] == 2.5


@pytest.mark.parametrize("text, says", [
    (None, "cannot read it"),
    ("{not json", "is not JSON"),
    (json.dumps({"rows": [{"table": "end_to_end", "session": "a"}]}), "is not the instructions"),
    (json.dumps({"rows": [{**_row("a"), "step_per_frame": 1.5}]}), "is not the instructions"),
    (json.dumps([1, 2]), "is not the instructions"),
])
def test_an_unusable_earlier_count_is_refused_before_any_counting(tmp_path, monkeypatch,
                                                                   capsys, text, says):
    path = tmp_path / "old.json"
    if text is not None:
        path.write_text(text)
    monkeypatch.setattr(instructions, "run", lambda *a, **k: pytest.fail("counted"))
    code = run(bench.main, ["--instructions", "--against", str(path), "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and str(path) in err and "--against" in err and says in err
    assert "Traceback" not in err


def test_against_needs_instructions_and_repeats_is_refused_with_it(tmp_path, capsys):
    code = run(bench.main, ["--replay", "--against", "x.json", "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "--against" in err and "--instructions" in err
    code = run(bench.main, ["--instructions", "--repeats", "3", "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "--repeats" in err and "Traceback" not in err


def test_a_python_whose_marker_callgrind_cannot_see_is_named(monkeypatch):
    # As with a stripped interpreter: the probe's two marker calls make no dumps.
    monkeypatch.setattr(instructions, "_callgrind", lambda script, args: ("", [123]))
    with pytest.raises(VadeError, match="callgrind cannot see zlib_adler32") as info:
        instructions.probe()
    assert info.value.field == "--instructions"
