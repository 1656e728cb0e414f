"""Bad input: one clear line naming the file, field or frame; exit code 2; no traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import RECORDINGS, run_cli
from vade_replay.recording import Recording
from mcap_edit import copy_recording


def _assert_clean_error(result, *needles):
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert "Traceback" not in result.stderr
    assert result.stderr.startswith("error: ")
    for needle in needles:
        assert needle in result.stderr, result.stderr


def _write(tmp_path: Path, doc) -> Path:
    path = tmp_path / "s.json"
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


def _doc():
    return json.loads((RECORDINGS / "drop_on_table.json").read_text())


def test_missing_session_file(tmp_path):
    # As a real process: the user sees one line, not a traceback.
    _assert_clean_error(run_cli("vade-record", str(tmp_path / "nope.json"), process=True),
                        "nope.json")


def test_session_not_json(tmp_path):
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, "{oops"))), "s.json", "JSON")


def test_a_tracker_log_given_for_its_session_says_what_it_is(tmp_path):
    """A researcher's trial: ``vade-record log.csv`` (the log, not its session) read "not
    valid JSON: Expecting value". It says it is a tracker log and where one goes."""
    for header in ("time,device,x,y,z,q0,q1,q2,q3,grip", "t;device;x;y;z;q0;q1;q2;q3;grip"):
        log = tmp_path / "p01.csv"
        log.write_text(header + "\n0.0,right_hand,0,0,1,0,0,0,1,0\n")
        result = run_cli("vade-record", str(log), "-o", str(tmp_path / "o.mcap"))
        _assert_clean_error(result, f"{log}: this is a tracker log (CSV), not a session file",
                            '("tracker": {"csv": "p01.csv", ...})')
        assert not (tmp_path / "o.mcap").exists()


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d["parts"][0]["shape"].pop("size"), "parts[0].shape"),
    (lambda d: d["tracker"].update(rate_hz=0), "tracker.rate_hz"),
    (lambda d: d.update(units="furlong"), "units"),
    (lambda d: d["parts"][0].update(density=-1), "parts[0].density"),
])
def test_invalid_session_names_the_field(tmp_path, mutate, field):
    doc = _doc()
    mutate(doc)
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))), "s.json", field)


def test_bad_mesh_file_is_named(tmp_path):
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "mesh", "file": "broken.stl"}
    (tmp_path / "broken.stl").write_bytes(b"solid nothing\nendsolid\n")
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))), "broken.stl")


def test_existing_output_survives_a_bad_session(tmp_path):
    out = tmp_path / "keep.mcap"
    out.write_bytes(b"precious")
    doc = _doc()
    doc["parts"][0]["shape"].pop("size")
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(out)))
    assert out.read_bytes() == b"precious"


def test_not_a_recording(tmp_path):
    path = tmp_path / "x.mcap"
    path.write_bytes(b"not an mcap file at all")
    _assert_clean_error(run_cli("vade-replay", str(path), process=True), "x.mcap")
    _assert_clean_error(run_cli("vade-replay", str(tmp_path / "missing.mcap")), "missing.mcap")


def test_truncated_recording_keeps_what_it_holds(tmp_path):
    """A crash loses at most the last second: the complete chunks before it still replay."""
    data = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    path = tmp_path / "cut.mcap"
    path.write_bytes(data[: len(data) * 2 // 3])
    result = run_cli("vade-replay", str(path), "--json")
    assert result.returncode == 0, result.stderr
    assert "cut.mcap" in result.stderr and "cut short" in result.stderr
    summary = json.loads(result.stdout)
    assert summary["truncated"] is True and summary["match"] is True
    # 151 frames in 2.5 s, chunks closed every second: at least one second survives.
    assert 60 <= summary["frames"] < 151
    path.write_bytes(data[:600])
    _assert_clean_error(run_cli("vade-replay", str(path)), "cut.mcap")


def test_flipped_bytes_in_compressed_chunks_never_give_a_traceback(tmp_path):
    """Damage inside a zstd chunk (a bad disk, a bad copy) is a damaged file, not a crash:
    the frames before it replay and the file is reported cut short, or it is unusable."""
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    path = tmp_path / "flipped.mcap"
    start = data.index(b"\x28\xb5\x2f\xfd")  # the first zstd frame (a chunk's data)
    for offset in range(start + 20, start + 620, 60):
        damaged = bytearray(data)
        damaged[offset] ^= 0xFF
        path.write_bytes(bytes(damaged))
        result = run_cli("vade-replay", str(path))
        assert "Traceback" not in result.stderr, result.stderr
        assert result.returncode in (0, 1, 2), result.stderr
        if result.returncode == 2:
            assert "flipped.mcap" in result.stderr


# What orjson refuses (NaN, a number past float64, an integer past 64 bits) json reads,
# and the check after it names the field either way.
@pytest.mark.parametrize("bad", ["x", float("nan"), 10**30, "1e400"])
def test_malformed_tracker_message_names_the_frame(tmp_path, bad):
    def edit(topic, index, data):
        if topic == "/tracker" and index == 42:
            msg = json.loads(data)
            msg["devices"]["right_hand"]["position"] = [0.0, "@", 1.0]
            # json writes NaN as the token NaN; a number past float64 is spliced in as text.
            return json.dumps(msg).replace('"@"', bad if bad == "1e400"
                                           else json.dumps(bad)).encode()
        return data

    path = tmp_path / "bad_input.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", path, edit)
    _assert_clean_error(run_cli("vade-replay", str(path)), "bad_input.mcap", "frame 42",
                        "right_hand.position")


@pytest.mark.parametrize("also", [b"", b',"x":NaN'])  # NaN: orjson gives up, json reads it
def test_a_frame_number_past_64_bits_is_refused_naming_the_frame_field(tmp_path, also):
    def edit(topic, index, data):
        if topic == "/tracker" and index == 42:
            return data.replace(b'"frame":42', b'"frame":100000000000000000000000' + also)
        return data

    path = tmp_path / "bad_frame.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", path, edit)
    _assert_clean_error(run_cli("vade-replay", str(path)), "bad_frame.mcap", "/tracker",
                        "frame")


def test_recording_without_its_session(tmp_path):
    path = tmp_path / "nosession.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", path, lambda t, i, d: d,
                   drop_attachments=("session.json",))
    _assert_clean_error(run_cli("vade-replay", str(path)), "nosession.mcap", "session")


@pytest.mark.parametrize("setting, needle", [
    ("physics.no_such=1", "physics.no_such"),
    ("physics.gravity_scale_free=fast", "physics.gravity_scale_free"),
    ("gravity=1", "gravity"),
    ("physics.free_rotation=spin", "physics.free_rotation"),
])
def test_bad_set_override(setting, needle):
    _assert_clean_error(run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"),
                                "--set", setting), needle)


def test_what_if_replay_runs_and_leaves_the_original_alone(tmp_path):
    golden = RECORDINGS / "drop_on_table.mcap"
    before = golden.read_bytes()
    out = tmp_path / "whatif.mcap"
    result = run_cli("vade-replay", str(golden), "--set", "physics.gravity_scale_free=1.0",
                     "--json", "-o", str(out))
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["overrides"] == {"physics.gravity_scale_free": 1.0}
    assert summary["match"] is False  # full gravity: the drop differs from the recording
    assert golden.read_bytes() == before
    assert out.exists()


def test_a_bad_row_of_a_tracker_log_is_an_error_before_anything_is_recorded(tmp_path):
    """A researcher's trial: a bad row was found only when the run reached it, and the
    ``.partial`` of the frames before it refused the corrected run. The log is read
    through first: the row is named, nothing is written (an older file at the output is
    kept), and the corrected log records at once. (A run that fails part way for another
    reason keeps its frames: ``test_batched_replay``.)"""
    from test_session import CSV, _csv_doc

    doc = _csv_doc()
    (tmp_path / "log.csv").write_text(CSV + "2.5,right_hand,0,0,oops,1,0,0,0,0\n")
    out = tmp_path / "run.mcap"
    out.write_bytes(b"an older recording")
    session = str(_write(tmp_path, doc))
    # (Not a recording of this session: without --force it is refused before the run.)
    refused = run_cli("vade-record", session, "-o", str(out))
    _assert_clean_error(refused, str(out), "not a readable recording", "--force")
    result = run_cli("vade-record", session, "-o", str(out), "--force")
    # The log named where it is, beside the session (a user's trial: bare "log.csv").
    _assert_clean_error(result, f"{tmp_path / 'log.csv'}: line 10")
    assert out.read_bytes() == b"an older recording"  # not clobbered
    assert not (tmp_path / "run.mcap.partial").exists() and "kept" not in result.stderr
    (tmp_path / "log.csv").write_text(CSV + "2.5,right_hand,0,0,0.8,1,0,0,0,0\n")
    fixed = run_cli("vade-record", session, "-o", str(out), "--force")
    assert fixed.returncode == 0, fixed.stderr
    replayed = run_cli("vade-replay", str(out), "--json")
    assert replayed.returncode == 0, replayed.stderr
    assert json.loads(replayed.stdout)["frames"] == 8


def test_output_paths_that_cannot_be_written(tmp_path):
    (tmp_path / "afile").write_text("x")
    session = str(RECORDINGS / "drop_on_table.json")
    golden = str(RECORDINGS / "drop_on_table.mcap")
    _assert_clean_error(run_cli("vade-record", session, "-o", str(tmp_path / "afile" / "x.mcap")),
                        "afile is a file")
    _assert_clean_error(run_cli("vade-record", session, "-o", str(tmp_path)), "is a folder")
    assert not list(tmp_path.glob("*.partial"))
    _assert_clean_error(run_cli("vade-replay", golden, "-o", str(tmp_path / "afile" / "y.mcap")),
                        "afile is a file")
    _assert_clean_error(run_cli("vade-replay", golden, "--rerun", str(tmp_path / "afile" / "r.rrd")),
                        "afile is a file")
    _assert_clean_error(run_cli("vade-replay", str(tmp_path)), "is a folder")
    _assert_clean_error(run_cli("vade-replay", golden, "--spawn"), "--rerun")


def test_goldens_command_rejects_unknown_names_and_folders(tmp_path):
    _assert_clean_error(run_cli("vade-goldens", "--dir", str(tmp_path / "none")), "--dir")
    _assert_clean_error(run_cli("vade-goldens", "--dir", str(tmp_path)), "no session files")
    _assert_clean_error(run_cli("vade-goldens", "--check", "nosuch"), "nosuch")


def test_session_errors_name_the_field_that_is_wrong(tmp_path):
    doc = _doc()
    doc["parts"][0]["shape"]["size"][0] = -0.04
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))), "parts[0].shape.size")
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "mesh", "file": "nosuch.stl"}
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))),
                        "parts[0].shape.file", "nosuch.stl")
    doc = _doc()
    doc["physics"] = {"gravty_scale_free": 0.3}
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))),
                        "physics.gravty_scale_free", "gravity_scale_free")


def test_friction_what_if_reaches_constraints_that_set_their_own():
    golden = RECORDINGS / "plane_block_wall.mcap"
    doc = json.loads((RECORDINGS / "plane_block_wall.json").read_text())
    assert doc["parts"][0]["assembly"]["constraints"][0]["friction"]["dynamic"] != 0.1
    result = run_cli("vade-replay", str(golden), "--set", "physics.friction_dynamic=0.1", "--json")
    summary = json.loads(result.stdout)
    assert result.returncode == 0 and summary["match"] is False


@pytest.mark.parametrize("mutate, needle", [
    (lambda d: d["parts"][0]["pose"].update(position=[0.0, 0.0, float("nan")]), "NaN"),
    (lambda d: d["tracker"]["devices"]["right_hand"][1].update(position=[1e200, 0, 0]),
     "right_hand[1].position"),
    (lambda d: d["tracker"].update(duration_s=1e12), "tracker.duration_s"),
    (lambda d: d.setdefault("physics", {}).update(free_rotation_max_step_s=1e-300),
     "physics.free_rotation_max_step_s"),
    (lambda d: d["parts"][0].pop("density") and d["parts"][0].update(mass_properties={
        "mass": 1.0, "center_of_mass": [0, 0, 0],
        "inertia": [[1, 2, 0], [2, 1, 0], [0, 0, 1]]}), "principal moments -1, 1, 3 kg m^2"),
])
def test_absurd_numbers_are_refused_not_simulated(tmp_path, mutate, needle):
    doc = _doc()
    mutate(doc)
    path = tmp_path / "s.json"
    path.write_text(json.dumps(doc))  # json writes NaN as the non-standard NaN token
    _assert_clean_error(run_cli("vade-record", str(path)), needle)
    assert not list(tmp_path.glob("*.mcap*"))


def test_set_refuses_nan():
    _assert_clean_error(run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--set",
                                "physics.contact_tolerance=NaN"), "physics.contact_tolerance")


def test_many_recordings_at_once(tmp_path):
    from mcap_edit import nudge_pose

    good = [str(RECORDINGS / "drop_on_table.mcap"), str(RECORDINGS / "throw_and_catch.mcap")]
    result = run_cli("vade-replay", *good)
    assert result.returncode == 0
    *lines, tally = result.stdout.splitlines()
    assert [line.split(": ")[1] for line in lines] == ["match", "match"]
    assert tally == "2 recordings: 2 match, 0 diverged, 0 could not be replayed"
    bad = tmp_path / "bad.mcap"
    nudge_pose(RECORDINGS / "drop_on_table.mcap", bad, frame=60, axis=1, delta=1e-9)
    missing = str(tmp_path / "missing.mcap")
    result = run_cli("vade-replay", good[0], str(bad), "--json")
    assert result.returncode == 1
    summaries = json.loads(result.stdout)
    assert [s["match"] for s in summaries] == [True, False]
    assert summaries[1]["first_divergence"]["frame"] == 60
    result = run_cli("vade-replay", str(bad), missing, good[1])
    assert result.returncode == 2  # the worst: an unusable file
    assert "missing.mcap" in result.stderr and "DIVERGED" in result.stdout
    assert result.stdout.count(": match") == 1
    # The last line counts them, so that a log of stdout alone still shows the unusable one.
    assert result.stdout.splitlines()[-1] == ("3 recordings: 1 match, 1 diverged, 1 could "
                                              "not be replayed (see the errors above)")
    _assert_clean_error(run_cli("vade-replay", *good, "-o", str(tmp_path / "x.mcap")), "-o")
    # One cut short (a crash while recording) is counted among those replayed, not beside
    # them (a researcher's trial read "2 match, 1 diverged, 1 cut short" of 3 as a sum).
    cut = tmp_path / "cut.mcap"
    data = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    cut.write_bytes(data[:len(data) // 2])
    result = run_cli("vade-replay", good[0], str(cut))
    assert result.returncode == 0
    assert result.stdout.splitlines()[-1] == ("2 recordings: 2 match, 0 diverged, 0 could "
                                              "not be replayed; 1 of those replayed cut short")


def test_many_recordings_in_worker_processes_give_the_same_output(tmp_path):
    """``--jobs 2``: the same lines, JSON and table, in the order given, and the same exit
    code, as one at a time; an unusable file among them is still named."""
    from mcap_edit import nudge_pose

    bad = tmp_path / "bad.mcap"
    nudge_pose(RECORDINGS / "drop_on_table.mcap", bad, frame=60, axis=1, delta=1e-9)
    files = [str(RECORDINGS / "two_hand_placed.mcap"), str(bad), str(tmp_path / "missing.mcap"),
             str(RECORDINGS / "gear_pendulum.mcap")]
    for extra in ([], ["--json"], ["--set", "physics.gravity_scale_free=0.3"]):
        one = run_cli("vade-replay", *files, *extra, "--csv", str(tmp_path / "one.csv"))
        two = run_cli("vade-replay", *files, *extra, "--csv", str(tmp_path / "two.csv"),
                      "--jobs", "2", process=True)
        assert (two.returncode, two.stdout, two.stderr) == (one.returncode, one.stdout,
                                                            one.stderr)
        assert (tmp_path / "two.csv").read_text() == (tmp_path / "one.csv").read_text()
    assert one.returncode == 2 and "missing.mcap" in one.stderr
    _assert_clean_error(run_cli("vade-replay", *files, "--jobs", "-1"), "--jobs")


def _dies_on_gear(path, *args):
    """``_replay_one`` in a worker, killed from outside as it replays the gear golden (the
    system out of memory, say), after the recordings before it had time to finish."""
    import os
    import signal
    import time

    if path.endswith("gear_pendulum.mcap"):
        time.sleep(1.0)
        os.kill(os.getpid(), signal.SIGKILL)
    return _REPLAY_ONE(path, *args)


from vade_replay.cli import replay as _replay_cli  # noqa: E402

_REPLAY_ONE = _replay_cli._replay_one


def test_a_worker_killed_from_outside_is_named_and_the_rest_reported(tmp_path, monkeypatch):
    """A worker of ``--jobs`` killed from outside used to end the run with the pool's
    ``BrokenProcessPool`` traceback, the study's table unwritten. The recording it had is
    named, the ones after it are reported not replayed, the ones before keep their lines
    and rows, exit 2."""
    monkeypatch.setattr(_replay_cli, "_replay_one", _dies_on_gear)
    files = [str(RECORDINGS / name) for name in ("drop_on_table.mcap", "gear_pendulum.mcap",
                                                 "tumbling_box.mcap")]
    table = tmp_path / "study.csv"
    result = run_cli("vade-replay", *files, "--jobs", "2", "--csv", str(table))
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert result.stdout.splitlines()[0] == f"{files[0]}: match"
    assert result.stderr.splitlines() == [
        f"error: {files[1]}: its worker process ended without a result (killed from "
        "outside, or out of memory?)",
        f"error: {files[2]}: not replayed: a worker process ended before it did (--jobs 1 "
        "replays in this process)"]
    rows = table.read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == files  # a row each, the first replayed
    assert "error" not in rows[1] and "worker process ended" in rows[2]


def test_a_sigterm_as_a_worker_starts_is_not_taken_by_the_parents_handler():
    """SIGTERM to the process group as ``--jobs`` forked its workers found the parent's
    handler in them, which raised inside the fork's own hooks ("Exception ignored ...
    Terminated" on stderr, a review). The workers are forked with SIGINT and SIGTERM
    held off until their own handlers are set. Here each worker is sent SIGTERM inside
    those hooks: it is held, then ends the worker (the default action), which is
    reported, and nothing else is printed."""
    import subprocess
    import sys

    script = (
        "import os, signal, sys\n"
        "os.register_at_fork(after_in_child=lambda: os.kill(os.getpid(), signal.SIGTERM))\n"
        "from vade_replay.cli._common import run\n"
        "from vade_replay.cli.replay import main\n"
        "sys.exit(run(main, sys.argv[1:]))\n")
    files = [str(RECORDINGS / "drop_on_table.mcap"), str(RECORDINGS / "tumbling_box.mcap")]
    done = subprocess.run([sys.executable, "-c", script, *files, "--jobs", "2"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "Exception ignored" not in done.stderr and "Traceback" not in done.stderr
    assert done.stderr.splitlines()[0] == (
        f"error: {files[0]}: its worker process ended without a result (killed from "
        "outside, or out of memory?)")


def test_workers_keep_an_ignored_sigint_and_take_ctrl_c_otherwise(monkeypatch):
    """A parent that ignores SIGINT (a script's background job) goes on past a Ctrl-C to
    its process group: its workers do too (they used to end, and the parent printed the
    pool's ``BrokenProcessPool`` traceback). Otherwise a worker ends at once, quietly."""
    import signal

    for parents, workers in ((signal.SIG_IGN, signal.SIG_IGN),
                             (signal.default_int_handler, _replay_cli._exit_interrupted)):
        previous = signal.signal(signal.SIGINT, parents)
        try:
            _replay_cli._quiet_on_interrupt()
            assert signal.getsignal(signal.SIGINT) is workers
        finally:
            signal.signal(signal.SIGINT, previous)


def test_the_pools_own_race_at_a_stop_prints_no_traceback():
    """The pool's manager thread, finding its workers gone after the run cancelled their
    work, raises ``InvalidStateError`` (CPython's race; 2 runs in 28 of a process-group
    SIGTERM printed its traceback). That one is left out; any other goes on to the hook."""
    import threading
    from concurrent.futures import InvalidStateError

    class _ExecutorManagerThread(threading.Thread):
        pass

    seen = []
    quietly = _replay_cli._pool_stopping_quietly(seen.append)
    manager, other = _ExecutorManagerThread(), threading.Thread()
    for exc_type, thread in ((InvalidStateError, manager), (ValueError, manager),
                             (InvalidStateError, other)):
        quietly(threading.ExceptHookArgs((exc_type, exc_type(), None, thread)))
    assert [(a.exc_type, a.thread) for a in seen] == [(ValueError, manager),
                                                      (InvalidStateError, other)]


UNWRITABLE = Path("/proc/vade-test-cannot-write-here")  # even root cannot create files in /proc


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs Linux /proc")
def test_outputs_that_cannot_be_written_are_clean_errors(tmp_path):
    golden = str(RECORDINGS / "gear_pendulum.mcap")
    _assert_clean_error(run_cli("vade-replay", golden, "-o", f"{UNWRITABLE}.mcap"),
                        f"{UNWRITABLE}.mcap", "cannot write")
    _assert_clean_error(run_cli("vade-replay", golden, "--rerun", f"{UNWRITABLE}.rrd"),
                        f"{UNWRITABLE}.rrd", "cannot write the review")
    _assert_clean_error(run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o",
                                f"{UNWRITABLE}.mcap"), "cannot write")


def test_a_damaged_derived_message_names_file_channel_and_frame(tmp_path):
    def edit(topic, index, data):
        if topic == "/foxglove/transforms" and index == 30:
            return b"\xd3" + data[1:]
        return data

    path = tmp_path / "damaged.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", path, edit)
    _assert_clean_error(run_cli("vade-replay", str(path)), "damaged.mcap", "frame 30",
                        "/foxglove/transforms", "not JSON")


def test_a_what_if_says_so(tmp_path):
    result = run_cli("vade-replay", str(RECORDINGS / "plane_block_wall.mcap"), "--set",
                     "physics.friction_dynamic=0.1")
    assert result.returncode == 0
    assert result.stdout.startswith("what-if (physics.friction_dynamic=0.1): departs from the "
                                    "recording: first divergence at frame ")


def _chunk_offsets(path: Path) -> list[int]:
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        return [c.chunk_start_offset for c in make_reader(f).get_summary().chunk_indexes]


@pytest.mark.parametrize("chunk", [0, 1])
@pytest.mark.parametrize("where", ["data", "compression"])
def test_a_damaged_chunk_is_an_error_naming_where_not_a_short_recording(tmp_path, chunk, where):
    """A chunk that cannot be read, with the file going on after it, is damage: exit 2
    naming the file and the place (it was taken for a recording cut short, which replayed
    the frames before it and could pass, or for an empty one). A file cut short still
    replays what it holds (test above)."""
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    start = _chunk_offsets(RECORDINGS / "drop_on_table.mcap")[chunk]
    # A chunk record: opcode, length, start and end times, uncompressed size and CRC
    # (1 + 8 + 8 + 8 + 8 + 4 bytes), the compression ("zstd", length-prefixed), the
    # records' length (8), then the zstd frame.
    at = start + 37 + (4 if where == "compression" else 4 + 4 + 8)
    assert bytes(data[start + 41:start + 45]) == b"zstd"
    data[at:at + 4] = b"zstx" if where == "compression" else b"\0\0\0\0"
    path = tmp_path / "damaged.mcap"
    path.write_bytes(bytes(data))
    _assert_clean_error(run_cli("vade-replay", str(path)), "damaged.mcap", "damaged after")


def test_o_writes_through_a_link_keeps_the_mode_and_never_over_its_input(tmp_path):
    """``-o`` is written as OUT.partial beside the file a link points to, and moved over it:
    the link stays a link, the file keeps its mode. A recording named as the output's
    .partial is refused (it would be overwritten while it is read)."""
    import shutil
    import stat
    golden = RECORDINGS / "drop_on_table.mcap"
    target = tmp_path / "target.mcap"
    target.write_bytes(b"an older file")
    target.chmod(0o640)
    link = tmp_path / "link.mcap"
    link.symlink_to(target)
    result = run_cli("vade-replay", str(golden), "-o", str(link), "--force")
    assert result.returncode == 0, result.stderr
    assert link.is_symlink() and stat.S_IMODE(target.stat().st_mode) == 0o640
    assert run_cli("vade-replay", str(target)).returncode == 0  # a complete recording
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.mcap", "target.mcap"]
    shutil.copy(golden, tmp_path / "x.mcap.partial")
    result = run_cli("vade-replay", str(tmp_path / "x.mcap.partial"), "-o",
                     str(tmp_path / "x.mcap"))
    assert result.returncode == 2 and "refusing" in result.stderr
    assert (tmp_path / "x.mcap.partial").read_bytes() == golden.read_bytes()
    assert not (tmp_path / "x.mcap").exists()


def test_recordings_and_options_in_any_order(tmp_path):
    """A study's files may follow an option's value (``--csv OUT.csv A.mcap B.mcap``)."""
    files = [str(RECORDINGS / f"{name}.mcap") for name in ("drop_on_table", "hoist_placed")]
    table = tmp_path / "t.csv"
    result = run_cli("vade-replay", files[0], "--csv", str(table), files[1])
    assert result.returncode == 0, result.stderr
    assert [line.split(": ")[-1] for line in result.stdout.splitlines()[:-1]] == ["match",
                                                                                "match"]
    assert table.read_text().count("\n") == 3  # the header and a row per recording's part


@pytest.mark.parametrize("outputs", [["--rerun", "{rec}"], ["-o", "{out}", "--rerun", "{out}"],
                                     ["--rerun", "{out}", "--csv", "{out}"]])
def test_no_output_is_written_over_the_recording_or_another_output(tmp_path, outputs):
    """A slip such as ``--rerun run.mcap`` for ``run.rrd`` used to replace the recording
    with the review, and ``-o X --rerun X`` the regenerated recording with it."""
    import shutil
    rec, out = tmp_path / "run.mcap", tmp_path / "out.mcap"
    shutil.copy(RECORDINGS / "drop_on_table.mcap", rec)
    args = [a.format(rec=rec, out=out) for a in outputs]
    option = args[-2]
    _assert_clean_error(run_cli("vade-replay", str(rec), *args), "refusing", option)
    assert rec.read_bytes() == (RECORDINGS / "drop_on_table.mcap").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]


def test_a_recording_is_not_written_over_its_session_or_the_files_it_names(tmp_path):
    """``vade-record s.json -o s.json`` used to replace the session with the recording."""
    from test_session import CSV, _csv_doc
    session = _write(tmp_path, _csv_doc())
    (tmp_path / "log.csv").write_text(CSV)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    _assert_clean_error(run_cli("vade-record", str(session), "-o", str(session)),
                        "refusing", "the session file")
    # Another spelling of the same path; a file the session names.
    _assert_clean_error(run_cli("vade-record", str(session), "-o",
                                str(tmp_path / "." / "s.json")), "refusing")
    _assert_clean_error(run_cli("vade-record", str(session), "-o", str(tmp_path / "log.csv")),
                        "refusing", "tracker.csv")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    assert run_cli("vade-record", str(session), "-o", str(tmp_path / "s.mcap")).returncode == 0


def test_a_file_of_the_other_kind_is_named_for_what_it_is(tmp_path):
    _assert_clean_error(run_cli("vade-replay", str(RECORDINGS / "drop_on_table.json")),
                        "drop_on_table.json", "session file", "vade-record")
    _assert_clean_error(run_cli("vade-record", str(RECORDINGS / "drop_on_table.mcap")),
                        "drop_on_table.mcap", "recording", "vade-replay")


@pytest.mark.parametrize("size, needle", [(0, "empty file"), (3, "cut short before its first"),
                                          (2000, "cut short before its first")])
def test_a_recording_cut_before_its_first_frame_says_so(tmp_path, size, needle):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes((RECORDINGS / "drop_on_table.mcap").read_bytes()[:size])
    _assert_clean_error(run_cli("vade-replay", str(cut)), "cut.mcap", needle)
    other = tmp_path / "other.mcap"
    other.write_bytes(b"PK\x03\x04 a zip file")
    _assert_clean_error(run_cli("vade-replay", str(other)), "not an MCAP file")


def test_a_review_or_a_folder_given_for_a_recording_says_what_to_give(tmp_path):
    """A newcomer's trial: a review (``.rrd``) given to vade-replay was "not an MCAP file",
    and a folder "a folder, not a recording", with no word of what to do."""
    review = tmp_path / "whatif.rrd"
    assert run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--rerun",
                   str(review)).returncode == 0
    _assert_clean_error(run_cli("vade-replay", str(review)), str(review),
                        "this is a rerun review", "open it with `rerun`")
    _assert_clean_error(run_cli("vade-replay", str(tmp_path)), str(tmp_path),
                        f"is a folder, not a recording (give its recordings: {tmp_path}/*.mcap)")


def test_a_table_on_standard_output(tmp_path):
    """``--csv -``: the table is standard output's alone; the run's lines go to stderr."""
    import csv
    import io
    files = [str(RECORDINGS / f"{name}.mcap") for name in ("drop_on_table", "hoist_placed")]
    result = run_cli("vade-replay", *files, "--csv", "-", process=True)
    assert result.returncode == 0, result.stderr
    rows = list(csv.DictReader(io.StringIO(result.stdout)))
    assert [(r["recording"], r["part"], r["match"]) for r in rows] == [
        (files[0], "peg", "True"), (files[1], "ring", "True")]
    from conftest import ROOT
    assert "2 recordings: 2 match" in result.stderr and not (ROOT / "-").exists()
    events = run_cli("vade-replay", files[0], "--events", "-", process=True)
    assert events.stdout.splitlines()[0].startswith("recording,frame,time_s,kind")
    assert "match" in events.stderr
    _assert_clean_error(run_cli("vade-replay", files[0], "--csv", "-", "--json"), "--json")
    # /dev/stdout is standard output too: not two tables mixed there.
    _assert_clean_error(run_cli("vade-replay", files[0], "--csv", "-", "--events",
                                "/dev/stdout"), "--events", "standard output")


def test_the_table_marks_a_recording_cut_short(tmp_path):
    """A crash while recording leaves fewer frames than the session: its rows say so."""
    import csv
    golden = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(golden[:len(golden) * 2 // 3])
    table = tmp_path / "t.csv"
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), str(cut),
                     "--csv", str(table))
    assert result.returncode == 0, result.stderr
    rows = list(csv.DictReader(table.open()))
    assert [(r["truncated"], r["match"]) for r in rows] == [("False", "True"), ("True", "True")]
    assert int(rows[1]["frames"]) < int(rows[0]["frames"])
    assert "; 1 of those replayed cut short" in result.stdout.splitlines()[-1]


def test_a_what_if_warns_of_gravity_in_the_wrong_units():
    """``--set physics.gravity`` is in the session's units: a value far from Earth's once in
    metres is named on stderr (the replay still runs: a what-if may mean it)."""
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--set",
                     "physics.gravity=[0,0,-0.0098]")
    assert result.returncode == 0, result.stderr
    assert "warning:" in result.stderr and "0.0098 m/s^2" in result.stderr
    plain = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"))
    assert plain.stderr == ""


def test_schema_slips_are_named_as_a_user_wrote_them(tmp_path):
    """A typo of a required key names the key written; a CSV tracker without its
    quaternion order names that field, not "not valid under any of the given schemas"."""
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    doc["parts"][0]["shape"]["radus"] = doc["parts"][0]["shape"].pop("radius")
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))), "parts[0].shape",
                        "'radius' is a required property", "'radus' a typo")
    doc = _doc()
    doc["tracker"] = {"csv": "log.csv", "csv_units": "mm"}
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))), "field tracker",
                        "'csv_quaternion_order' is a required property")
    # The alternative whose fields it uses, not the first one listed: a CSV log with a
    # stray duration_s, mass properties without their inertia.
    doc["tracker"] = {"csv": "log.csv", "duration_s": 2.5}
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))), "field tracker",
                        "'csv_quaternion_order' is a required property")
    doc = _doc()
    part = doc["parts"][0]
    part.pop("density", None)
    part["mass_properties"] = {"mass": 0.2, "center_of_mass": [0, 0, 0]}
    result = run_cli("vade-record", str(_write(tmp_path, doc)))
    _assert_clean_error(result, "parts[0].mass_properties", "required property")
    assert "'file'" not in result.stderr


def test_a_zero_direction_and_a_part_too_small_to_hold_are_named(tmp_path):
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    doc["parts"][0]["assembly"]["constraints"][0]["base"]["direction"] = [0, 0, 0]
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))),
                        "parts[0].assembly.constraints[0].base.direction", "zero vector")
    # Metres written in a mm session: a peg 0.08 mm across, not a mass of round-off.
    doc = _doc()
    doc["units"] = "mm"
    result = run_cli("vade-record", str(_write(tmp_path, doc)), process=True)
    _assert_clean_error(result, "mm across", "units")
    assert "RuntimeWarning" not in result.stderr


def test_standard_output_closed_early_ends_quietly():
    """``vade-replay study/*.mcap --poses - | head -1``: no traceback, no error line; the
    exit code of a process that SIGPIPE ended (141), as a shell's own tools give. (The pose
    rows, ~450 KB, outgrow the pipe's buffer, so the writer is still writing when the
    reader goes; a run's few verdict lines could all fit before it does.)"""
    import subprocess
    import sys

    from conftest import COMMANDS, ROOT
    files = [str(p) for p in sorted(RECORDINGS.glob("*.mcap"))]
    proc = subprocess.Popen([sys.executable, "-m", COMMANDS["vade-replay"], *files, "--poses",
                             "-"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    first = proc.stdout.readline()
    proc.stdout.close()  # the reader goes away, as `head -1` does
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141
    assert first and "Traceback" not in err and "error:" not in err

    assert "stopped: standard output was closed" in err


def test_a_run_with_files_to_write_goes_on_when_standard_output_closes(tmp_path):
    """``vade-replay study/*.mcap --poses - --csv study.csv | head -1``: the pose rows on
    standard output are cut off, but the study's table is a file, so the run goes on
    without standard output and writes it whole (a row per recording); still 141, and a
    line saying the files were written. (Without a file to write it stops at once.)"""
    import csv
    import subprocess
    import sys

    from conftest import COMMANDS, ROOT
    files = [str(p) for p in sorted(RECORDINGS.glob("*.mcap"))]
    table = tmp_path / "study.csv"
    proc = subprocess.Popen([sys.executable, "-m", COMMANDS["vade-replay"], *files, "--poses",
                             "-", "--csv", str(table)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=ROOT)
    first = proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141 and first
    assert "Traceback" not in err and "error:" not in err
    assert "the run went on without it and wrote its files" in err
    rows = list(csv.DictReader(table.open(encoding="utf-8")))
    assert len(rows) == len(files) and all(r["match"] == "True" for r in rows)


def test_output_still_buffered_when_the_reader_went_ends_quietly_too(tmp_path):
    """Without PYTHONUNBUFFERED, a batch's --json is written when the run ends: far more
    than a pipe holds, so the reader is gone before it is all written. Not 'Exception ignored'
    and exit 120 at the interpreter's exit: 141 and one line."""
    import os
    import subprocess
    import sys

    from conftest import COMMANDS, ROOT
    # ~1.1 KB of JSON a recording: 200 of them are 220 KB, over a pipe's 64 KB.
    # (Hard links: links to one file, given twice, are one recording replayed once.)
    import shutil
    shutil.copy(RECORDINGS / "drop_on_table.mcap", tmp_path / "r000.mcap")
    for i in range(1, 200):
        os.link(tmp_path / "r000.mcap", tmp_path / f"r{i:03d}.mcap")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    proc = subprocess.Popen([sys.executable, "-m", COMMANDS["vade-replay"], "--json",
                             *sorted(str(p) for p in tmp_path.iterdir())],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT, env=env)
    first = proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141 and first.strip() == b"["
    assert "Exception ignored" not in err and "Traceback" not in err


def test_a_named_pipe_whose_reader_went_is_an_error_not_a_quiet_stop(tmp_path):
    """Only standard output closing is a quiet stop: a table written to a named pipe whose
    reader died is an error naming it (exit 2), and a recording cannot go to a pipe."""
    import os
    import threading
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)

    def read_a_little():
        with open(fifo, "rb") as reader:
            reader.read(100)
    threading.Thread(target=read_a_little, daemon=True).start()
    result = run_cli("vade-replay", str(RECORDINGS / "shaft_placed.mcap"), "--poses",
                     str(fifo), process=True)
    _assert_clean_error(result, "--poses", str(fifo), "Broken pipe")
    threading.Thread(target=read_a_little, daemon=True).start()
    result = run_cli("vade-replay", str(RECORDINGS / "shaft_placed.mcap"), "-o", str(fifo),
                     process=True)
    _assert_clean_error(result, str(fifo), "cannot write a recording to a pipe")


def test_ctrl_c_while_a_command_is_still_importing_is_interrupted_not_a_traceback(
        monkeypatch, capsys):
    """The installed commands start in ``cli._launch``: Ctrl-C during the ~0.3 s of imports
    (a traceback from inside numpy or dataclasses) is "interrupted", exit 130, as later."""
    import importlib

    from vade_replay.cli import _launch

    def interrupted(name):
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib, "import_module", interrupted)
    with pytest.raises(SystemExit) as exit_:
        _launch.replay()
    assert exit_.value.code == 130 and capsys.readouterr().err == "interrupted\n"


def test_the_installed_commands_start_in_the_launcher():
    import tomllib
    from pathlib import Path

    scripts = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml")
                            .read_text())["project"]["scripts"]
    from vade_replay.cli import _launch
    for command, target in scripts.items():
        module, _, name = target.partition(":")
        assert module == "vade_replay.cli._launch" and callable(getattr(_launch, name))
        assert command == f"vade-{name}"


def test_two_recordings_to_one_output_at_once_do_not_mix(tmp_path):
    """A second ``vade-record -o X`` while one is writing ``X.partial`` is refused (exit 2,
    naming the file): it used to truncate the first's file and interleave its records.
    The first run's recording is whole, and lands at X."""
    from vade_replay.recording import RecordingWriter, Recording
    from vade_replay.replay import simulate
    from vade_replay.session import load
    session = load(RECORDINGS / "drop_on_table.json")
    scene = session.build_scene()
    out = tmp_path / "run.mcap"
    partial = tmp_path / "run.mcap.partial"
    first = RecordingWriter(partial, session, scene)
    frames = list(simulate(scene, session.tracker_frames()))
    for record in frames[:50]:
        first.write_frame(record)
    second = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(out),
                     process=True)
    _assert_clean_error(second, str(partial), "another run is writing")
    for record in frames[50:]:
        first.write_frame(record)
    first.close(complete_as=out)
    assert not partial.exists()
    recording = Recording(out)
    assert len(list(recording.frames())) == len(frames) and not recording.truncated
    # Once the first is done, the same output is free again.
    assert run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(out),
                   process=True).returncode == 0


@pytest.mark.parametrize("how", ["dropped", "doubled", "last"])
def test_a_tracker_message_dropped_or_repeated_by_another_tool_is_named(tmp_path, how):
    """A researcher's trial: a recording passed through another tool that dropped (or
    repeated) one /tracker message replayed as "DIVERGED" (exit 1, the physics blamed),
    dumping a /parts message's whole dict. Frames are numbered from 0, one a message: a
    gap or a repeat is named, with the frame, exit 2."""
    from mcap.reader import make_reader
    golden = RECORDINGS / "drop_on_table.mcap"
    with open(golden, "rb") as f:
        tracker = [message.data for _, channel, message in make_reader(f).iter_messages()
                   if channel.topic == "/tracker"]

    def edit(topic, index, data):
        if topic == "/tracker" and index == 70 and how == "dropped":
            return None
        if topic == "/tracker" and index == 71 and how == "doubled":
            return tracker[70]  # frame 70's message again, in frame 71's place
        if topic == "/tracker" and index == len(tracker) - 1 and how == "last":
            return None  # (found by no later frame's number: a review)
        return data
    edited = tmp_path / f"{how}.mcap"
    copy_recording(golden, edited, edit)
    result = run_cli("vade-replay", str(edited))
    expected = {"dropped": "frame 70: tracker frame 70 is missing (frame 69 is followed by "
                           "frame 70's other messages)",
                "doubled": "frame 71: tracker frame 70 appears twice",
                "last": f"frame {len(tracker) - 1}: tracker frame {len(tracker) - 1} is "
                        f"missing (frame {len(tracker) - 2} is followed by frame "
                        f"{len(tracker) - 1}'s other messages)"}[how]
    _assert_clean_error(result, f"{edited}: field /tracker frame: {expected}: the recording "
                                "was edited, filtered or merged by another tool?")
    assert "DIVERGED" not in result.stdout + result.stderr


def test_a_lock_held_for_a_moment_does_not_refuse_a_writer(tmp_path):
    """``left_partial`` takes a shared lock on a ``.partial`` for a moment to see whether a
    run is writing it; a writer starting in that moment was told "another run is writing".
    It waits for a lock let go within a fifth of a second (a run writing holds it for the
    whole run, refused above)."""
    import fcntl
    import os
    import threading
    from vade_replay.recording import RecordingWriter
    from vade_replay.session import load
    session = load(RECORDINGS / "drop_on_table.json")
    partial = tmp_path / "run.mcap.partial"
    partial.write_bytes(b"left by an interrupted run")
    fd = os.open(partial, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    threading.Timer(0.05, os.close, (fd,)).start()  # let go 50 ms on, as a glance does
    writer = RecordingWriter(partial, session, session.build_scene())
    writer.close()
    assert Recording(partial).session.name == "drop_on_table"


@pytest.mark.parametrize("command, option", [("vade-record", "-o"), ("vade-replay", "-o"),
                                             ("vade-replay", "--rerun")])
def test_a_recording_or_review_to_standard_output_is_refused_not_a_file_named_dash(
        tmp_path, command, option, monkeypatch):
    """``-o -`` wrote a file named ``-`` (a table's ``-`` is standard output)."""
    monkeypatch.chdir(tmp_path)
    source = RECORDINGS / ("drop_on_table.json" if command == "vade-record"
                           else "drop_on_table.mcap")
    _assert_clean_error(run_cli(command, str(source), option, "-"), option,
                        "writes a file, not standard output")
    assert not (tmp_path / "-").exists()


def test_an_output_holding_another_recording_is_not_replaced_without_force(tmp_path):
    """An engineer's trial: vade-record -o and vade-replay -o replaced a study's recording
    of another session without a word. A recording of another session, or a file that is
    no recording, is refused (exit 2, the file untouched) unless --force; one of this
    session is replaced: silently where it is this recording made again (a re-run of the
    demo), with a note where the session, its files or the physics differ (editing a
    session and recording it again; a review: an older version's recording)."""
    import shutil
    out = tmp_path / "study1.mcap"
    drop, throw = RECORDINGS / "drop_on_table.json", RECORDINGS / "throw_and_catch.json"
    assert run_cli("vade-record", str(drop), "-o", str(out)).returncode == 0
    kept = out.read_bytes()
    again = run_cli("vade-record", str(drop), "-o", str(out))
    assert again.returncode == 0 and "note:" not in again.stderr  # made again
    other = run_cli("vade-record", str(throw), "-o", str(out))
    _assert_clean_error(other, str(out), "another session ('drop_on_table')", "--force")
    assert out.read_bytes() == kept and not list(tmp_path.glob("*.partial"))
    edited = json.loads(drop.read_text())
    edited["parts"][0]["density"] = 2000  # the session's design edited, the same input
    session = _write(tmp_path, edited)
    changed = run_cli("vade-record", str(session), "-o", str(out))
    assert changed.returncode == 0 and (f"note: replacing {out}, a recording of "
                                        "'drop_on_table' made otherwise (its session, in "
                                        "parts.peg)") in changed.stderr
    # Another take (other tracker input, which may exist nowhere else): refused.
    edited["tracker"]["devices"]["right_hand"][1]["position"][0] += 0.01
    take = run_cli("vade-record", str(_write(tmp_path, edited)), "-o", str(out))
    _assert_clean_error(take, "a recording of 'drop_on_table' with other tracker input",
                        "--force")
    old = tmp_path / "old.mcap"
    shutil.copy(Path(__file__).parent / "data" / "shaft_slide_off_before_analytic4.mcap", old)
    (tmp_path / "slide.json").write_bytes(Recording(old).session.raw)
    older = run_cli("vade-record", str(tmp_path / "slide.json"), "-o", str(old))
    # The physics keys a default moved in since (a researcher's trial: it named none).
    assert older.returncode == 0 and "(its physics, in block_cut, block_event, " \
        "coaxial_fit, contact_sweep, environment_contact, final_pose_check, 14 more)" \
        in older.stderr
    forced = run_cli("vade-record", str(throw), "-o", str(out), "--force")
    assert forced.returncode == 0 and Recording(out).session.name == "throw_and_catch"
    # A what-if's recording embeds its changed session: made again, replaced silently;
    # another what-if of the same recording, replaced with a note.
    what_if = tmp_path / "what_if.mcap"
    args = ["vade-replay", str(out), "--set", "physics.gravity_scale_free=0.5", "-o",
            str(what_if)]
    first = run_cli(*args)
    assert first.returncode == 0 and f"wrote {what_if} (181 frames regenerated)" in first.stdout
    assert "note:" not in run_cli(*args).stderr
    other_what_if = run_cli("vade-replay", str(out), "--set", "physics.gravity_scale_free=0.3",
                            "-o", str(what_if))
    assert other_what_if.returncode == 0 and \
        "(its session, in physics; its physics, in gravity_scale_free)" in other_what_if.stderr
    (tmp_path / "notes.txt").write_text("not a recording")
    _assert_clean_error(run_cli("vade-replay", str(out), "-o", str(tmp_path / "notes.txt")),
                        "not a readable recording", "--force")

def test_a_set_given_twice_with_two_values_is_refused():
    """An engineer's trial: the last of two --set values of one key won without a word."""
    golden = str(RECORDINGS / "drop_on_table.mcap")
    result = run_cli("vade-replay", golden, "--set", "physics.friction_dynamic=0.1",
                     "--set", "physics.friction_dynamic=0.2")
    _assert_clean_error(result, "--set physics.friction_dynamic is given twice, 0.1 and 0.2")
    again = run_cli("vade-replay", golden, "--set", "physics.friction_dynamic=0.1",
                    "--set", "physics.friction_dynamic=0.1")
    assert again.returncode == 0, again.stderr  # the same value twice says one thing


def test_messages_name_the_duplicate_part_and_a_compound_childs_field(tmp_path):
    """An engineer's trial: 'part names must be unique' did not say which; a tube in a
    compound base was named at base.shape.children[1].shape.inner_radius, a path the file
    does not have."""
    doc = json.loads((RECORDINGS / "drop_on_table.json").read_text())
    doc["parts"].append(dict(doc["parts"][0]))
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))),
                        "field parts: part names must be unique: 'peg' is given to more than "
                        "one part")
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    doc["base"]["shape"]["children"][1] = {"type": "tube", "radius": 0.01,
                                           "inner_radius": 0.02, "height": 0.1}
    _assert_clean_error(run_cli("vade-record", str(_write(tmp_path, doc))),
                        "field base.shape.children[1].inner_radius: inner_radius must be "
                        "smaller than radius")
    # A command-line option is named as given, not as a field.
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "-o", "-")
    assert result.returncode == 2 and "field -o" not in result.stderr \
        and result.stderr.startswith("error: -o: ")


def test_tables_and_reviews_do_not_replace_what_vade_replay_did_not_write(tmp_path):
    """A researcher's trial: --csv (or --events, --poses, --rerun) given a participant's
    recording or a session file replaced it. Only a table (or a review) vade-replay wrote,
    or an empty file, is replaced without --force; the file is untouched, exit 2."""
    import shutil
    kept = tmp_path / "participant.mcap"
    shutil.copy(RECORDINGS / "drop_on_table.mcap", kept)
    session = tmp_path / "s.json"
    shutil.copy(RECORDINGS / "drop_on_table.json", session)
    golden = str(RECORDINGS / "throw_and_catch.mcap")
    for option, path, what in (("--csv", kept, "a recording"), ("--events", kept, "a recording"),
                               ("--poses", session, "a JSON file (a session?)"),
                               ("--rerun", session, "a JSON file (a session?)")):
        _assert_clean_error(run_cli("vade-replay", golden, option, str(path)),
                            f"{option}: {path} holds {what}", "--force")
    assert kept.read_bytes() == (RECORDINGS / "drop_on_table.mcap").read_bytes()
    assert session.read_bytes() == (RECORDINGS / "drop_on_table.json").read_bytes()
    # Its own outputs, run again: replaced.
    table, review = tmp_path / "t.csv", tmp_path / "r.rrd"
    for _ in range(2):
        assert run_cli("vade-replay", golden, "--csv", str(table), "--rerun",
                       str(review)).returncode == 0
    assert run_cli("vade-replay", golden, "--csv", str(kept), "--force").returncode == 0
    assert kept.read_text().startswith("recording,")


def test_a_table_does_not_replace_a_tracker_log_a_mesh_or_a_picture(tmp_path):
    """A newcomer's trial: ``--poses log.csv`` replaced the session's own tracker log (a CSV,
    but not a table vade-replay wrote), ``--events peg.stl`` a mesh the session uses and
    ``--csv pic.png`` a picture, exit 0. A table replaces only an empty file or a table
    (its header's first column ``recording``, also re-saved by a spreadsheet with a
    byte-order mark and quotes); the rest is refused, exit 2, the file untouched."""
    golden = str(RECORDINGS / "throw_and_catch.mcap")
    log = tmp_path / "log.csv"
    log.write_text("time,device,x,y,z,q0,q1,q2,q3,grip\n0.0,right_hand,0,0,1,1,0,0,0,0\n")
    mesh = tmp_path / "peg.stl"
    mesh.write_bytes(b"solid peg\nendsolid peg\n")
    picture = tmp_path / "pic.png"
    picture.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(32))
    for option, path in (("--poses", log), ("--events", mesh), ("--csv", picture)):
        before = path.read_bytes()
        _assert_clean_error(run_cli("vade-replay", golden, option, str(path)),
                            f"{option}: {path} holds other data, not a table vade-replay "
                            "wrote", "--force")
        assert path.read_bytes() == before
    resaved = tmp_path / "study.csv"
    resaved.write_bytes(b'\xef\xbb\xbf"recording";"session";"match"\r\n"a.mcap";"s";"True"\r\n')
    assert run_cli("vade-replay", golden, "--csv", str(resaved)).returncode == 0
    assert resaved.read_text().startswith("recording,session,")


def test_a_table_does_not_replace_another_of_vade_replays_tables_without_force(tmp_path):
    """A researcher's trial: ``--events out/study.csv`` replaced the study's --csv table with
    an events table, without a word. Another kind of vade-replay table is refused, exit 2,
    the file untouched, as any file vade-replay did not write is; the same kind is
    replaced (a study run again), and --force replaces the other."""
    golden = str(RECORDINGS / "drop_on_table.mcap")
    study = tmp_path / "study.csv"
    assert run_cli("vade-replay", golden, "--csv", str(study)).returncode == 0
    before = study.read_bytes()
    _assert_clean_error(run_cli("vade-replay", golden, "--events", str(study)),
                        f"--events: {study} holds vade-replay's --csv table, which this table "
                        "would replace", "--force")
    assert study.read_bytes() == before
    assert run_cli("vade-replay", golden, "--csv", str(study)).returncode == 0
    assert run_cli("vade-replay", golden, "--events", str(study), "--force").returncode == 0
    assert study.read_text().startswith("recording,frame,time_s,kind,")
    poses = tmp_path / "poses.csv"
    assert run_cli("vade-replay", golden, "--poses", str(poses)).returncode == 0
    _assert_clean_error(run_cli("vade-replay", golden, "--tracker", str(poses)),
                        "holds vade-replay's --poses table")
    # A study table an older version wrote (fewer columns at its end: a review), or a
    # spreadsheet saved again (quoted, semicolons), is the --csv table too.
    for header in (b"recording,session,match,first_divergence_frame,frames\n",
                   b'\xef\xbb\xbf"recording";"session";"match";"first_divergence_frame"\r\n'):
        older = tmp_path / "older.csv"
        older.write_bytes(header + b"a.mcap,s,True,,1\n")
        _assert_clean_error(run_cli("vade-replay", golden, "--events", str(older)),
                            "holds vade-replay's --csv table")
        assert older.read_bytes().startswith(header)


def test_a_bad_physics_set_writes_nothing_and_says_so_once(tmp_path):
    """A researcher's trial: a typo in --set over a study replaced a good study table with
    a row of errors per recording, and printed its message once a recording."""
    files = [str(RECORDINGS / f"{n}.mcap") for n in ("drop_on_table", "gear_pendulum")]
    table = tmp_path / "study.csv"
    assert run_cli("vade-replay", *files, "--csv", str(table)).returncode == 0
    good = table.read_bytes()
    result = run_cli("vade-replay", *files, "--set", "physics.release_velocty=two_frame",
                     "--csv", str(table))
    _assert_clean_error(result, "physics.release_velocty: unknown field")
    assert result.stderr.count("unknown field") == 1
    assert table.read_bytes() == good


@pytest.mark.parametrize("key, meant", [("part.peg.mass", "parts.peg.mass"),
                                       ("physic.friction_dynamic", "physics.friction_dynamic"),
                                       ("Physics.friction_dynamic", "physics.friction_dynamic"),
                                       ("tool.hoist.max_mass_kg", "tools.hoist.max_mass_kg"),
                                       ("gravity", None)])
def test_a_set_typo_in_its_first_word_writes_nothing_and_says_so_once(tmp_path, key, meant):
    """A researcher's trial: ``--set part.pin.mass=2`` (``parts`` meant) over a study failed
    each recording on its own and replaced the study's table with rows of the error, and
    its --events with a header. It is one error before anything is written, naming the key
    it is close to, and the tables are kept."""
    files = [str(RECORDINGS / f"{n}.mcap") for n in ("drop_on_table", "gear_pendulum")]
    table, events = tmp_path / "study.csv", tmp_path / "events.csv"
    assert run_cli("vade-replay", *files, "--csv", str(table), "--events",
                   str(events)).returncode == 0
    good = (table.read_bytes(), events.read_bytes())
    result = run_cli("vade-replay", *files, "--set", f"{key}=2", "--csv", str(table),
                     "--events", str(events))
    _assert_clean_error(result, f"--set {key}: only physics parameters, tools and parts")
    assert result.stderr.count("\n") == 1 and result.stdout == ""
    assert (f"(did you mean {meant}?)" in result.stderr) == (meant is not None)
    assert (table.read_bytes(), events.read_bytes()) == good


def test_a_recording_given_twice_is_replayed_once(tmp_path):
    golden = RECORDINGS / "drop_on_table.mcap"
    result = run_cli("vade-replay", str(golden), str(golden.parent / "." / golden.name))
    assert result.returncode == 0
    assert "is " + str(golden) + " again: replayed once" in result.stderr
    assert result.stdout.splitlines() == [
        "match: 151 frames (2.50 s), 308 derived messages identical to the recording"]
    # Through a link too (a user's trial: a folder's latest.mcap, a link to its last take,
    # was a second row of the study's table).
    latest = tmp_path / "latest.mcap"
    latest.symlink_to(golden)
    result = run_cli("vade-replay", str(golden), str(latest), "--csv", str(tmp_path / "t.csv"))
    assert result.returncode == 0
    assert result.stderr == (f"warning: {latest} is {golden} again (a link to it, or it to "
                             "this): replayed once\n")
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 2  # the header and one row


def test_a_run_stopped_by_a_closed_standard_output_names_only_what_it_left_undone(
        monkeypatch, capsys):
    """A researcher's trial: ``vade-replay FILE | head`` ended with "outputs of the run not
    yet written (tables, -o, --rerun) were not written" though none was asked for (a run
    with files to write goes on without standard output). The line says only that it
    stopped, and what a command that writes as it prints left undone (``vade-goldens
    --check``: the goldens after the last one named)."""
    import sys

    from cli import _common

    def closing(argv):
        raise BrokenPipeError

    def checking(argv):  # as vade-goldens --check's main says what it leaves undone
        _common.UNDONE = "the goldens after the last one named were not checked"
        raise BrokenPipeError
    monkeypatch.setattr(_common, "closed_pipe", lambda stream: stream is sys.stdout)
    monkeypatch.setattr(_common, "_to_devnull", lambda stream: None)
    assert _common.run(checking) == 141
    capsys.readouterr()
    assert _common.run(closing) == 141  # (not the run before's)
    assert capsys.readouterr().err == "stopped: standard output was closed by its reader\n"
    assert _common.run(checking) == 141
    assert capsys.readouterr().err.endswith("reader; the goldens after the last one named "
                                            "were not checked\n")


def test_vade_record_whose_reader_goes_says_the_recording_was_written_whole(tmp_path):
    """A researcher's trial: ``vade-record long.json -o X | true`` said "stopped: standard
    output was closed by its reader" (141) of a recording written whole, which replayed.
    The recording is complete before its summary lines: the line says so (still 141)."""
    import subprocess
    import sys

    from conftest import COMMANDS, ROOT
    out = tmp_path / "gear.mcap"
    proc = subprocess.Popen([sys.executable, "-m", COMMANDS["vade-record"],
                             str(RECORDINGS / "gear_pendulum.json"), "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    proc.stdout.close()  # the reader goes before the run prints
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141
    assert err.splitlines()[-1] == (f"standard output was closed by its reader; the recording "
                                    f"was written whole ({out}); its summary lines were not "
                                    "shown")
    assert "stopped" not in err and "Traceback" not in err
    assert run_cli("vade-replay", str(out)).returncode == 0


def test_a_study_what_if_line_says_what_changed_in_the_analysis():
    """A researcher's trial: over several recordings a what-if's line ended "analysis
    changed", which told a study nothing; a lone recording's "analysis:" line lists the
    changes. Each recording's line now ends with them (up to three)."""
    files = [str(RECORDINGS / "drop_on_table.mcap"), str(RECORDINGS / "gear_pendulum.mcap")]
    result = run_cli("vade-replay", *files, "--set", "physics.gravity_scale_free=1.0")
    assert result.returncode == 0
    line = next(x for x in result.stdout.splitlines() if x.startswith(files[0]))
    alone = run_cli("vade-replay", files[0], "--set", "physics.gravity_scale_free=1.0")
    (changes,) = [x for x in alone.stdout.splitlines() if x.startswith("analysis: ")]
    assert "; analysis changed: " + changes[len("analysis: "):] + "; largest departure " in line
    assert line.endswith(" m, 0 rad (peg)")
    other = next(x for x in result.stdout.splitlines() if x.startswith(files[1]))
    assert "the recording is unchanged" in other and "analysis" not in other


def test_a_mesh_edited_between_takes_is_replaced_with_a_note_and_a_log_is_refused(tmp_path):
    """An engineer's trial: a mesh added to the base (the design edited, the same hands) was
    refused as "other tracker input (another take?)": every file of the session counted as
    tracker input. Only the tracker's own log does; an edited mesh is replaced with a note
    naming the file, and an edited log is still refused, as another take."""
    import trimesh

    from test_world_velocities import _shaft_placed, _with_log
    doc, files = _with_log(_shaft_placed())
    base = trimesh.creation.box(extents=[0.02, 0.02, 0.02])
    doc["base"]["shape"] = {"type": "compound", "children": [
        doc["base"]["shape"], {"type": "mesh", "file": "block.stl", "units": "m",
                               "pose": {"position": [0.1, 0.0, 0.0]}}]}
    files["block.stl"] = base.export(file_type="stl")
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    session = _write(tmp_path, doc)
    out = tmp_path / "take.mcap"
    assert run_cli("vade-record", str(session), "-o", str(out)).returncode == 0
    (tmp_path / "block.stl").write_bytes(
        trimesh.creation.box(extents=[0.03, 0.02, 0.02]).export(file_type="stl"))
    edited = run_cli("vade-record", str(session), "-o", str(out))
    assert edited.returncode == 0 and (f"note: replacing {out}, a recording of 'shaft_placed' "
                                       "made otherwise (its files, block.stl)") in edited.stderr
    log = tmp_path / "tracker.csv"
    log.write_text(log.read_text().replace("\n0.5,", "\n0.5000001,", 1))
    _assert_clean_error(run_cli("vade-record", str(session), "-o", str(out)),
                        "a recording of 'shaft_placed' with other tracker input", "--force")


def test_a_bad_set_value_is_named_by_its_set():
    """A --set that the changed session's schema refuses is named as given (an engineer's
    trial: "field parts[0].mass" for --set parts.sleeve.mass=-3), with the field it went to."""
    result = run_cli("vade-replay", str(RECORDINGS / "shaft_placed.mcap"),
                     "--set", "parts.sleeve.mass=-3")
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr == ("error: --set parts.sleeve.mass: -3 is less than or equal to the "
                             "minimum of 0 (the changed session's parts[0].mass)\n")


def test_a_file_cut_before_its_first_frame_says_how_little_it_holds(tmp_path):
    path = tmp_path / "c10.mcap"
    path.write_bytes((RECORDINGS / "drop_on_table.mcap").read_bytes()[:10])
    result = run_cli("vade-replay", str(path))
    assert result.returncode == 2
    assert result.stderr == (f"error: {path}: cut short before its first frame: no complete "
                             "frame to replay (the file holds only 10 bytes)\n")


def _flip_inside(path: Path, marker: bytes, offset: int = 0) -> None:
    data = bytearray(path.read_bytes())
    at = data.index(marker) + offset
    data[at] ^= 0x01
    path.write_bytes(bytes(data))


def test_a_damaged_stored_session_is_an_unusable_file_not_a_divergence(tmp_path):
    """One byte of the session stored in a recording changed (a friction 0.4 made 0.5 by a
    bad disk or a careless edit): the replay re-runs what is stored, so it was reported as
    the session diverging at frame 112 (a user's trial). The attachment's CRC-32 says it
    is damaged: exit 2, one line naming the file and what is damaged."""
    path = tmp_path / "wall.mcap"
    path.write_bytes((RECORDINGS / "plane_block_wall.mcap").read_bytes())
    _flip_inside(path, b'"static": 0.4', offset=12)
    result = run_cli("vade-replay", str(path))
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert str(path) in result.stderr and "the session stored in it is damaged" in result.stderr


def test_a_damaged_stored_mesh_file_is_named(tmp_path):
    import trimesh
    mesh = trimesh.creation.box(extents=[0.04, 0.04, 0.08]).export(file_type="obj")
    (tmp_path / "peg.obj").write_text(mesh)
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "mesh", "file": "peg.obj"}
    (tmp_path / "s.json").write_text(json.dumps(doc))
    out = tmp_path / "s.mcap"
    assert run_cli("vade-record", str(tmp_path / "s.json"), "-o", str(out)).returncode == 0
    assert run_cli("vade-replay", str(out)).returncode == 0
    _flip_inside(out, b"\nv ", offset=4)  # a vertex's first digit
    result = run_cli("vade-replay", str(out))
    assert result.returncode == 2 and "the file 'peg.obj' stored in it is damaged" \
        in result.stderr, result.stderr


def test_a_review_s_place_holding_other_data_is_refused_in_plain_words(tmp_path):
    """(A user's trial read "x.rrd holds a file that is not a rerun review, not a review".)"""
    notes = tmp_path / "x.rrd"
    notes.write_text("my notes on this session\n")
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--rerun",
                     str(notes))
    _assert_clean_error(result, f"{notes} holds other data, not a rerun review", "--force")
    assert notes.read_text() == "my notes on this session\n"


@pytest.mark.parametrize("command, option", [
    ("vade-replay", "--rerun"), ("vade-replay", "--events"), ("vade-replay", "--csv"),
    ("vade-replay", "-o"), ("vade-record", "-o")])
def test_a_folder_given_for_an_output_names_the_option(tmp_path, command, option):
    """(Users' trials: ``--rerun out``, and later ``-o out``, said "out: is a folder"
    without the option.)"""
    given = str(RECORDINGS / ("drop_on_table.mcap" if command == "vade-replay"
                              else "drop_on_table.json"))
    result = run_cli(command, given, option, str(tmp_path))
    _assert_clean_error(result, f"{tmp_path}: {option}: is a folder; give a file name")


@pytest.mark.parametrize("option, what", [("-o", "the regenerated recording"),
                                          ("--rerun", "the review"), ("--csv", "the table")])
def test_an_output_over_the_recording_replayed_says_what_it_would_write(option, what):
    """(A user's trial: "-o: refusing to write -o to s1.mcap".) It names what would have
    been written there."""
    golden = str(RECORDINGS / "drop_on_table.mcap")
    result = run_cli("vade-replay", golden, option, golden)
    _assert_clean_error(result, f"error: {option}: refusing to write {what} to {golden}, "
                                "which is also a recording replayed")


@pytest.mark.parametrize("where, typo, meant", [
    (("parts", 0), "densty", "density"), (("physics",), "gravty_scale_free", "gravity_scale_free")])
def test_a_misspelt_key_is_named_with_the_one_meant(tmp_path, where, typo, meant):
    """(A user's trial: an unknown key got only the list of allowed names, 35 for
    ``physics``.)"""
    doc = _doc()
    target = doc
    for key in where:
        target = target.setdefault(key, {}) if isinstance(key, str) else target[key]
    target[typo] = 1.0
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    _assert_clean_error(result, f"unknown field {typo!r} (a typo of {meant!r}?); allowed:")


@pytest.mark.parametrize("extents, given, warned", [
    ([40.0, 40.0, 80.0], None, "40 x 40 x 80 m across, too large"),   # CAD in mm
    ([40.0, 40.0, 80.0], "mm", None),    # its units given: as meant
    ([40.0, 40.0, 80.0], "m", "40 x 40 x 80 m across, too large"),    # given, and wrong
    ([0.04, 0.04, 0.08], None, None)])   # a peg of 4 x 4 x 8 cm
def test_a_mesh_in_other_units_than_the_session_is_warned_of_first(tmp_path, extents, given,
                                                                 warned):
    """(A user's trial: a peg drawn in millimetres in a metre session was warned of only as
    starting 6e+04 mm inside the table, and its grab refused as too heavy; an engineer's,
    the same with the wrong units given, "units": "m". One drawn in metres in a millimetre
    session is refused as under a millimetre across, scene.py.)"""
    import trimesh
    (tmp_path / "peg.stl").write_bytes(
        trimesh.creation.box(extents=extents).export(file_type="stl"))
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "mesh", "file": "peg.stl",
                                **({"units": given} if given else {})}
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning")]
    mesh = [line for line in lines if "peg.stl" in line]
    if warned is None:
        assert result.returncode == 0, result.stderr  # (no warning from a run that failed)
        assert not mesh, result.stderr
    else:
        advice = "are those units right?" if given else "give shape.units"
        assert len(mesh) == 1 and warned in mesh[0] and advice in mesh[0], result.stderr
        assert lines.index(mesh[0]) == 0  # before what it causes (inside the table, ...)


@pytest.mark.parametrize("size", [[40.0, 40.0, 80.0], [0.04, 0.04, 0.08]])
def test_a_session_in_mm_written_as_metres_is_warned_of_by_its_own_shapes(tmp_path, size):
    """A researcher's trial: a session of boxes and cylinders written in millimetres with
    "units": "m" (a metre example copied, mm numbers typed) built an 80 m pin of 23,533 t
    and said nothing (the size check looked at mesh files only). A part of its own shapes
    over 5 m across is warned of first; a 4 x 4 x 8 cm one is not."""
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "box", "size": size}
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning")]
    said = [line for line in lines if "too large for a part of an assembly" in line]
    if size[0] < 1.0:
        assert result.returncode == 0 and not said, result.stderr
        return
    assert len(said) == 1 and "40 x 40 x 80 m across" in said[0] \
        and 'another unit than its "units": "m"?' in said[0], result.stderr
    assert lines.index(said[0]) == 0  # before what it causes


def test_an_environment_object_in_another_unit_is_warned_of(tmp_path):
    """A review: a table of 1200 x 800 x 40 in a session in "m" (mm meant) was not warned
    of (only parts and the base were). An object over 50 m across is; a 1.2 m table not."""
    for size, warned in (([1200, 800, 40], True), ([1.2, 0.8, 0.04], False)):
        doc = _doc()
        doc["environment"] = [{"name": "table", "shape": {"type": "box", "size": size},
                               "pose": {"position": [0, 0, 0.72]}}]
        result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o",
                         str(tmp_path / "o.mcap"), "--force")
        said = [line for line in result.stderr.splitlines() if "environment[0].shape" in line]
        assert bool(said) == warned, result.stderr
        if warned:
            assert "table is 1.2e+03 x 800 x 40 m across" in said[0]


def test_a_constraint_that_fits_no_mesh_drawn_in_millimetres_says_so(tmp_path):
    """A CAD user's trial: a base part's mesh drawn in millimetres in a metre session, with
    an axis constraint, was refused only as "check point, direction and radius" (a
    correct constraint); the units warning, said before what the slip causes, never came,
    the constraint being refused first. The error says what is too large."""
    import trimesh
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    base = trimesh.creation.box(extents=[300.0, 300.0, 20.0])
    (tmp_path / "base.stl").write_bytes(base.export(file_type="stl"))
    doc["base"]["shape"] = {"type": "mesh", "file": "base.stl"}
    session = _write(tmp_path, doc)
    result = run_cli("vade-record", str(session), "-o", str(tmp_path / "o.mcap"))
    _assert_clean_error(result, "no base faces lie within the axis radius",
                        "(the base part is 300 x 300 x 20 m across: a mesh drawn in "
                        "millimetres? give its shape.units)")
    doc["base"]["shape"]["units"] = "mm"  # right now: the same constraint, no such word
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    _assert_clean_error(result, "no base faces lie within the axis radius")
    assert "millimetres" not in result.stderr


def test_bodies_of_a_mesh_are_counted():
    """``replay.body_count``: faces that share a vertex are one body."""
    import trimesh
    from vade_replay.replay import body_count
    box = trimesh.creation.box(extents=[0.02, 0.02, 0.02])
    tube = trimesh.creation.annulus(r_min=0.01, r_max=0.02, height=0.03, sections=64)
    three = trimesh.util.concatenate([box, box.copy().apply_translation([0.05, 0, 0]),
                                      tube.copy().apply_translation([0, 0.1, 0])])
    assert [body_count(m.faces) for m in (box, tube, three)] == [1, 1, 3]
    # A long chain of faces (labels spread end to end): still one.
    rod = trimesh.creation.box(extents=[1.0, 0.001, 0.001]).subdivide().subdivide().subdivide()
    assert body_count(rod.faces) == 1


@pytest.mark.parametrize("apart", [None, 0.05])
def test_a_part_s_mesh_of_two_bodies_is_warned_of(tmp_path, apart):
    """A CAD user's trial: two pegs exported as one STL were taken as one part (twice the
    mass, its centre of mass in the air between them) without a word."""
    import trimesh
    peg = trimesh.creation.box(extents=[0.02, 0.02, 0.04])
    mesh = peg if apart is None else trimesh.util.concatenate(
        [peg, peg.copy().apply_translation([apart, 0, 0])])
    (tmp_path / "pegs.stl").write_bytes(mesh.export(file_type="stl"))
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "mesh", "file": "pegs.stl"}
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    assert result.returncode == 0, result.stderr
    warned = [line for line in result.stderr.splitlines() if "separate bodies" in line]
    if apart is None:
        assert not warned
    else:
        assert len(warned) == 1 and "'pegs.stl' holds 2 separate bodies" in warned[0]
        assert "parts[0].shape" in warned[0]


@pytest.mark.parametrize("given", [None, "mm"])
def test_a_mesh_child_of_a_compound_in_other_units_is_warned_of(tmp_path, given):
    """The same slip inside a compound shape (a block with a peg drawn in millimetres): the
    warning names the child and its file; with the child's units given, none."""
    import trimesh
    (tmp_path / "peg.stl").write_bytes(
        trimesh.creation.box(extents=[40.0, 40.0, 80.0]).export(file_type="stl"))
    doc = _doc()
    doc["parts"][0]["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.04, 0.04, 0.02]},
        {"type": "mesh", "file": "peg.stl", **({"units": given} if given else {}),
         "pose": {"position": [0.0, 0.0, 0.05]}}]}
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    mesh = [line for line in result.stderr.splitlines()
            if line.startswith("warning") and "peg.stl" in line]
    if given:
        assert result.returncode == 0, result.stderr
        assert not mesh, result.stderr
    else:
        assert len(mesh) == 1, result.stderr
        assert "parts[0].shape.children[1] ('peg.stl')" in mesh[0]
        assert "too large for a part" in mesh[0] and "shape.units" in mesh[0]


def test_damaged_physics_metadata_is_not_restored_by_as_recorded(tmp_path):
    """MCAP's metadata carries no CRC: a user's trial changed the recorded model "general"
    to "General", and --as-recorded ran with a value no session allows. It is held to the
    session schema: exit 2 naming the metadata field; the plain replay is unaffected."""
    path = tmp_path / "wall.mcap"
    path.write_bytes((RECORDINGS / "plane_block_wall.mcap").read_bytes()
                     .replace(b'"general"', b'"General"', 1))
    result = run_cli("vade-replay", str(path), "--as-recorded")
    _assert_clean_error(result, str(path), "metadata physics.model", "'General'",
                        "without --as-recorded")
    assert run_cli("vade-replay", str(path)).returncode == 0


@pytest.mark.parametrize("keep", [8, None])
def test_a_length_damaged_near_the_start_is_not_taken_for_a_file_cut_short(tmp_path, keep):
    """(A user's trial: a byte of the stored session's length changed, in a file whole to
    its end, was reported as "cut short before its first frame".) The opening magic alone
    is still a file cut short."""
    import struct
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    path = tmp_path / "d.mcap"
    if keep is not None:
        path.write_bytes(bytes(data[:keep]))
        result = run_cli("vade-replay", str(path))
        _assert_clean_error(result, "cut short before its first frame")
        return
    at = 8
    while struct.unpack_from("<B", data, at)[0] != 0x09:  # to the first attachment
        at += 9 + struct.unpack_from("<Q", data, at + 1)[0]
    at += 9 + 16
    at += 4 + struct.unpack_from("<I", data, at)[0]  # its name
    at += 4 + struct.unpack_from("<I", data, at)[0]  # its media type
    data[at + 3] ^= 0x01  # its data's length, 2**24 bytes longer
    path.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(path))
    _assert_clean_error(result, str(path), "damaged near its start", "not cut short")


@pytest.mark.parametrize("value", ['"abc"', "0", "1e-12"])
def test_a_damaged_effective_step_in_the_metadata_is_not_restored(tmp_path, value):
    """(A review: a recorded ``turn_step_s`` restored through ``turn_max_step_s`` was not
    held to the schema: "abc" and 0 were tracebacks, 1e-12 ran for minutes.)"""
    path = tmp_path / "shaft.mcap"

    def edit_metadata(name, values):
        return {**values, "turn_step_s": value} if name == "physics" else values
    copy_recording(RECORDINGS / "shaft_placed.mcap", path, lambda topic, index, data: data,
                   edit_metadata=edit_metadata)
    result = run_cli("vade-replay", str(path), "--as-recorded")
    _assert_clean_error(result, str(path), "metadata physics.turn_max_step_s",
                        "without --as-recorded")


def _second_chunk_length_at(data: bytes) -> int:
    """The offset of the length field of the file's second chunk record (opcode 0x06)."""
    import struct
    at, chunks = 8, 0
    while True:
        opcode, length = struct.unpack_from("<BQ", data, at)
        if opcode == 0x06:
            chunks += 1
            if chunks == 2:
                return at + 1
        at += 9 + length


def test_a_chunk_length_damaged_in_a_whole_file_is_damage_not_a_crash(tmp_path):
    """(A review: a high byte of the second chunk's length changed, in a file whole to its
    closing magic, replayed the first 120 of 151 frames as a crash's and said "match".)"""
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    data[_second_chunk_length_at(data) + 2] ^= 0x01  # 64 KiB longer: past the file's end
    path = tmp_path / "d.mcap"
    path.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(path))
    _assert_clean_error(result, str(path), "damaged after 120 complete frames",
                        "not cut short")
    # Cut short for real (a crash): its complete frames replay, with a warning.
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes((RECORDINGS / "drop_on_table.mcap").read_bytes()[:20000]))
    assert run_cli("vade-replay", str(cut)).returncode == 0


@pytest.mark.parametrize("byte", [4, 7])
def test_an_impossible_length_near_the_start_of_a_whole_file_is_named_damage(tmp_path, byte):
    """(A review: a high byte of the stored session's length gave "not a readable MCAP file
    (MemoryError)" or "cannot fit 'int' into an index-sized integer".)"""
    import struct
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    at = 8
    while struct.unpack_from("<B", data, at)[0] != 0x09:
        at += 9 + struct.unpack_from("<Q", data, at + 1)[0]
    at += 9 + 16
    at += 4 + struct.unpack_from("<I", data, at)[0]
    at += 4 + struct.unpack_from("<I", data, at)[0]
    data[at + byte] ^= 0x40
    path = tmp_path / "d.mcap"
    path.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(path))
    _assert_clean_error(result, str(path), "damaged near its start")


def test_an_attachment_whose_name_is_damaged_is_not_called_a_file(tmp_path):
    path = tmp_path / "wall.mcap"
    path.write_bytes((RECORDINGS / "plane_block_wall.mcap").read_bytes())
    _flip_inside(path, b"session.json", offset=1)
    result = run_cli("vade-replay", str(path))
    _assert_clean_error(result, "the attachment whose name reads 'sdssion.json' (the "
                                "session or a file) stored in it is damaged")


def test_tracker_time_going_backwards_is_refused_naming_the_frame(tmp_path):
    # A recording vade-record cannot write (a tracker log's time never steps back there):
    # one edited so, or another tool's. The frames before it replay; then a clear error.
    def edit(topic, index, data):
        if topic == "/tracker" and index == 42:
            msg = json.loads(data)
            msg["time_ns"] -= 10**9 // 30  # two frames back
            return json.dumps(msg).encode()
        return data

    path = tmp_path / "back_in_time.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", path, edit)
    _assert_clean_error(run_cli("vade-replay", str(path)), "back_in_time.mcap", "frame 42",
                        "/tracker time_ns", "goes backwards")
    frames = []
    with pytest.raises(Exception, match="goes backwards"):
        for frame in Recording(path).frames():
            frames.append(frame.inputs.frame)
    assert frames == list(range(42))
    # A repeated time (a duplicated sample) is not refused.
    times = [f.inputs.time_ns for f in Recording(RECORDINGS / "drop_on_table.mcap").frames()]

    def repeat(topic, index, data):
        if topic == "/tracker" and index == 42:
            msg = json.loads(data)
            msg["time_ns"] = times[41]
            return json.dumps(msg).encode()
        return data

    same = tmp_path / "same_time.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", same, repeat)
    assert [f.inputs.time_ns for f in Recording(same).frames()] == \
        times[:42] + [times[41]] + times[43:]


@pytest.mark.parametrize("override", [
    "physics.friction_static=abc",        # the schema's check of the changed session
    "physics.nope=1",                     # an unknown physics name
    "foo=1",                              # nothing a --set can change
    "physics.contact_tolerance=3kg",      # a unit of the wrong kind
    "physics.contact_tolerance=3zz",      # an unknown unit
    "physics.contact_tolerance=1e400",    # not finite
    "physics.contact_tolerance=1e400mm",  # not finite once converted
    "parts.nope.mass=1",                  # no such part
    "tools.hoist=1",                      # a tool's key without its field
])
def test_every_set_error_begins_with_the_set_it_names(override):
    """(Left from the twelfth session's trial: a --set's error began "--set KEY:" where the
    changed session was refused and "field KEY:" where the key or value was.) One form:
    the option as typed, exit 2, no traceback."""
    key = override.partition("=")[0]
    result = run_cli("vade-replay", str(RECORDINGS / "plane_block_wall.mcap"), "--set",
                     override)
    _assert_clean_error(result)
    assert result.stderr.startswith(f"error: --set {key}: "), result.stderr


@pytest.mark.parametrize("args, option", [
    (["--set", "physics.grab_radius=15", "mm"], "--set"),
    (["--set", "parts.block.mass=12", "g"], "--set"),
    (["--tolerance", "1", "um"], "--tolerance"),
    (["--set", "physics.grab_radius=15", "MM"], "--set"),
])
def test_a_unit_split_off_its_value_is_named_before_anything_is_replayed(args, option):
    """(A user's trial: ``--set physics.grab_radius=15 mm`` replayed with 15 m, then
    stopped at "mm: no such file".) The unit, taken for a recording, is named as what it is,
    exit 2, before any replay."""
    result = run_cli("vade-replay", str(RECORDINGS / "plane_block_wall.mcap"), *args)
    _assert_clean_error(result, f"error: {option}: '{args[-1]}' is given as a recording, "
                                "and is a unit", "without a space")
    assert result.stdout == ""  # nothing replayed


def test_a_tolerance_s_angle_given_apart_is_named_and_a_loose_one_warned_of():
    """A researcher's trial: ``--tolerance 1mm 1deg`` replayed the study, then stopped at
    "1deg: no such file"; ``--tolerance 5`` took 5 m and 5 rad and matched any replay
    without a word. The one is refused before anything is replayed, the other warned of."""
    golden = str(RECORDINGS / "plane_block_wall.mcap")
    result = run_cli("vade-replay", golden, "--tolerance", "1mm", "1deg")
    _assert_clean_error(result, "error: --tolerance: '1deg' is given as a recording, and is "
                                "a value", "(--tolerance 1mm,1deg)")
    assert result.stdout == ""
    loose = run_cli("vade-replay", golden, "--tolerance", "5")
    assert loose.returncode == 0 and loose.stderr.startswith(
        "warning: --tolerance 5: 5 m and 5 rad, which a replay of other physics may be "
        "within")
    tight = run_cli("vade-replay", golden, "--tolerance", "1e-9")
    assert tight.returncode == 0 and "warning" not in tight.stderr


def test_vade_record_json_of_a_bad_session_prints_its_error_as_json(tmp_path):
    """A researcher's trial: ``vade-record --json`` of a bad session printed nothing on
    stdout (vade-replay --json gives ``{"recording", "error"}``): now
    ``{"session", "error"}``, with the error line and exit 2 as ever."""
    doc = json.loads((RECORDINGS / "drop_on_table.json").read_text())
    doc["parts"][0]["densty"] = 2700
    path = _write(tmp_path, doc)
    result = run_cli("vade-record", str(path), "-o", str(tmp_path / "r.mcap"), "--json")
    assert result.returncode == 2 and result.stderr.startswith("error: ")
    printed = json.loads(result.stdout)
    assert printed["session"] == str(path) and "densty" in printed["error"]
    assert printed["error"] == result.stderr.removeprefix("error: ").strip()


def test_a_tracker_message_that_is_not_json_names_its_frame(tmp_path):
    """A researcher's trial: frame 70's /tracker message cut by 10 bytes said "message on
    /tracker is not JSON" without the frame the README promises."""
    def edit(topic, index, data):
        return data[:-10] if topic == "/tracker" and index == 70 else data
    edited = tmp_path / "garbage.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", edited, edit)
    _assert_clean_error(run_cli("vade-replay", str(edited)),
                        f"error: {edited}: frame 70: message on /tracker is not JSON")


def test_one_unusable_recording_with_json_prints_its_entry_as_several_do(tmp_path):
    """(A user's trial: ``--json`` printed no JSON for one unusable recording, and an entry
    for it among several.) The same entry either way; the error line and exit 2 as ever."""
    missing = str(tmp_path / "missing.mcap")
    one = run_cli("vade-replay", missing, "--json")
    _assert_clean_error(one, f"{missing}: no such file")
    several = run_cli("vade-replay", missing, str(RECORDINGS / "drop_on_table.mcap"), "--json")
    assert several.returncode == 2
    assert json.loads(one.stdout) == json.loads(several.stdout)[0] == {
        "recording": missing, "error": f"{missing}: no such file"}


def test_a_run_in_which_no_hand_took_a_part_says_so(tmp_path):
    """(An engineer's trial: a hand scripted 110 mm above its part closed on nothing, and
    the run said only "never placed", or nothing.) The count of closes on nothing is said
    when no part was grabbed at all; the golden's own run does not say it."""
    doc = _doc()
    ok = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "a.mcap"))
    assert ok.returncode == 0 and "no part was grabbed" not in ok.stdout
    for kf in doc["tracker"]["devices"]["right_hand"]:
        if "position" in kf:
            kf["position"][2] += 0.3
    missed = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "b.mcap"))
    assert missed.returncode == 0
    assert ("no part was grabbed: a hand closed 1 time with nothing in reach (a part's box "
            "within physics.grab_radius of the hand; --events lists each)") in missed.stdout


@pytest.mark.parametrize("recording, override, why", [
    ("throw_and_catch", "physics.friction_static=0.9",
     " (no part was on the base part, where it acts)"),
    ("shaft_placed", "physics.gravity_scale_free=0.5", " (no part flew, where it acts)"),
    ("shaft_placed", "physics.friction_static=0.9", ""),  # on the base: no reason to give
])
def test_a_what_if_that_changes_nothing_says_why_where_no_part_was_where_it_acts(
        recording, override, why):
    """(Users' trials: friction what-ifs of sessions whose parts never lay on the base said
    only "the recording is unchanged".) Where no part was ever where a key acts, it says
    so; where one was (a part on a vertical shaft has no load for friction), no reason is
    made up."""
    result = run_cli("vade-replay", str(RECORDINGS / f"{recording}.mcap"), "--set", override)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"what-if ({override}): the recording is unchanged{why}, "
                                    "match:"), result.stdout


def test_a_constraint_s_tolerance_is_not_said_to_act_on_the_base():
    """A constraint's tolerances act as a part is let go near it (a review of the reasons):
    no reason is given for them; its friction acts on the base."""
    from types import SimpleNamespace

    from cli.replay import _why_unchanged
    flying = SimpleNamespace(analysis={"parts": {"peg": {
        "time_in_state_s": {"INHAND": 1.0, "INSPACE": 0.5, "STATIC": 1.0}, "tool_grabs": 0}}})
    key = "parts.peg.constraints.pin.tolerance.distance"
    assert _why_unchanged({key: "0.01"}, flying) == ""
    assert _why_unchanged({"parts.peg.constraints.pin.friction.static": "0.9"}, flying) == \
        " (no part was on the base part, where it acts)"
    assert _why_unchanged({"tools.hoist.max_mass_kg": "1"}, flying) == " (no tool took a part)"
    assert _why_unchanged({"physics.gravity_scale_free": "1"}, flying) == ""  # it flew


def test_a_hand_passing_through_the_table_is_warned_of(tmp_path):
    """(An engineer's trial: a keyframe typed 85 for 805 mm dragged the held part through
    the table and under it, without a word; a held part is stopped by nothing.) A device
    over an obstacle and then under it, within its footprint, is named with the frame;
    going round its edge is not passing through; the golden's own run says nothing."""
    doc = _doc()
    ok = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "a.mcap"))
    assert ok.returncode == 0 and "passes through" not in ok.stderr
    carried = doc["tracker"]["devices"]["right_hand"][3]
    assert carried["t"] == 1.2  # the peg held, carried up
    carried["position"] = [0.05, 0.05, 0.11]  # typed 0.11 for 1.1: under the table
    typo = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "b.mcap"))
    assert typo.returncode == 0
    (line,) = [x for x in typo.stderr.splitlines() if "passes through" in x]
    assert line.startswith("warning: ") and "right_hand passes through table by frame " in line and "(1 more such)" in line
    assert line.endswith("a part it holds goes through with it (a held part is stopped by "
                         "nothing); a position mistyped?")
    # Under the table beside it, reached round its edge, and back up beside it.
    carried["position"] = [0.9, 0.05, 0.11]
    doc["tracker"]["devices"]["right_hand"].insert(3, {"t": 0.95, "position": [0.9, 0.0, 0.9]})
    doc["tracker"]["devices"]["right_hand"][6]["position"] = [0.9, -0.2, 1.1]
    around = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "c.mcap"))
    assert "passes through" not in around.stderr, around.stderr


class _FillsUp:
    """A file that takes ``room`` bytes and then fails as a full disk does."""

    def __init__(self, stream, room: int) -> None:
        self._stream, self._room = stream, room

    def write(self, data) -> int:
        import errno
        import os
        if len(data) > self._room:
            self._room = 0  # full: nothing more fits
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._room -= len(data)
        return self._stream.write(data)

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        self._stream.close()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def test_a_full_disk_is_one_line_and_exit_2_and_keeps_what_was_written(tmp_path, monkeypatch):
    """A user's trial: a disk filling up while a long session was recorded gave a
    traceback and exit 1 (which means "diverged"). It is one line naming the file, exit 2,
    and the frames written before it are kept and replay (a partial file cut short); a disk
    full from the start leaves no file."""
    from vade_replay import recording as recording_module
    doc = _doc()
    doc["tracker"]["duration_s"] = 20.0
    session = tmp_path / "long.json"
    session.write_text(json.dumps(doc))
    real_open = recording_module._open_alone
    room = {"bytes": 60_000}
    monkeypatch.setattr(recording_module, "_open_alone",
                        lambda path: _FillsUp(real_open(path), room["bytes"]))
    out = tmp_path / "long.mcap"
    result = run_cli("vade-record", str(session), "-o", str(out))
    partial = Path(f"{out}.partial").resolve()
    assert result.returncode == 2 and "Traceback" not in result.stderr
    (line,) = [l for l in result.stderr.splitlines() if l.startswith("error:")]
    assert line.startswith(f"error: {partial}: frame ") and line.endswith(
        f": cannot write it: No space left on device (the frames written before it are kept "
        f"in {partial}, cut short: vade-replay reads them)")
    assert not out.exists()
    monkeypatch.undo()
    kept = run_cli("vade-replay", str(partial))
    assert kept.returncode == 0 and "the recording was cut short" in kept.stderr
    assert kept.stdout.startswith("match: ")
    partial.unlink()
    # Full from the start: nothing is left behind.
    monkeypatch.setattr(recording_module, "_open_alone",
                        lambda path: _FillsUp(real_open(path), 0))
    result = run_cli("vade-record", str(session), "-o", str(out))
    assert result.returncode == 2 and result.stderr.endswith(
        f"cannot write it: No space left on device\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.json"]


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full here")
def test_standard_output_that_takes_nothing_or_is_closed_is_no_traceback(tmp_path):
    """A user's trial: ``> /dev/full`` gave a traceback and exit 1; a standard output
    closed (``>&-``, a detached job) a traceback, exit 1 and the study's table unwritten."""
    import subprocess
    import sys
    golden = RECORDINGS / "drop_on_table.mcap"
    full = subprocess.run(f"{sys.executable} -m vade_replay.cli.replay {golden} --json "
                          "> /dev/full", shell=True, capture_output=True, text=True)
    assert (full.returncode, full.stderr) == (
        2, "error: standard output: cannot write it: No space left on device\n")
    table = tmp_path / "study.csv"
    closed = subprocess.run(f"{sys.executable} -m vade_replay.cli.replay {golden} --csv {table}"
                            " >&-", shell=True, capture_output=True, text=True)
    assert (closed.returncode, closed.stderr) == (0, "")
    assert table.read_text().startswith("recording,")
    # A recording written to a device that takes nothing.
    result = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", "/dev/full")
    assert result.returncode == 2 and result.stderr == (
        "error: /dev/full: frame 61: cannot write it: No space left on device\n")


def test_a_review_that_cannot_be_written_whole_leaves_the_one_before(tmp_path, monkeypatch):
    """A user's trial: a full disk left a review cut short at its path. A review is written
    beside its path and moved there whole: one that fails leaves what was there."""
    from vade_replay import view
    out = tmp_path / "run.rrd"
    golden = str(RECORDINGS / "drop_on_table.mcap")
    assert run_cli("vade-replay", golden, "--rerun", str(out)).returncode == 0
    before = out.read_bytes()

    def fails(rec, *args):
        rec.flush()
        raise view._unwritable(RuntimeError("Failed to write: No space left on device"),
                               args[-1])
    monkeypatch.setattr(view, "_write_runs", fails)
    result = run_cli("vade-replay", golden, "--rerun", str(out))
    assert result.returncode == 2 and result.stderr == (
        f"error: {out}: cannot write the review here (Failed to write: No space left on "
        "device)\n")
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.rrd"]
    monkeypatch.undo()
    assert run_cli("vade-replay", golden, "--rerun", str(out)).returncode == 0
    assert out.stat().st_mode & 0o777 == 0o666 & ~_umask()


def _umask() -> int:
    import os
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_a_what_if_that_moved_no_part_says_so_in_words():
    """A user's trial: "largest departure: peg none" where a what-if changed only the
    events; the study's line said "no part departed". Both say it in words now."""
    from types import SimpleNamespace

    from vade_replay.cli.replay import _departure_text
    none = {"peg": {"distance_m": 0.0, "angle_rad": 0.0, "distance_frame": None,
                    "angle_frame": None}}
    moved = {**none, "pin": {"distance_m": 0.002, "angle_rad": 0.0, "distance_frame": 7,
                             "angle_frame": None}}
    assert _departure_text(SimpleNamespace(largest_departure=none), short=False) == (
        "\nno part departed (what differs is not where a part is)")
    assert _departure_text(SimpleNamespace(largest_departure=none), short=True) == (
        "; no part departed")
    assert _departure_text(SimpleNamespace(largest_departure=moved), short=False) == (
        "\nlargest departure: peg none; pin 0.002 m (frame 7)")


def test_a_suggested_command_quotes_a_path_with_a_space(tmp_path):
    """A user's trial: "open with `rerun sp ace/r.rrd`" failed when pasted (a study folder
    synced from Windows has spaces). The paths in a suggested command are quoted for the
    shell; a plain one is left as it is."""
    import shutil
    folder = tmp_path / "sp ace"
    folder.mkdir()
    shutil.copy(RECORDINGS / "drop_on_table.mcap", folder / "r ü.mcap")
    review = folder / "r ü.rrd"
    result = run_cli("vade-replay", str(folder / "r ü.mcap"), "--rerun", str(review))
    assert result.returncode == 0
    assert f"open with `rerun '{review}'`" in result.stderr + result.stdout
    plain = tmp_path / "plain.rrd"
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--rerun",
                     str(plain))
    assert f"open with `rerun {plain}`" in result.stderr + result.stdout


def test_a_flipped_bit_in_a_record_s_text_or_a_name_reads_as_damage(tmp_path):
    """A user's trial, a bit flipped at every 97th byte of a recording: a metadata record's
    text no longer UTF-8 read "not a readable MCAP file ('utf-8' codec ...)", and the parts
    encoding's name "unknown parts encoding 'chanfed' (this version reads ...)", where
    every other damage says damaged."""
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    at = data.index(b"platform") + 1  # the versions metadata's
    data[at] ^= 0x80  # no longer UTF-8
    damaged = tmp_path / "schema.mcap"
    damaged.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(damaged))
    assert result.returncode == 2 and result.stderr.startswith(
        f"error: {damaged}: damaged near its start: a record there cannot be read ('utf-8' "
        "codec can't decode")
    data = bytearray((RECORDINGS / "drop_on_table.mcap").read_bytes())
    at = data.index(b"changed")
    data[at + 3] ^= 0x01  # "chaoged"
    damaged = tmp_path / "name.mcap"
    damaged.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(damaged))
    assert result.returncode == 2 and result.stderr == (
        f"error: {damaged}: field metadata encoding.parts: unknown parts encoding 'chaoged': "
        "damaged, or written by a newer version (this version reads full, changed)\n")


def test_a_device_or_pipe_given_as_a_recording_is_named_so_and_no_pipe_output_waits(tmp_path):
    """A user's trial: /dev/null and a named pipe given to replay read "no such file"
    (they exist); ``-o`` a named pipe with no reader blocked for ever in its open."""
    import os
    fifo = tmp_path / "fifo.mcap"
    os.mkfifo(fifo)
    for given in (os.devnull, str(fifo)):
        result = run_cli("vade-replay", given)
        assert result.returncode == 2 and result.stderr == (
            f"error: {given}: not a file (a device or a pipe): a recording is read from its "
            "file\n")
    refused = (f"error: {fifo}: cannot write a recording to a pipe: an MCAP file is written "
               "with offsets into it; give a file\n")
    # (In processes of their own, with a time limit: a refusal broken would block in the
    # open, not fail.)
    result = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(fifo),
                     process=True)
    assert (result.returncode, result.stderr) == (2, refused)
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "-o", str(fifo),
                     process=True)
    assert (result.returncode, result.stderr) == (2, refused)
    # A review likewise (a review: it blocked in rerun's open for ever).
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--rerun",
                     str(fifo), process=True)
    assert (result.returncode, result.stderr) == (
        2, f"error: {fifo}: cannot write a review to a named pipe: give a file\n")


def test_standard_output_full_with_python_s_own_buffer_is_still_one_line(tmp_path):
    """A review: with standard output buffered (no PYTHONUNBUFFERED, as in a user's shell),
    what the buffer held was flushed again at the interpreter's exit, failed, and the run
    ended "Exception ignored" and exit 120."""
    import os
    import subprocess
    import sys
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    done = subprocess.run(f"{sys.executable} -m vade_replay.cli.replay "
                          f"{RECORDINGS / 'drop_on_table.mcap'} > /dev/full", shell=True,
                          capture_output=True, text=True, env=env)
    assert (done.returncode, done.stderr) == (
        2, "error: standard output: cannot write it: No space left on device\n")


def test_a_regeneration_whose_standard_output_fails_still_remakes_all_or_none(tmp_path):
    """A review: the goldens were moved one by one, each printed as it went; standard output
    failing stopped it after the first, some goldens remade and the rest not. All are
    moved first, then printed."""
    import os
    import shutil
    import subprocess
    import sys
    names = ("drop_on_table", "plane_block_wall")
    for name in names:
        for suffix in (".json", ".mcap"):
            shutil.copy(RECORDINGS / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
        doc = json.loads((tmp_path / f"{name}.json").read_text())
        doc["description"] = "described again: its golden changes"
        (tmp_path / f"{name}.json").write_text(json.dumps(doc))
    before = {n: (tmp_path / f"{n}.mcap").read_bytes() for n in names}
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    for unbuffered in ("", "1"):
        done = subprocess.run(f"{sys.executable} -m vade_replay.cli.goldens --dir {tmp_path} "
                              "> /dev/full", shell=True, capture_output=True, text=True,
                              env={**env, **({"PYTHONUNBUFFERED": "1"} if unbuffered else {})})
        assert done.returncode in (0, 2) and "Traceback" not in done.stderr
        assert all((tmp_path / f"{n}.mcap").read_bytes() != before[n] for n in names)
        for n in names:
            shutil.copy(RECORDINGS / f"{n}.mcap", tmp_path / f"{n}.mcap")


def test_sigterm_not_taken_in_time_ends_the_run_at_once(monkeypatch, tmp_path):
    """A review: a review's file writer stuck on a full disk held the main thread inside
    rerun's native flush, where Python's SIGTERM handler never runs, and SIGTERM, which
    used to end the process, no longer could. A watchdog woken by the signal ends the
    process (exit 143) when no Terminated was raised within the grace; none where one
    was. Ended so, it removes the half-written review's or table's hidden temporary file
    first (it was left beside the review's path)."""
    import os
    import signal
    import threading

    from vade_replay.cli import _common
    from vade_replay.errors import TERMINATED_RAISED
    from vade_replay.tables import forget_temp, temp_beside
    ended = threading.Event()
    codes = []

    def end(code):
        codes.append(code)
        ended.set()
    monkeypatch.setattr(_common.os, "_exit", end)
    monkeypatch.setattr(_common, "_TERM_GRACE_S", 0.2)
    previous = signal.signal(signal.SIGTERM, lambda *a: None)  # a handler that takes nothing
    kept = ""
    try:
        fd, half = temp_beside(tmp_path / "review.rrd")
        os.close(fd)
        with _common._TermWatch():
            os.kill(os.getpid(), signal.SIGTERM)
            assert ended.wait(5.0)
        assert codes == [143]
        assert not Path(half).exists()
        codes.clear()
        ended.clear()
        fd, kept = temp_beside(tmp_path / "table.csv")
        os.close(fd)
        with _common._TermWatch():
            TERMINATED_RAISED.set()  # as raise_terminated does
            os.kill(os.getpid(), signal.SIGTERM)
            assert not ended.wait(0.6)
        assert codes == [] and Path(kept).exists()  # the run's own ending removes it
    finally:
        signal.signal(signal.SIGTERM, previous)
        forget_temp(kept)


def test_standard_error_that_takes_nothing_or_closed_streams_keep_the_exit_code(tmp_path):
    """A review: an error line that could not be written (``2> /dev/full``) made exit 1,
    "diverged"; with standard output and error both closed, the recording being written
    took descriptor 2, where anything below Python writes."""
    import subprocess
    import sys
    command = Path(sys.executable).parent / "vade-replay"  # the installed entry point
    missing = tmp_path / "missing.mcap"
    done = subprocess.run(f"{command} {missing} 2>/dev/full", shell=True,
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 2
    out = tmp_path / "out.mcap"
    done = subprocess.run(f"{command} {RECORDINGS / 'drop_on_table.mcap'} -o {out} >&- 2>&-",
                          shell=True, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0
    result = run_cli("vade-replay", str(out))
    assert result.returncode == 0 and result.stdout.startswith("match: 151 frames")


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # (the export)
@pytest.mark.parametrize("where, name", [("base", "block.glb"), ("parts[0]", "sleeve.ply")])
def test_a_binary_ply_or_glb_with_a_nan_vertex_is_refused_by_name(tmp_path, where, name):
    """A CAD user's trial: a base's GLB, a part's binary PLY, with a vertex of NaN lost the
    faces naming it in trimesh's processing (the base a few faces short without a word, the
    part "not watertight"). Refused as the other formats are: the file and the count named,
    exit code 2, no traceback; nothing written."""
    import numpy as np
    import trimesh
    mesh = trimesh.creation.box(extents=[0.12, 0.12, 0.04] if where == "base"
                                else [0.02, 0.02, 0.03])
    mesh.vertices[5] = [np.nan, np.nan, 0.02]
    (tmp_path / name).write_bytes(mesh.export(file_type=name.rsplit(".", 1)[1]))
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    body = doc["base"] if where == "base" else doc["parts"][0]
    body["shape"] = {"type": "mesh", "file": name}
    result = run_cli("vade-record", str(_write(tmp_path, doc)), "-o", str(tmp_path / "o.mcap"))
    _assert_clean_error(result, "s.json", f"{where}.shape.file",
                        f"mesh {name!r} holds 2 coordinates that are not finite (NaN or "
                        "infinite): fix the export")
    assert not list(tmp_path.glob("*.mcap*"))


def test_ctrl_c_while_the_tracker_log_is_read_says_nothing_was_recorded(tmp_path, monkeypatch):
    """A researcher's trial: Ctrl-C while a long log was read (before the first frame)
    printed only "interrupted"; it says nothing was recorded, and nothing is left."""
    from vade_replay.session import Session

    def reading(self):
        raise KeyboardInterrupt
    monkeypatch.setattr(Session, "tracker_frames", reading)
    out = tmp_path / "o.mcap"
    result = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(out))
    assert result.returncode == 130
    assert result.stderr == ("interrupted; nothing was recorded (the tracker log was being "
                             "read)\n")
    assert list(tmp_path.iterdir()) == []
