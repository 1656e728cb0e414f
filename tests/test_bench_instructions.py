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
from vade_replay import native
from vade_replay.bench import instructions
from vade_replay.cli import bench
from vade_replay.cli._common import run
from vade_replay.errors import VadeError


ROOT = RECORDINGS.parent


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


def test_objects_made_are_the_calls_to_new_reference_followed_across_dumps(tmp_path):
    """Callgrind names a function once, ``cfn=(7) name``, then ``cfn=(7)``, in the same dump
    or a later one: every call of ``_Py_NewReference`` counted in the dump it ran in, from
    any caller, and nothing else's calls."""
    prefix = tmp_path / "callgrind.out"
    (tmp_path / "callgrind.out.1").write_text(
        "events: Ir\nsummary: 100\n"
        "fn=(1) PyFloat_FromDouble\n3 40\n"
        "cfn=(2) _Py_NewReference\ncalls=5 10\n3 50\n"
        "cfn=(3) PyTuple_New\ncalls=7 10\n3 70\n"
        "fn=(4) main\n1 10\n"
        "cfn=(2)\ncalls=2 10\n1 20\n")
    (tmp_path / "callgrind.out.2").write_text(
        "events: Ir\nsummary: 100\n"
        "fn=(3)\n1 5\n"
        "cfn=(2)\ncalls=11 10\n1 20\n"
        "cfn=(1)\ncalls=13 10\n1 20\n"
        # (uncompressed names, as with --compress-strings=no)
        "fn=tuple_alloc\n1 5\ncfn=_Py_NewReference\ncalls=17 10\n1 20\n")
    prefix.write_text("events: Ir\nsummary: 1\nfn=(4)\n1 1\n")
    assert instructions.dump_calls(prefix) == [5 + 2, 11 + 17, 0]
    assert instructions.dump_calls(prefix, "PyTuple_New") == [7, 0, 0]


def test_objects_are_given_to_the_code_that_asked_for_them():
    """An allocator's objects go to its callers in proportion to their calls, up through
    any depth of C helpers, and stop at this package's compiled code or the interpreter's
    loop; a maker with no callers keeps its own. Only the dump asked for counts."""
    arcs = [
        # dump 1: 10 floats boxed, 7 of them by turn, 3 by the encoder
        (1, "PyFloat_FromDouble", "_Py_NewReference", 10),
        (1, "CPyDef_vade_replay___dynamics___onbase___turn", "PyFloat_FromDouble", 7),
        (1, "CPyDef_vade_replay___codec___FrameEncoder____by_numbers", "PyFloat_FromDouble", 3),
        # 4 tuples: tuple_alloc <- PyTuple_New <- (step 3, the interpreter 1)
        (1, "tuple_alloc", "_Py_NewReference", 4),
        (1, "PyTuple_New", "tuple_alloc", 4),
        (1, "CPyDef_vade_replay___step___step", "PyTuple_New", 3),
        (1, "_PyEval_EvalFrameDefault'2", "PyTuple_New", 1),
        # compiled code making its own, and a maker nobody is seen calling
        (1, "CPyDef_vade_replay___step___frame_record", "_Py_NewReference", 5),
        (1, "0x0000000000012df0", "_Py_NewReference", 2),
        # another dump's calls are not this one's
        (0, "PyFloat_FromDouble", "_Py_NewReference", 1000),
        (2, "CPyDef_vade_replay___step___step", "_Py_NewReference", 1000),
    ]
    made = instructions.objects_by_function(arcs, 1)
    assert made == {"CPyDef_vade_replay___dynamics___onbase___turn": 7,
                    "CPyDef_vade_replay___codec___FrameEncoder____by_numbers": 3,
                    "CPyDef_vade_replay___step___step": 3, "_PyEval_EvalFrameDefault'2": 1,
                    "CPyDef_vade_replay___step___frame_record": 5, "0x0000000000012df0": 2}
    # A cycle among helpers ends after the levels given, with what is left where it is.
    loop = [(0, "a", "_Py_NewReference", 6), (0, "b", "a", 1), (0, "a", "b", 1)]
    assert sum(instructions.objects_by_function(loop, 0, levels=3).values()) == 6


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
    # The objects each stage made, by the same arithmetic.
    objects = [10**6, 300, 5, 25, 40, 90, 160, 600, 2, 8, 80, 170, 330, 1]
    a, b = instructions.rows_from(["a", "b"], [10, 20], totals, objects)
    assert a["floor_objects_per_frame"] == 30 and a["frames_read_objects_per_frame"] == 4
    assert a["step_objects_per_frame"] == (90 - 30 - 40) / 10
    assert a["check_and_loop_objects_per_frame"] == (160 - 90) / 10
    assert a["replay_objects_per_frame"] == 16 and a["replay_objects_over_floor"] == 160 / 300
    assert b["replay_objects_over_floor"] == 330 / 600
    # A Python whose objects callgrind cannot see being made: no object columns at all.
    a, _ = instructions.rows_from(["a", "b"], [10, 20], totals, [0] * len(totals))
    assert "replay_objects_per_frame" not in a
    with pytest.raises(VadeError, match="callgrind wrote"):
        instructions.rows_from(["a", "b"], [10, 20], totals, objects[:-1])
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
    build, frames, marks = done.stdout.strip().splitlines()[-3:]
    assert json.loads(build) == native.describe()  # the build it ran, to hold to the parent's
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
    # The objects a frame: counted (this Python makes them through _Py_NewReference), each
    # stage's repeating within 1 %, and a replay makes more than reading alone.
    assert first["replay_objects_per_frame"] > first["floor_objects_per_frame"] > 0
    for k in [k for k in first if k.endswith("_objects_per_frame")]:
        assert abs(first[k] - second[k]) <= 0.01 * abs(first[k]) + 0.1, (k, first[k], second[k])
    json.dumps(first)  # the row is what the JSON file holds


@pytest.mark.stress
@pytest.mark.skipif(not FULL, reason="a replay under valgrind, ~20 s: VADE_STRESS=full")
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind")
def test_the_census_of_a_real_replay_names_this_package_s_code():
    """``tools/object_census.py``'s count: every object of a replay given to someone, a
    good part of them to this package's compiled functions (in this one-part golden ~half:
    the interpreted reader and loop, and the setup spread over 151 frames, make the rest),
    about as many a frame as the count by stage makes of a replay."""
    path = RECORDINGS / "drop_on_table.mcap"
    frames, made = instructions.census(path)
    assert frames == 151
    total = sum(made.values())
    ours = sum(n for name, n in made.items() if name.startswith("CPyDef_vade_replay"))
    assert ours > 0.3 * total
    assert any(name.startswith("_PyEval_EvalFrameDefault") for name in made)
    row, = instructions.count([path])
    # (The census replays once after a warm-up; the count's replay stage opens and sets up
    # the same way: within a tenth.)
    assert abs(total / frames - row["replay_objects_per_frame"]) <= \
        0.1 * row["replay_objects_per_frame"]


def test_the_census_tool_refuses_what_is_not_a_recording(tmp_path):
    bad = tmp_path / "notes.mcap"
    bad.write_text("not a recording")
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "object_census.py"), str(bad)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and str(bad) in done.stderr
    assert "Traceback" not in done.stderr


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
    monkeypatch.setattr(instructions, "_callgrind", lambda script, args: ("", [123], [0]))
    with pytest.raises(VadeError, match="callgrind cannot see zlib_adler32") as info:
        instructions.probe()
    assert info.value.field == "--instructions"


def test_a_count_by_another_build_than_this_one_is_refused(monkeypatch):
    """A session's count gave the step ~7x its instructions, quietly: a compiled module's
    source was edited while valgrind ran, and the counted process, finding the build stale,
    ran the sources (``native.install_switch``). The build the counted process ran is held
    to this one's."""
    here = native.describe()
    monkeypatch.setattr(instructions, "_callgrind", lambda script, args: (
        json.dumps("pure Python (stale: vade_replay/scene.py)") + "\n[151]\n", [1] * 8, [0] * 8))
    with pytest.raises(VadeError, match="the counted process ran 'pure Python") as info:
        instructions.count([RECORDINGS / "drop_on_table.mcap"])
    assert info.value.field == "--instructions" and here in info.value.message
