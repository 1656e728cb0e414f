"""The replay's check by value (``FrameEncoder.matches``) says "the same" exactly when the
recorded messages hold the values the encoder would write, every float to the bit.

It parses the recording instead of writing ours (vade-bench --replay), so it is held here to
the byte comparison it stands in for: on everything the encoder writes it agrees, a change
of one bit anywhere (a number by one ulp, -0.0 for 0.0, a key, a name, a mode, a flag, an
event) is a difference, and a "no" leaves the encoder where it was, so that the bytes can
then be written and compared. Text that reads back to the same values (other spacing or
number notation) is the same session: a replay of it matches.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from mcap_edit import copy_recording
from test_codec import finite, frame_sequences

from vade_replay import codec
from vade_replay.recording import Recording
from vade_replay.replay import replay

RECORDINGS = Path(__file__).resolve().parent.parent / "recordings"
ENCODINGS = (codec.PARTS_FULL, codec.PARTS_CHANGED)


@pytest.mark.parametrize("parts", ENCODINGS)
@settings(max_examples=150, deadline=None, derandomize=True)
@given(frames=frame_sequences(values=finite))
def test_what_the_encoder_writes_matches_and_keeps_the_encoder_in_step(parts, frames):
    """Every frame the encoder writes matches; a frame checked by value, not written, leaves
    the encoder where writing it would have (the next frame it writes is the reference's)."""
    reference = codec.FrameEncoder(parts)
    checker = codec.FrameEncoder(parts)
    for k, record in enumerate(frames):
        written = reference.derived_messages(record)
        if k % 2:
            assert checker.derived_messages(record) == written
        else:
            assert checker.matches(record, written)


def _numbers(doc, path=()):
    """Paths to every float in a parsed message."""
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield from _numbers(value, path + (key,))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            yield from _numbers(value, path + (i,))
    elif type(doc) is float:
        yield path


def _set(doc, path, value):
    for key in path[:-1]:
        doc = doc[key]
    doc[path[-1]] = value


def _get(doc, path):
    for key in path:
        doc = doc[key]
    return doc


def _dumps(doc) -> bytes:
    return json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()


def _mutations(derived):
    """Each way one bit of a frame's messages can change: every float one ulp either way
    (and 0.0 to -0.0), each key dropped or added, each string changed, each int moved, the
    messages' order, one dropped or added."""
    for m, (topic, data) in enumerate(derived):
        doc = json.loads(data)
        for path in _numbers(doc):
            x = _get(doc, path)
            for y in {float(np.nextafter(x, math.inf)), float(np.nextafter(x, -math.inf)),
                      -x if x == 0.0 else x}:
                if y != x or math.copysign(1, y) != math.copysign(1, x):
                    changed = json.loads(data)
                    _set(changed, path, y)
                    yield f"{topic} {path} {x!r}->{y!r}", m, _dumps(changed)

        def strings_and_keys(node, path=()):
            if isinstance(node, dict):
                yield path, node
                for key, value in node.items():
                    yield from strings_and_keys(value, path + (key,))
            elif isinstance(node, list):
                for i, value in enumerate(node):
                    yield from strings_and_keys(value, path + (i,))
            elif isinstance(node, (str, bool, int)) and not isinstance(node, float):
                yield path, node

        for path, node in list(strings_and_keys(doc)):
            if isinstance(node, dict):
                changed = json.loads(data)
                _get(changed, path)["extra"] = 1
                yield f"{topic} {path} + key", m, _dumps(changed)
                for key in node:
                    changed = json.loads(data)
                    del _get(changed, path)[key]
                    yield f"{topic} {path} - {key}", m, _dumps(changed)
            elif path:
                changed = json.loads(data)
                new = (not node if isinstance(node, bool) else node + "x"
                       if isinstance(node, str) else node + 1)
                _set(changed, path, new)
                yield f"{topic} {path} {node!r}->{new!r}", m, _dumps(changed)
                if isinstance(node, int) and not isinstance(node, bool):
                    changed = json.loads(data)
                    _set(changed, path, float(node))  # 3.0 for 3: another value's text
                    yield f"{topic} {path} int->float", m, _dumps(changed)


@pytest.mark.parametrize("golden", ["gear_pendulum", "drop_on_table", "two_hand_placed"])
def test_every_one_bit_change_of_a_golden_frame_is_a_difference(golden):
    """Frames of goldens (both encodings' shapes: full key frames and changed-only ones,
    with events) checked against each of their one-change mutations."""
    path = RECORDINGS / f"{golden}.mcap"
    recording = Recording(path)
    session = recording.session
    from vade_replay.collision import CollisionWorld
    from vade_replay.step import Stepper

    scene = session.build_scene()
    advance = Stepper(scene, CollisionWorld(scene))
    encoder = codec.FrameEncoder(recording.parts_encoding)
    tried = 0
    kinds = set()
    for recorded in recording.frames():
        record = advance(recorded.inputs)
        frame = recorded.inputs.frame
        if frame % 37 == 5 or record.events:
            kinds.add((bool(record.events), json.loads(recorded.derived[0][1]).get("complete")))
            for what, m, data in _mutations(recorded.derived):
                mutated = list(recorded.derived)
                mutated[m] = (mutated[m][0], data)
                assert not encoder.matches(record, mutated), f"frame {frame}: {what}"
                tried += 1
            swapped = [recorded.derived[1], recorded.derived[0], *recorded.derived[2:]]
            assert not encoder.matches(record, swapped)
            assert not encoder.matches(record, recorded.derived[:-1])
            assert not encoder.matches(record, recorded.derived + [recorded.derived[-1]])
        # Each "no" above left the encoder where it was: the true frame still matches.
        assert encoder.matches(record, recorded.derived), f"frame {frame}"
    assert tried > 200
    assert any(events for events, _ in kinds)


def test_the_same_values_written_otherwise_replay_as_a_match(tmp_path: Path):
    """Spacing, key order and number notation (1e-05 written 0.00001, 2.5 as 25e-1) carry
    no value: a recording rewritten so still replays as the same session."""
    src = RECORDINGS / "drop_on_table.mcap"

    def notation(match_text: str) -> str:
        x = float(match_text)
        return f"{x:.17e}" if x != 0.0 and abs(x) < 1e-3 else repr(x)

    def edit(topic: str, index: int, data: bytes) -> bytes:
        if topic in (codec.PARTS_TOPIC, codec.FOXGLOVE_TOPIC):
            doc = json.loads(data)
            text = json.dumps(doc, indent=1)  # other spacing, keys in written order
            import re

            text = re.sub(r"-?\d+\.\d+(e-?\d+)?", lambda m: notation(m.group()), text)
            assert json.loads(text) == doc
            return text.encode()
        return data

    out = tmp_path / "reformatted.mcap"
    copy_recording(src, out, edit)
    assert replay(Recording(out)).match
    # Written out again (the path that writes its own bytes and compares them): the same
    # verdict, and the file written is this encoder's text, the golden's bytes.
    again = tmp_path / "again.mcap"
    assert replay(Recording(out), out=again).match
    assert [f.derived for f in Recording(again).frames()] == \
        [f.derived for f in Recording(src).frames()]


def test_a_one_ulp_change_in_a_recording_is_named_where_it_is(tmp_path: Path):
    """End to end: the check by value finds a pose one ulp off and the report names it."""
    src = RECORDINGS / "drop_on_table.mcap"
    moving = [f.inputs.frame for f in Recording(src).frames()
              if json.loads(f.derived[1][1])["transforms"]]
    target = moving[len(moving) // 2]

    def edit(topic: str, index: int, data: bytes) -> bytes:
        if topic == codec.FOXGLOVE_TOPIC and index == target:
            doc = json.loads(data)
            x = doc["transforms"][-1]["translation"]["z"]
            doc["transforms"][-1]["translation"]["z"] = float(np.nextafter(x, math.inf))
            return _dumps(doc)
        return data

    out = tmp_path / "ulp.mcap"
    copy_recording(src, out, edit)
    summary = replay(Recording(out))
    assert not summary.match
    found = summary.first_divergence
    assert found["frame"] == target and found["channel"] == codec.FOXGLOVE_TOPIC
    assert found["field"] == "translation.z"


@pytest.mark.parametrize("parts", ENCODINGS)
def test_a_frame_listing_many_parts_is_checked_by_its_bytes_with_the_same_verdicts(parts):
    """``check`` parses a frame listing few parts and writes one listing many (a key frame
    of many resting parts: their text is kept); both ways the verdicts are the byte
    comparison's, the messages it returns on a difference are ``derived_messages``', and
    the encoder stays in step through either."""
    from vade_replay.events import ModeChanged
    from vade_replay.frames import FrameRecord, PartSnapshot, TrackerFrame

    rest = [PartSnapshot(f"r{i:02d}", "STATIC", (0.1 * i, 0.0, 0.75), (0.0, 0.0, 0.0, 1.0),
                         (0.0,) * 3, (0.0,) * 3) for i in range(20)]
    frames = []
    for k in range(150):  # across two key frames of the changed encoding
        mover = PartSnapshot("m", "INSPACE", (0.0, 0.0, 1.0 - 1e-3 * k),
                             (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, -0.01 * k), (0.0,) * 3)
        events = (ModeChanged(k, "m", "x", "INHAND", "INSPACE"),) if k % 50 == 7 else ()
        frames.append(FrameRecord(TrackerFrame(k, k * 16_666_667, ()), None,
                                  (mover, *rest), events))
    reference, checker = codec.FrameEncoder(parts), codec.FrameEncoder(parts)
    shown = []
    for k, record in enumerate(frames):
        written = reference.derived_messages(record)
        shown.append(len(json.loads(written[1][1])["transforms"]))
        if k % 3 == 1:  # a one-ulp change of the first number in the transforms
            doc = json.loads(written[1][1])
            x = doc["transforms"][0]["translation"]["x"]
            doc["transforms"][0]["translation"]["x"] = float(np.nextafter(x, math.inf))
            changed = [written[0], (written[1][0], _dumps(doc)), *written[2:]]
            assert checker.check(record, changed) == written
        else:
            assert checker.check(record, written) is None
    assert max(shown) == 21 and (parts == codec.PARTS_FULL or min(shown) == 1)


def test_a_snapshot_that_comes_back_after_frames_checked_by_value_is_listed():
    """The encoder's text cache lags behind frames checked by value; a part whose snapshot
    object comes back (X, then Y, then X again) must still be listed as changed in the
    third frame, as the reference encoder lists it, and a recording leaving it out must
    not match."""
    from vade_replay.frames import FrameRecord, PartSnapshot, TrackerFrame

    def snap(name, z):
        return PartSnapshot(name, "INSPACE", (0.0, 0.0, z), (0.0, 0.0, 0.0, 1.0),
                            (0.0,) * 3, (0.0,) * 3)

    x, y = snap("a", 1.0), snap("a", 0.5)
    others = tuple(snap(f"r{i}", 0.1 * i) for i in range(3))
    frames = [FrameRecord(TrackerFrame(k, k * 16_666_667, ()), None, (part, *others))
              for k, part in enumerate((x, y, x, x))]
    reference = []
    previous = None
    for record in frames:
        reference.append(codec.derived_messages(
            record, parts=codec.PARTS_CHANGED,
            previous_parts=previous.parts if previous else None,
            previous_time_ns=previous.time_ns if previous else None))
        previous = record
    encoder = codec.FrameEncoder(codec.PARTS_CHANGED)
    assert encoder.derived_messages(frames[0]) == reference[0]
    assert encoder.matches(frames[1], reference[1])  # by value: the text cache stays at X
    assert encoder.derived_messages(frames[2]) == reference[2]
    assert json.loads(reference[2][0][1])["parts"][0]["name"] == "a"
    checker = codec.FrameEncoder(codec.PARTS_CHANGED)
    assert checker.derived_messages(frames[0]) == reference[0]
    assert checker.matches(frames[1], reference[1])
    left_out = json.loads(reference[2][0][1])
    left_out["parts"] = []
    doc = json.loads(reference[2][1][1])
    doc["transforms"] = []
    assert checker.check(frames[2], [(codec.PARTS_TOPIC, _dumps(left_out)),
                                     (codec.FOXGLOVE_TOPIC, _dumps(doc))]) == reference[2]


def test_a_frame_s_last_event_and_a_zero_s_sign_are_checked_end_to_end(tmp_path: Path):
    """(A test audit: the check by value skipping a frame's last event message, or taking
    -0.0 for 0.0, was caught by one test alone.) A recording whose frame's last event says
    another hand, and one whose resting velocity 0.0 is written -0.0 (a sign bit, a value
    JSON keeps): each is a divergence, named at its frame."""
    src = RECORDINGS / "drop_on_table.mcap"
    frames = list(Recording(src).frames())
    grab = next(f for f in frames if len(f.derived) > 3)
    last_topic = grab.derived[-1][0]
    count = sum(1 for f in frames if f.inputs.frame < grab.inputs.frame
                for t, _ in f.derived if t == last_topic)

    def other_hand(topic: str, index: int, data: bytes) -> bytes:
        if topic == last_topic and index == count:
            doc = json.loads(data)
            doc["hand"] = "left_hand"
            return _dumps(doc)
        return data

    rest = next(f for f in frames if f.inputs.frame > 0
                and json.loads(f.derived[0][1])["parts"]
                and json.loads(f.derived[0][1])["parts"][0]["linear_velocity"] == [0, 0, 0])
    parts_index = sum(1 for f in frames if f.inputs.frame < rest.inputs.frame
                      for t, _ in f.derived if t == codec.PARTS_TOPIC)

    def signed_zero(topic: str, index: int, data: bytes) -> bytes:
        if topic == codec.PARTS_TOPIC and index == parts_index:
            doc = json.loads(data)
            doc["parts"][0]["linear_velocity"][2] = -0.0
            return _dumps(doc)
        return data

    for name, edit, frame in (("hand", other_hand, grab.inputs.frame),
                              ("zero", signed_zero, rest.inputs.frame)):
        out = tmp_path / f"{name}.mcap"
        copy_recording(src, out, edit)
        summary = replay(Recording(out))
        assert not summary.match, name
        assert summary.first_divergence["frame"] == frame, (name, summary.first_divergence)
