"""The progress bar: drawn on a terminal, silent otherwise."""

from __future__ import annotations

import contextlib
import io

from conftest import RECORDINGS, run_cli
from vade_replay.cli._common import Progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_bar_on_a_terminal():
    err = _Terminal()
    with contextlib.redirect_stderr(err):
        bar = Progress("replaying", 90)
        for _ in range(90):
            bar.update()
        bar.close()
    text = err.getvalue()
    assert "\rreplaying [" in text and "90/90 frames" in text and text.endswith("\n")


def test_quiet_when_not_a_terminal():
    result = run_cli("vade-replay", str(RECORDINGS / "throw_and_catch.mcap"))
    assert result.returncode == 0
    assert result.stderr == ""
    assert "\r" not in result.stdout


def test_replay_knows_its_length_for_the_bar():
    from vade_replay.recording import Recording

    assert Recording(RECORDINGS / "throw_and_catch.mcap").frame_count == 181


def test_recording_knows_its_length_for_the_bar_where_keyframes_say_it():
    """A newcomer's trial: vade-record's bar was a bare count with no total, though a
    keyframed session says how many frames it makes (a CSV log's count is not known before
    it is read, and stays a count). The total is the frames recorded, for every golden."""
    import json

    from conftest import make_session
    from vade_replay.recording import Recording
    for path in sorted(RECORDINGS.glob("*.json")):
        session = make_session(json.loads(path.read_text()))
        assert session.frame_count() == Recording(path.with_suffix(".mcap")).frame_count
    csv_doc = json.loads((RECORDINGS / "drop_on_table.json").read_text())
    csv_doc["tracker"] = {"csv": "log.csv", "csv_quaternion_order": "xyzw"}
    session = make_session(csv_doc, {"log.csv": b"time,device,x,y,z,qx,qy,qz,qw,grip\n"})
    assert session.frame_count() is None
