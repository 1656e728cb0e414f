"""A replay reads, steps and checks its frames a batch at a time, and a recording steps
and writes them so (``replay._BATCH_FRAMES``, for speed: ``docs/DEVELOPMENT.md``). What
stops either part way (a damaged chunk, an error stepping, an interrupt) must leave what a
run a frame at a time left: every frame before it checked, counted, shown to ``on_frame``
and written, none after it."""

from __future__ import annotations

import pytest
from mcap.reader import make_reader

from vade_replay import replay as rp
from vade_replay.errors import RecordingError, VadeError
from vade_replay.recording import Recording
from vade_replay.session import load

from conftest import RECORDINGS

GOLDEN = RECORDINGS / "gear_pendulum.mcap"  # 361 frames: six batches and a part
STEPPER = rp.Stepper


def _frames_before_error(path) -> int:
    count = 0
    try:
        for _ in Recording(path).frames():
            count += 1
    except RecordingError:
        return count
    raise AssertionError("the file was expected to be damaged")


def _damaged(tmp_path, chunk: int):
    data = bytearray(GOLDEN.read_bytes())
    with open(GOLDEN, "rb") as f:
        start = make_reader(f).get_summary().chunk_indexes[chunk].chunk_start_offset
    at = start + 37 + 4 + 4 + 8  # the chunk's zstd frame (test_cli_errors)
    data[at:at + 4] = b"\0\0\0\0"
    path = tmp_path / "damaged.mcap"
    path.write_bytes(bytes(data))
    return path


def test_the_batch_is_more_than_one_frame_and_the_golden_spans_several():
    frames = Recording(GOLDEN).frame_count
    assert rp._BATCH_FRAMES > 1 and frames is not None
    assert frames % rp._BATCH_FRAMES != 0 and frames > 3 * rp._BATCH_FRAMES


def test_every_frame_is_checked_once_in_order():
    seen = []
    summary = rp.replay(Recording(GOLDEN), on_frame=lambda f: seen.append(f.recorded.inputs.frame))
    assert summary.match
    expected = [f.inputs.frame for f in Recording(GOLDEN).frames()]
    assert seen == expected and summary.frames == len(expected)


@pytest.mark.parametrize("chunk", [1, 3])
@pytest.mark.parametrize("batch", [25, rp._BATCH_FRAMES])
def test_a_damaged_chunk_keeps_exactly_the_frames_before_it(tmp_path, monkeypatch, chunk,
                                                            batch):
    # (A chunk holds one simulated second, 60 frames here: batches of 25 end inside one.)
    monkeypatch.setattr(rp, "_BATCH_FRAMES", batch)
    path = _damaged(tmp_path, chunk)
    before = _frames_before_error(path)
    assert before == 60 * chunk
    seen = []
    out = tmp_path / "out.mcap"
    with pytest.raises(RecordingError) as caught:
        rp.replay(Recording(path), out=out, on_frame=lambda f: seen.append(f.divergence))
    assert "damaged after" in caught.value.message and caught.value.file == str(path)
    assert f"the {before} regenerated frames before it are kept" in caught.value.message
    assert seen == [None] * before  # each checked, and each the recording's
    kept = Recording(out.with_name("out.mcap.partial"))
    assert sum(1 for _ in kept.frames()) == before
    # and the kept frames are the recording's own, bit for bit
    for ours, theirs in zip(kept.frames(), Recording(GOLDEN).frames()):
        assert ours.inputs == theirs.inputs and ours.derived == theirs.derived


class _FailingStepper:
    """The real stepper, failing at one frame as a physics error would."""

    def __init__(self, at: int, error: BaseException):
        self.at, self.error, self.calls = at, error, 0

    def __call__(self, scene, collision):
        stepper = STEPPER(scene, collision)
        outer = self

        def advance(inputs):
            if outer.calls == outer.at:
                raise outer.error
            outer.calls += 1
            return stepper(inputs)
        return advance


@pytest.mark.parametrize("at", [0, 75, 120])
def test_an_error_stepping_a_frame_comes_after_the_frames_before_it(tmp_path, monkeypatch, at):
    monkeypatch.setattr(rp, "Stepper", _FailingStepper(at, VadeError("a physics error")))
    seen = []
    out = tmp_path / "out.mcap"
    with pytest.raises(VadeError) as caught:
        rp.replay(Recording(GOLDEN), out=out, on_frame=lambda f: seen.append(f.divergence))
    assert caught.value.message.startswith("a physics error")
    assert seen == [None] * at
    partial = out.with_name("out.mcap.partial")
    if at == 0:
        assert not partial.exists() and not out.exists()  # nothing written, nothing left
    else:
        assert f"the {at} regenerated frames before it are kept" in caught.value.message
        kept = Recording(partial)
        assert sum(1 for _ in kept.frames()) == at and kept.stopped is not None


def test_an_interrupt_while_stepping_keeps_the_frames_before_it(tmp_path, monkeypatch):
    monkeypatch.setattr(rp, "Stepper", _FailingStepper(100, KeyboardInterrupt()))
    seen = []
    out = tmp_path / "out.mcap"
    with pytest.raises(KeyboardInterrupt) as caught:
        rp.replay(Recording(GOLDEN), out=out, on_frame=lambda f: seen.append(f))
    assert len(seen) == 100
    assert any("the 100 frames written so far are kept" in n for n in caught.value.__notes__)
    kept = Recording(out.with_name("out.mcap.partial"))
    assert sum(1 for _ in kept.frames()) == 100 and kept.stopped == "interrupted"


@pytest.mark.parametrize("at", [0, 75, 120])
def test_a_recording_that_fails_stepping_keeps_the_frames_before_it(tmp_path, monkeypatch, at):
    session = load(GOLDEN.with_suffix(".json"))
    monkeypatch.setattr(rp, "Stepper", _FailingStepper(at, VadeError("a physics error")))
    seen = []
    out = tmp_path / "rec.mcap"
    with pytest.raises(VadeError) as caught:
        rp.record(session, out, on_frame=lambda r: seen.append(r.frame))
    assert seen == list(range(at))
    assert not out.exists()
    partial = out.with_name("rec.mcap.partial")
    if at == 0:
        assert not partial.exists()
    else:
        assert caught.value.frame == at  # the frame being made when it failed
        assert f"the {at} frames before it are kept" in caught.value.message
        kept = list(Recording(partial).frames())
        golden = list(Recording(GOLDEN).frames())[:at]
        assert [(f.inputs, f.derived) for f in kept] == [(f.inputs, f.derived) for f in golden]


def test_a_recording_interrupted_while_stepping_keeps_the_frames_before_it(tmp_path,
                                                                          monkeypatch):
    session = load(GOLDEN.with_suffix(".json"))
    monkeypatch.setattr(rp, "Stepper", _FailingStepper(130, KeyboardInterrupt()))
    out = tmp_path / "rec.mcap"
    with pytest.raises(KeyboardInterrupt) as caught:
        rp.record(session, out)
    assert any("the 130 frames written so far are kept" in n for n in caught.value.__notes__)
    kept = Recording(out.with_name("rec.mcap.partial"))
    assert sum(1 for _ in kept.frames()) == 130 and kept.stopped == "interrupted"


def test_a_whole_recording_is_the_golden_frame_for_frame(tmp_path):
    """Batches end inside the session and at its end (361 frames): none lost or doubled."""
    out = tmp_path / "rec.mcap"
    summary = rp.record(load(GOLDEN.with_suffix(".json")), out)
    assert summary.frames == 361
    assert [(f.inputs, f.derived) for f in Recording(out).frames()] \
        == [(f.inputs, f.derived) for f in Recording(GOLDEN).frames()]


def _sigint_inside_frame(monkeypatch, at_message: int, times: int = 1,
                         signum: int | None = None) -> None:
    """A real Ctrl-C (SIGINT to this process; or ``signum``) while a frame is being
    written: as the writer adds message ``at_message`` of the run (counted from 1: a frame's
    tracker message is followed by its /parts and transforms, so 3k + 2 falls inside a frame
    where no event came before), ``times`` over."""
    import os
    import signal

    from vade_replay.recording import RecordingWriter
    if signum is None:
        signum = signal.SIGINT
        if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            pytest.skip("SIGINT does not have Python's own handler here")
    add = RecordingWriter._add
    count = 0

    def adding(self, topic, time_ns, data):
        nonlocal count
        count += 1
        if count == at_message:
            for _ in range(times):
                os.kill(os.getpid(), signum)
                for _ in range(1000):  # (the handler runs between bytecodes)
                    pass
        add(self, topic, time_ns, data)
    monkeypatch.setattr(RecordingWriter, "_add", adding)


def _interrupted(run: str, out) -> KeyboardInterrupt:
    """The golden recorded (``record``) or replayed to ``out`` (``replay -o``), stopped by an
    interrupt: the interrupt."""
    with pytest.raises(KeyboardInterrupt) as caught:
        if run == "record":
            rp.record(load(GOLDEN.with_suffix(".json")), out)
        else:
            rp.replay(Recording(GOLDEN), out=out)
    return caught.value


def _frames_kept(stop: KeyboardInterrupt) -> int:
    """The frames an interrupted run's note says it kept."""
    note, = [n for n in stop.__notes__ if "written so far are kept" in n]
    return int(note.split("the ")[1].split(" ")[0])


@pytest.mark.parametrize("run", ["record", "replay -o"])
def test_ctrl_c_while_a_frame_is_written_waits_for_the_frame_s_end(tmp_path, monkeypatch,
                                                                   run):
    """Raised where it came, Ctrl-C cut a frame part way: the partial file diverged at its
    last frame or could not be read, and its count of frames was one off (a user's trial of
    1,200 s sessions, 5 interrupts in 14). Held to the frame's end, the kept file replays,
    every frame it says it holds."""
    import signal
    out = tmp_path / "out.mcap"
    _sigint_inside_frame(monkeypatch, at_message=3 * 40 + 2)  # inside a frame near the 40th
    caught = _interrupted(run, out)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
    frames = _frames_kept(caught)
    assert 30 <= frames <= 41
    partial = out.with_name("out.mcap.partial")
    summary = rp.replay(Recording(partial))
    assert summary.match and summary.frames == frames
    kept = Recording(partial)
    assert sum(1 for _ in kept.frames()) == frames and kept.stopped == "interrupted"


def test_a_second_ctrl_c_before_the_frame_s_end_is_raised_at_once(tmp_path, monkeypatch):
    """The way out of a run that does not reach a frame's end: asked twice, it stops there
    and then."""
    seen = []
    _sigint_inside_frame(monkeypatch, at_message=3 * 40 + 2, times=2)
    with pytest.raises(KeyboardInterrupt):
        rp.record(load(GOLDEN.with_suffix(".json")), tmp_path / "out.mcap",
                  on_frame=lambda r: seen.append(r.frame))
    # The frame being written when it came never reached on_frame.
    assert len(seen) < 42


def _sigint_while_closing(monkeypatch, when) -> None:
    """A real Ctrl-C inside ``RecordingWriter.close`` when ``when(kwargs)`` says so."""
    import os
    import signal

    from vade_replay.recording import RecordingWriter
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT does not have Python's own handler here")
    close = RecordingWriter.close

    def closing(self, **kwargs):
        if when(kwargs):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # (the handler runs between bytecodes)
                pass
        close(self, **kwargs)
    monkeypatch.setattr(RecordingWriter, "close", closing)


@pytest.mark.parametrize("run", ["record", "replay -o"])
def test_a_second_ctrl_c_while_an_interrupted_run_closes_its_file_keeps_the_frames(
        tmp_path, monkeypatch, run):
    """(A review: in ``record`` the close of an interrupted run was no longer held, and a
    second Ctrl-C inside it lost every frame kept.)"""
    out = tmp_path / "out.mcap"
    _sigint_inside_frame(monkeypatch, at_message=3 * 40 + 2)
    _sigint_while_closing(monkeypatch, lambda kwargs: kwargs.get("stopped") is not None)
    caught = _interrupted(run, out)
    frames = _frames_kept(caught)
    summary = rp.replay(Recording(out.with_name("out.mcap.partial")))
    assert summary.match and summary.frames == frames > 0


@pytest.mark.parametrize("run", ["record", "replay -o"])
def test_a_ctrl_c_as_a_run_finishes_its_file_stops_it_with_the_file_complete(
        tmp_path, monkeypatch, run):
    """Pressed after the last frame, while the file is finished: not lost (a review: a
    study's loop of runs went on), and not a half-closed file: the run stops, its file
    complete and named."""
    import signal
    out = tmp_path / "out.mcap"
    _sigint_while_closing(monkeypatch, lambda kwargs: kwargs.get("complete_as") is not None)
    caught = _interrupted(run, out)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert f"the run had reached its end: {out} is complete" in caught.__notes__
    summary = rp.replay(Recording(out))
    assert summary.match and summary.frames == 361


def _summary(path, **kwargs) -> dict:
    out = rp.replay(Recording(path), **kwargs).to_dict()
    out.pop("build")
    return out


@pytest.mark.parametrize("golden", sorted(RECORDINGS.glob("*.mcap")), ids=lambda p: p.stem)
def test_the_compiled_run_of_matching_frames_sums_up_as_the_frame_by_frame_loop(golden):
    # A plain replay checks and counts the frames that match without events in compiled code
    # (codec.checked_run); one shown to on_frame goes frame by frame: the same summary.
    shown = []
    assert _summary(golden) == _summary(golden, on_frame=shown.append)
    assert len(shown) == Recording(golden).frame_count


@pytest.mark.parametrize("at", [0, 59, 60, 61, 200])
def test_a_divergence_inside_a_batch_is_reported_as_frame_by_frame(tmp_path, at):
    # A frame's transforms one ulp off, at a batch's first, last or a middle frame: the
    # compiled run stops there, and the report and the counts are the frame-by-frame loop's.
    import json
    import math

    from mcap_edit import copy_recording

    from vade_replay import codec

    def edit(topic: str, index: int, data: bytes) -> bytes:
        if topic == codec.FOXGLOVE_TOPIC and index == at:
            doc = json.loads(data)
            pose = doc["transforms"][0]["translation"]
            pose["z"] = math.nextafter(pose["z"], math.inf)
            return codec.dumps(doc)
        return data

    out = tmp_path / "off.mcap"
    copy_recording(GOLDEN, out, edit)
    fast, slow = _summary(out), _summary(out, on_frame=lambda f: None)
    assert fast == slow
    assert not fast["match"] and fast["first_divergence"]["frame"] == at
    assert fast["frames"] == Recording(GOLDEN).frame_count


@pytest.mark.parametrize("command", ["vade-record", "vade-replay"])
def test_sigterm_is_taken_as_ctrl_c_and_ends_143(tmp_path, monkeypatch, command):
    """A user's trial: a scheduler's stop (SIGTERM: SLURM, systemd, ``timeout``) ended a
    recording without a word, its file cut short mid-frame. It is taken as Ctrl-C is: held
    to the frame's end, the file closed with its frames and why it stopped, one line, and
    exit 143 (128 + SIGTERM's number); SIGTERM's own action is put back after the run."""
    import signal

    from conftest import run_cli
    if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        pytest.skip("SIGTERM has a handler of its own here")
    # Inside a frame near the 40th; SIGTERM is taken as Ctrl-C only inside a command's run.
    _sigint_inside_frame(monkeypatch, at_message=3 * 40 + 2, signum=signal.SIGTERM)
    out = tmp_path / "out.mcap"
    args = ([str(GOLDEN.with_suffix(".json"))] if command == "vade-record"
            else [str(GOLDEN)]) + ["-o", str(out)]
    result = run_cli(command, *args)
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    partial = out.with_name("out.mcap.partial").resolve()
    assert result.returncode == 143
    assert result.stderr.startswith("terminated; the ") and result.stderr.endswith(
        f" frames written so far are kept in {partial}\n")
    frames = int(result.stderr.split("the ")[1].split(" ")[0])
    assert 30 <= frames <= 41
    kept = Recording(partial)
    summary = rp.replay(kept)
    assert summary.match and summary.frames == frames
    assert kept.stopped == "terminated"  # (read with the frames, at the file's end)
