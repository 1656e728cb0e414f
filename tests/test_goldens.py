"""Golden recordings are regression tests: each replays exactly; a changed value is caught."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from conftest import RECORDINGS, run_cli
from mcap_edit import copy_recording, nudge_pose
from vade_replay.recording import Recording
from vade_replay.replay import replay

GOLDENS = sorted(RECORDINGS.glob("*.mcap"))


def test_every_session_has_a_golden():
    sessions = sorted(p.stem for p in RECORDINGS.glob("*.json"))
    assert sessions, "no sessions in recordings/"
    assert sessions == [p.stem for p in GOLDENS]
    for required in ("drop_on_table", "throw_and_catch", "tumbling_box"):
        assert required in sessions


def test_goldens_were_recorded_against_this_schema():
    """Each golden's digest (metadata 'validated') is of this version's session schema and
    validator, so replaying it skips validation as a user's fresh recording does (and the
    benchmark's figures for the goldens mean that). After a change to the schema or to
    jsonschema, regenerate them with `vade-goldens`: their messages will not change."""
    from vade_replay.session import validated_digest
    stale = []
    for golden in GOLDENS:
        recording = Recording(golden)
        if recording.metadata.get("validated", {}).get("session") != \
                validated_digest(recording.session.raw):
            stale.append(golden.name)
    assert not stale, f"regenerate with vade-goldens: {stale}"


@pytest.mark.parametrize("golden", GOLDENS, ids=[p.stem for p in GOLDENS])
def test_golden_replays_exactly(golden: Path):
    summary = replay(Recording(golden))
    assert summary.first_divergence is None, summary.first_divergence
    assert summary.match and summary.frames > 10
    assert summary.messages_checked >= 2 * summary.frames


def test_changed_pose_is_named_with_its_frame(tmp_path: Path):
    target_frame = 100
    tampered = tmp_path / "tampered.mcap"
    nudge_pose(RECORDINGS / "drop_on_table.mcap", tampered, frame=target_frame, axis=2,
               delta=1e-12)
    result = run_cli("vade-replay", str(tampered))
    assert result.returncode == 1, result.stderr
    assert f"frame {target_frame}" in result.stdout
    assert "/parts" in result.stdout and "peg" in result.stdout and "position[2]" in result.stdout
    result = run_cli("vade-replay", str(tampered), "--json")
    summary = json.loads(result.stdout)
    assert result.returncode == 1
    assert summary["match"] is False
    assert summary["first_divergence"]["frame"] == target_frame
    assert summary["first_divergence"]["part"] == "peg"
    assert summary["first_divergence"]["field"] == "position[2]"


def test_missing_event_is_a_divergence(tmp_path: Path):
    def edit(topic, index, data):
        return None if topic == "/events/ModeChanged" and index == 1 else data

    tampered = tmp_path / "no_event.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", tampered, edit)
    summary = replay(Recording(tampered))
    assert not summary.match
    assert summary.first_divergence["channel"] == "/events/ModeChanged"


def test_embedded_scene_is_enough(tmp_path: Path):
    """Record from a folder with a mesh file, delete the folder, replay the recording."""
    import trimesh

    folder = tmp_path / "session"
    folder.mkdir()
    trimesh.creation.cylinder(radius=0.02, height=0.06, sections=24).export(folder / "peg.stl")
    doc = json.loads((RECORDINGS / "drop_on_table.json").read_text())
    doc["parts"][0]["shape"] = {"type": "mesh", "file": "peg.stl"}
    (folder / "s.json").write_text(json.dumps(doc))
    out = tmp_path / "s.mcap"
    assert run_cli("vade-record", str(folder / "s.json"), "-o", str(out)).returncode == 0
    shutil.rmtree(folder)
    result = run_cli("vade-replay", str(out), process=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "match" in result.stdout


def test_regenerated_recording_replays(tmp_path: Path):
    out = tmp_path / "again.mcap"
    summary = replay(Recording(RECORDINGS / "throw_and_catch.mcap"), out=out)
    assert summary.match
    again = replay(Recording(out))
    assert again.match and again.frames == summary.frames


@pytest.mark.parametrize("session", sorted(RECORDINGS.glob("*.json")), ids=lambda p: p.stem)
def test_recording_a_session_again_gives_its_golden(session: Path, tmp_path: Path):
    out = tmp_path / "again.mcap"
    assert run_cli("vade-record", str(session), "-o", str(out)).returncode == 0
    again = [(f.inputs, f.derived) for f in Recording(out).frames()]
    golden = [(f.inputs, f.derived) for f in Recording(session.with_suffix(".mcap")).frames()]
    assert again == golden
    assert run_cli("vade-replay", str(out)).returncode == 0


def test_signed_zero_is_a_difference_and_spacing_is_not(tmp_path: Path):
    """Bit for bit means -0.0 differs from 0.0, though they compare equal as numbers; text
    that reads back to the same values is the same (``tests/test_value_check.py``)."""
    from vade_replay.replay import _divergence

    inputs = next(Recording(RECORDINGS / "drop_on_table.mcap").frames()).inputs
    found = _divergence(inputs, [("/parts", b'{"x":-0.0}')], [("/parts", b'{"x":0.0}')])
    assert found is not None and found.field == "x"
    assert _divergence(inputs, [("/parts", b'{"x": 1.0}')], [("/parts", b'{"x":1.0}')]) is None
    found = _divergence(inputs, [("/parts", b'{"x": 1.0}'), ("/parts", b'{"x":3}')],
                        [("/parts", b'{"x":1.0}'), ("/parts", b'{"x":3.0}')])
    assert found is not None and found.field == "x" and (found.recorded, found.replayed) == (3, 3.0)


def test_goldens_check_finds_a_stale_session_and_a_cut_golden_and_remakes_all_or_none(tmp_path):
    """From a developer's trial: a session file edited after its golden was made checked
    as ``match`` (the check replays the session inside the golden); a golden cut short
    replayed its first frames and said ``match``; one bad session stopped a regeneration
    half way, the goldens a mix of old and new. Now: stale (exit 1, naming the field), cut
    short (exit 2), and a regeneration with a bad session writes no golden at all."""
    import shutil

    from conftest import run_cli
    for name in ("plane_block_wall", "gear_pendulum"):
        for suffix in (".json", ".mcap"):
            shutil.copy(RECORDINGS / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
    assert run_cli("vade-goldens", "--check", "--dir", str(tmp_path)).returncode == 0
    # Made again here first: a golden holds the package versions that wrote it, which a
    # fresh install may not share; the bytes compared below are this install's.
    assert run_cli("vade-goldens", "--dir", str(tmp_path)).returncode == 0
    session = tmp_path / "plane_block_wall.json"
    doc = json.loads(session.read_text())
    doc["parts"][0]["assembly"]["constraints"][0]["friction"]["static"] = 0.35
    session.write_text(json.dumps(doc, indent=1))
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 1
    assert (f"{tmp_path / 'plane_block_wall.mcap'}: STALE: {session} changed since its golden "
            "was made (field parts[0].assembly.constraints[0].friction.static: 0.4 in the "
            "golden, 0.35 now); regenerate it") in result.stdout
    assert result.stdout.splitlines()[-1] == ("2 goldens: 1 match, 0 diverged, 1 stale, 0 "
                                              "could not be replayed")
    # The same values written otherwise (spacing, key order) are the same session.
    session.write_text(json.dumps(json.loads((RECORDINGS / "plane_block_wall.json")
                                             .read_text()), indent=3, sort_keys=True))
    assert run_cli("vade-goldens", "--check", "--dir", str(tmp_path)).returncode == 0
    golden = tmp_path / "gear_pendulum.mcap"
    data = golden.read_bytes()
    golden.write_bytes(data[:len(data) // 2])
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path), "gear_pendulum")
    assert result.returncode == 2 and "cut short (a crash while it was written)" in \
        result.stderr and "Traceback" not in result.stderr
    # A regeneration with one bad session: named, and no golden written, not even the
    # good ones before it in name order.
    golden.write_bytes(data)
    (tmp_path / "a_bad.json").write_text("{not json")
    before = {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")}
    result = run_cli("vade-goldens", "--dir", str(tmp_path))
    assert result.returncode == 2 and "a_bad.json" in result.stderr
    assert "cannot be recorded: no golden was written" in result.stderr
    assert {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")} == before
    (tmp_path / "a_bad.json").unlink()
    shutil.copy(RECORDINGS / "plane_block_wall.json", session)  # its own bytes again
    assert run_cli("vade-goldens", "--dir", str(tmp_path)).returncode == 0
    assert {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")} == before


def test_a_second_regeneration_of_a_folder_waits_its_turn(tmp_path, monkeypatch):
    """Two at once wrote the same NAME.mcap.partial files and renamed them from under each
    other; the second is now refused while the first holds the folder's lock."""
    import fcntl
    import shutil

    from conftest import run_cli
    shutil.copy(RECORDINGS / "drop_on_table.json", tmp_path / "drop_on_table.json")
    with open(tmp_path / ".vade-goldens.lock", "a") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)
        result = run_cli("vade-goldens", "--dir", str(tmp_path))
        assert result.returncode == 2 and "another vade-goldens is regenerating this folder" \
            in result.stderr
        assert not (tmp_path / "drop_on_table.mcap").exists()
        # Checking needs no lock.
        assert run_cli("vade-goldens", "--check", "--dir", str(tmp_path)).returncode == 2
    assert run_cli("vade-goldens", "--dir", str(tmp_path)).returncode == 0
    # (A newcomer's trial: the lock file stayed in the user's goldens folder.)
    assert not (tmp_path / ".vade-goldens.lock").exists()
    # A lock taken on a file another run removed (opened just before) is no lock: the path
    # now names another file, and the run is refused.
    import os

    from cli import goldens
    from vade_replay.errors import ConfigError
    real_stat = os.stat

    class _Other:
        st_ino = -1

    monkeypatch.setattr(goldens.os, "stat", lambda path, *a, **k: _Other()
                        if str(path).endswith(".vade-goldens.lock") else real_stat(path, *a, **k))
    with pytest.raises(ConfigError, match="another vade-goldens is regenerating"):
        goldens._lock(tmp_path)


def test_a_regeneration_says_what_it_changed_in_each_golden(tmp_path, monkeypatch):
    """For the commit that remakes goldens: each line says unchanged, new, only the session
    text or metadata changed, or the first frame that differs (a friction edit)."""
    for name in ("plane_block_wall", "drop_on_table"):
        for suffix in (".json", ".mcap"):
            shutil.copy(RECORDINGS / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
    before = {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")}
    # The shipped goldens hold the package versions and the machine that wrote them:
    # another install's differ only there, and such a golden is kept as it was (a
    # developer's trial: every golden rewritten for its kernel's build name).
    from vade_replay import recording as recording_module
    made_here = recording_module.package_versions()
    monkeypatch.setattr(recording_module, "package_versions",
                        lambda: {**made_here, "platform": "another machine"})
    result = run_cli("vade-goldens", "--dir", str(tmp_path))
    assert result.returncode == 0
    assert [line.split("; ", 1)[1] for line in result.stdout.splitlines()] == [
        "unchanged (only its versions metadata differs: kept as it was)"] * 2
    assert {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")} == before
    monkeypatch.undo()
    stamps = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in tmp_path.glob("*.mcap")}
    result = run_cli("vade-goldens", "--dir", str(tmp_path))
    assert result.returncode == 0
    assert all(line.endswith(("; unchanged", "; unchanged (only its versions metadata "
                                              "differs: kept as it was)"))
               for line in result.stdout.splitlines()), result.stdout
    # An unchanged golden's file is left alone, not written again the same (a user's trial:
    # a new file and time for make, rsync and backups).
    assert {p.name: (p.stat().st_ino, p.stat().st_mtime_ns)
            for p in tmp_path.glob("*.mcap")} == stamps
    result = run_cli("vade-goldens", "--dir", str(tmp_path), "drop_on_table")
    # (The first ending on the machine that made the shipped goldens, the second elsewhere.)
    assert result.stdout.endswith(("; unchanged\n", "; unchanged (only its versions metadata "
                                                     "differs: kept as it was)\n")), result.stdout
    assert {p.name: (p.stat().st_ino, p.stat().st_mtime_ns)
            for p in tmp_path.glob("*.mcap")} == stamps
    wall = tmp_path / "plane_block_wall.json"
    doc = json.loads(wall.read_text())
    doc["parts"][0]["assembly"]["constraints"][0]["friction"]["dynamic"] = 0.25
    wall.write_text(json.dumps(doc))
    drop = tmp_path / "drop_on_table.json"
    doc = json.loads(drop.read_text())
    doc["description"] = "the same drop, described again"
    drop.write_text(json.dumps(doc))
    result = run_cli("vade-goldens", "--dir", str(tmp_path))
    lines = result.stdout.splitlines()
    # (With "versions" too where the kept golden was made on another machine.)
    assert lines[0].endswith(("; frames unchanged; session, validated changed",
                              "; frames unchanged; session, validated, versions changed"))
    assert "; frames differ from frame " in lines[1]
    (tmp_path / "drop_on_table.mcap").unlink()
    result = run_cli("vade-goldens", "--dir", str(tmp_path), "drop_on_table")
    assert result.stdout.splitlines() == [f"{tmp_path / 'drop_on_table.mcap'}: 151 frames, 3 "
                                          "transitions; new"]
    assert result.stderr == ""
    # What vade-record would warn of is said as the golden is made (a mass in grams).
    doc = json.loads(drop.read_text())
    del doc["parts"][0]["density"]
    doc["parts"][0]["mass"] = 350
    drop.write_text(json.dumps(doc))
    result = run_cli("vade-goldens", "--dir", str(tmp_path), "drop_on_table")
    assert result.returncode == 0
    assert f"warning: {drop}: parts[0].mass (part 'peg'): 350 kg in 128 cm^3" in result.stderr


def test_a_session_that_fails_while_it_is_recorded_leaves_every_golden_as_it_was(tmp_path):
    """A tracker keyframe a million metres out is found only as the session is recorded,
    after the goldens before it in name order were recorded too: none is replaced."""
    for name in ("drop_on_table", "plane_block_wall"):
        for suffix in (".json", ".mcap"):
            shutil.copy(RECORDINGS / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
    drop = tmp_path / "drop_on_table.json"
    doc = json.loads(drop.read_text())
    doc["description"] = "described again: its golden would change"
    drop.write_text(json.dumps(doc))
    wall = tmp_path / "plane_block_wall.json"
    doc = json.loads(wall.read_text())
    keyframe = next(kf for kf in doc["tracker"]["devices"]["right_hand"] if "position" in kf)
    keyframe["position"] = [2e6, 0.0, 0.0]
    wall.write_text(json.dumps(doc))
    before = {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")}
    result = run_cli("vade-goldens", "--dir", str(tmp_path))
    assert result.returncode == 2 and "no golden was written" in result.stderr
    assert "Traceback" not in result.stderr
    assert {p.name: p.read_bytes() for p in tmp_path.glob("*.mcap")} == before
    assert not list(tmp_path.glob(".*.new")) and not list(tmp_path.glob(".*.partial"))
    assert " kept in " not in result.stderr


def test_an_interrupted_regeneration_leaves_no_partial_golden_and_says_so(tmp_path, capsys,
                                                                          monkeypatch):
    """A user's trial: Ctrl-C said the frames so far were kept in .NAME.mcap.new.partial,
    and the next regeneration removed it without a word. A golden's partial take is
    removed at once, and the line says the goldens are as they were."""
    from cli import goldens
    for suffix in (".json", ".mcap"):
        shutil.copy(RECORDINGS / f"drop_on_table{suffix}", tmp_path / f"drop_on_table{suffix}")
    before = (tmp_path / "drop_on_table.mcap").read_bytes()

    from vade_replay.recording import RecordingWriter
    add = RecordingWriter._add
    stop: list[BaseException] = []

    def adding(self, topic, time_ns, data):  # the real run, stopped at its 100th message
        add(self, topic, time_ns, data)
        if self._sequence == 100:
            raise stop[0]
    monkeypatch.setattr(RecordingWriter, "_add", adding)
    stop.append(KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt) as info:
        goldens._regenerate(tmp_path, [tmp_path / "drop_on_table.json"])
    assert info.value.__notes__ == ["no golden was written: the goldens are as they were"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drop_on_table.json",
                                                          "drop_on_table.mcap"]
    assert (tmp_path / "drop_on_table.mcap").read_bytes() == before
    # So is one an error stopped part way: the error does not say its frames are kept.
    from vade_replay.errors import SessionError
    stop[0] = SessionError("a bad sample", file="s.json", frame=5)
    assert goldens._regenerate(tmp_path, [tmp_path / "drop_on_table.json"]) == 2
    assert capsys.readouterr().err == ("error: s.json: frame 5: a bad sample\n"
                                       "a session cannot be recorded: no golden was written\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drop_on_table.json",
                                                          "drop_on_table.mcap"]


def test_a_golden_whose_tracker_log_changed_names_the_log_and_takes_the_file_name(tmp_path):
    """An engineer's trial: with only the CSV log edited, STALE named the session file as
    changed; and ``vade-goldens --check csvsess.json`` said there was no session named
    csvsess.json. The log is named as what changed, and a session is found by its name or
    its file's."""
    from conftest import run_cli
    from test_session import CSV, _csv_doc
    (tmp_path / "csvsess.json").write_text(json.dumps(_csv_doc()))
    (tmp_path / "log.csv").write_text(CSV)
    assert run_cli("vade-goldens", "--dir", str(tmp_path), "csvsess.json").returncode == 0
    assert run_cli("vade-goldens", "--check", "--dir", str(tmp_path),
                   "csvsess.json").returncode == 0
    (tmp_path / "log.csv").write_text(CSV.replace("2.000,right_hand", "2.500,right_hand"))
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path), "csvsess")
    assert result.returncode == 1
    # Where in it (a researcher's trial: told only that the log changed).
    line = 1 + CSV[:CSV.index("2.000,right_hand")].count("\n")
    old_row = CSV.splitlines()[line - 1]
    assert (f"STALE: log.csv (named by {tmp_path / 'csvsess.json'}) changed since its golden "
            "was made (file log.csv is not the one the golden was made with: first at line "
            f"{line}, {old_row!r} in the golden and {old_row.replace('2.000', '2.500')!r} "
            "now)") in result.stdout


def test_a_folder_s_session_without_a_golden_is_named_by_its_own_fault(tmp_path):
    """(A user's trial: a session with two parts of one name and no golden yet was reported
    as "no such file (record it with vade-goldens --dir ...)", a command that would fail.)
    A missing golden whose session is good gets that hint; one whose session cannot be
    recorded gets the session's error. Given the session file for ``--dir``: which folder
    and name to give."""
    shutil.copy(RECORDINGS / "drop_on_table.json", tmp_path / "good.json")
    doc = json.loads((RECORDINGS / "drop_on_table.json").read_text())
    doc["parts"].append(dict(doc["parts"][0]))  # a second part of the same name
    (tmp_path / "dup_part.json").write_text(json.dumps(doc))
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    dup, = [line for line in lines if "dup_part" in line]
    good, = [line for line in lines if "good" in line]
    assert "record it with" not in dup and "dup_part.json" in dup
    assert f"record it with vade-goldens --dir {tmp_path} good" in good
    assert run_cli("vade-goldens", "--dir", str(tmp_path), "good").returncode == 0
    as_file = run_cli("vade-goldens", "--check", "--dir", str(tmp_path / "good.json"))
    assert as_file.returncode == 2 and "is a file, not a folder of sessions" in as_file.stderr
    # (What it suggests checks as asked: without --check it would remake the golden.)
    assert f"vade-goldens --check --dir {tmp_path} good)" in as_file.stderr
    remake = run_cli("vade-goldens", "--dir", str(tmp_path / "good.json"))
    assert f"(vade-goldens --dir {tmp_path} good)" in remake.stderr
    # A device or a pipe is not "no such folder" (a user's trial); a missing one is.
    import os
    os.mkfifo(tmp_path / "pipe")
    for given, why in ((os.devnull, "not a folder (a device or a pipe)"),
                       (str(tmp_path / "pipe"), "not a folder (a device or a pipe)"),
                       (str(tmp_path / "gone"), "no such folder")):
        result = run_cli("vade-goldens", "--check", "--dir", given)
        assert (result.returncode, result.stderr) == (2, f"error: {given}: --dir: {why}\n")


def test_a_golden_without_its_session_is_named_not_skipped(tmp_path):
    """A user's trial: a golden whose session file was renamed or deleted was dropped from
    ``--check`` without a word (a regression test fewer, CI green). It is replayed on its
    own session, named as held to none, and the check exits 1, as for a stale one; a
    regeneration names it as not regenerated."""
    for suffix in (".json", ".mcap"):
        shutil.copy(RECORDINGS / f"drop_on_table{suffix}", tmp_path / f"drop_on_table{suffix}")
    shutil.copy(RECORDINGS / "plane_block_wall.mcap", tmp_path / "renamed.mcap")
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 1
    assert result.stdout.splitlines() == [
        f"{tmp_path / 'drop_on_table.mcap'}: match",
        f"{tmp_path / 'renamed.mcap'}: NO SESSION: no renamed.json beside it (renamed or "
        "deleted?), so it is not held to one; its own session replays: match",
        "2 goldens: 1 match, 0 diverged, 0 stale, 1 without their session, 0 could not be "
        "replayed"]
    # Named alone, the others are not asked after.
    assert run_cli("vade-goldens", "--check", "--dir", str(tmp_path),
                   "drop_on_table").returncode == 0
    result = run_cli("vade-goldens", "--dir", str(tmp_path))
    assert result.returncode == 0 and result.stderr == (
        f"warning: {tmp_path / 'renamed.mcap'}: no session renamed.json beside it (renamed "
        "or deleted?): not regenerated\n")


def test_a_golden_without_its_session_cut_short_is_named_so(tmp_path):
    """A review: a golden with no session beside it that was cut short (a crash while it
    was written) read "its own session replays: match"."""
    data = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) * 2 // 3])
    shutil.copy(RECORDINGS / "drop_on_table.json", tmp_path / "drop_on_table.json")
    shutil.copy(RECORDINGS / "drop_on_table.mcap", tmp_path / "drop_on_table.mcap")
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 2
    assert f"error: {tmp_path / 'cut.mcap'}: cut short (a crash while it was written), and no " \
        "session cut.json beside it (renamed or deleted?)" in result.stderr


def test_where_a_named_file_changed_is_said():
    """The line of a text file (a tracker log) where it first differs from the golden's, or
    the byte of a binary one (a mesh), or that it is new or gone."""
    from cli.goldens import _where_changed
    assert _where_changed(b"a\nb\nc\n", b"a\nB\nc\n") == (
        ": first at line 2, 'b' in the golden and 'B' now")
    # A line added at the end, or lost there: the file said to end (a review: '' read as
    # an empty line); an end of line turned CRLF shows its \r.
    assert _where_changed(b"a\nb\n", b"a\nb\nc\n") == (
        ": first at line 3, it ends before it (2 lines) in the golden and 'c' now")
    assert _where_changed(b"a\nb\nc\n", b"a\nb\n") == (
        ": first at line 3, 'c' in the golden and it ends before it (2 lines) now")
    assert _where_changed(b"a\nb\n", b"a\r\nb\r\n") == (
        ": first at line 1, 'a' in the golden and 'a\\r' now")
    assert _where_changed(b"solid\0\x01\x02", b"solid\0\x01\x03") == (
        ": first at byte 7, 8 bytes in the golden and 8 now")
    assert _where_changed(None, b"x") == " (not in the golden)"
    assert _where_changed(b"x", None) == " (missing now)"
