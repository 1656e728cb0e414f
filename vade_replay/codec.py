"""Messages as JSON: deterministic encoding, exact decoding, one schema per message type.

``json`` writes floats with ``repr``, the shortest text that reads back to the same
float64, so a decoded recording holds exactly the numbers that were simulated. Keys are
sorted and separators fixed, so equal values give equal bytes. A replay checks the
recorded messages by writing ours and comparing bytes (``FrameEncoder.check``: a frame's
numbers by one ``orjson.dumps``, the text around them by ``_framejson.c``, about a third
of the cost of parsing the recorded ones), and by value (``FrameEncoder.matches``) only
where the bytes differ, so that another writer's spacing or notation of the same numbers
still matches.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any, Final

import orjson

from . import events as ev
from . import native
from .errors import RecordingError
from .frames import (MAX_ABS_POSITION_M, DeviceSample, FrameRecord, PartSnapshot,
                     RecordedFrame, TrackerFrame, changed_indices)

TRACKER_TOPIC: Final = "/tracker"
PARTS_TOPIC: Final = "/parts"
FOXGLOVE_TOPIC: Final = "/foxglove/transforms"
EVENT_TOPIC_PREFIX: Final = "/events/"

# topic -> (schema name, schema file in schemas/)
CHANNELS = {
    TRACKER_TOPIC: ("vade.TrackerFrame", "messages/TrackerFrame.schema.json"),
    PARTS_TOPIC: ("vade.PartPoses", "messages/PartPoses.schema.json"),
    FOXGLOVE_TOPIC: ("foxglove.FrameTransforms", "messages/foxglove.FrameTransforms.schema.json"),
}
for _kind in sorted(ev.REGISTRY):
    CHANNELS[EVENT_TOPIC_PREFIX + _kind] = (f"vade.{_kind}", f"events/{_kind}.schema.json")


def dumps(value: dict) -> bytes:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


def parse_json(data: bytes):
    """A message's JSON: by ``orjson`` (6x ``json.loads`` on a tracker frame, the same
    float64 for every number: both round correctly), and by ``json`` what ``orjson``
    refuses (``NaN``, a number past float64's range, lone surrogates), so that the checks
    after name the field, not the parser. One difference is left: an integer past 64 bits
    ``orjson`` reads as a float, ``json`` as an int. No field takes one: the numbers of a
    pose are bounded, and ``decode_tracker`` checks that frame and time fit 64 bits, so
    either reading is refused, naming the field."""
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError:
        return json.loads(data)


def loads(data: bytes, *, topic: str, frame: int | None = None) -> dict:
    try:
        value = parse_json(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RecordingError(f"message on {topic} is not JSON: {exc}", frame=frame) from None
    if not isinstance(value, dict):
        raise RecordingError(f"message on {topic} is not a JSON object", frame=frame)
    return value


def encode_tracker(frame: TrackerFrame) -> dict:
    return {
        "frame": frame.frame,
        "time_ns": frame.time_ns,
        "devices": {name: {"position": list(s.position), "xyzw": list(s.rotation_xyzw),
                           "grip": s.grip}
                    for name, s in frame.devices},
    }


_QUOTED: dict[str, str] = {}  # names and modes as JSON strings (a few dozen per session)


def json_string(text: str) -> str:
    """``json.dumps(text)``, remembered: part, mode and device names recur every frame."""
    quoted = _QUOTED.get(text)
    if quoted is None:
        quoted = json.dumps(text)
        if len(_QUOTED) < 4096:
            _QUOTED[text] = quoted
    return quoted


def tracker_message(frame: TrackerFrame) -> bytes:
    """``dumps(encode_tracker(frame))``, the same bytes (``tests/test_codec.py``), written
    directly, numbers by ``json_numbers``: ~5x cheaper, for the recorder. Anything the
    direct path does not cover goes through ``json`` and its errors."""
    if type(frame.frame) is not int or type(frame.time_ns) is not int:
        return dumps(encode_tracker(frame))
    devices: list[str] = []
    last = ""
    for name, sample in frame.devices:
        # Names in strictly increasing order, as sort_keys writes them (and no repeats,
        # which a dict would merge).
        if type(name) is not str or (devices and name <= last):
            return dumps(encode_tracker(frame))
        last = name
        grip = sample.grip
        g = "null" if grip is None else "true" if grip is True else "false" \
            if grip is False else ""
        p, q = sample.position, sample.rotation_xyzw  # read once (see FrameEncoder._fragments)
        n = json_numbers((p[0], p[1], p[2], q[0], q[1], q[2], q[3])) \
            if len(p) == 3 and len(q) == 4 else None
        if n is None or not g:
            return dumps(encode_tracker(frame))
        devices.append(f'{json_string(name)}:{{"grip":{g},"position":[{n[0]},{n[1]},{n[2]}],'
                       f'"xyzw":[{n[3]},{n[4]},{n[5]},{n[6]}]}}')
    return (f'{{"devices":{{{",".join(devices)}}},"frame":{frame.frame},'
            f'"time_ns":{frame.time_ns}}}').encode()


def _vec(value, n: int, *, topic: str, field: str, frame: int | None) -> tuple:
    # Fast path: what this encoder writes (floats); the sum is finite only if every term is.
    if type(value) is list and len(value) == n and all(type(v) is float for v in value) \
            and math.isfinite(sum(value, 0.0)) and max(map(abs, value)) <= MAX_ABS_POSITION_M:
        return tuple(value)
    if not (isinstance(value, list) and len(value) == n and
            all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                and abs(v) <= MAX_ABS_POSITION_M for v in value)):
        raise RecordingError(f"{field} must be {n} finite numbers of at most "
                             f"{MAX_ABS_POSITION_M:g} in size, got {value!r}",
                             field=f"{topic} {field}", frame=frame)
    return tuple(float(v) for v in value)


def _floats_in_room(values: list) -> bool:
    """Every item a float of at most MAX_ABS_POSITION_M in size (so finite: NaN fails)."""
    for v in values:
        if type(v) is not float or not abs(v) <= MAX_ABS_POSITION_M:
            return False
    return True


def _decode_devices_fast(devices: dict) -> tuple | None:
    """The devices of a tracker frame as this encoder writes them (3 + 4 finite floats of at
    most MAX_ABS_POSITION_M and a bool or null grip each), checked number by number;
    ``None`` for anything else, which the per-device path below then decodes or refuses,
    naming it. (Compiled, the numbers are C doubles here: a NaN fails ``<=``.)"""
    out: list[tuple[str, DeviceSample]] = []
    last = ""
    # In the order written (orjson keeps it): sorted, as this encoder writes them; else
    # taken again sorted.
    for name, d in devices.items():
        if out and not name > last:
            return _decode_devices_fast({k: devices[k] for k in sorted(devices)})
        last = name
        if type(d) is not dict:
            return None
        pos, rot, grip = d.get("position"), d.get("xyzw"), d.get("grip")
        if not (type(pos) is list and type(rot) is list and len(pos) == 3 and len(rot) == 4
                and (grip is None or grip is True or grip is False)):
            return None
        if not (_floats_in_room(pos) and _floats_in_room(rot)):
            return None
        px: float = pos[0]
        py: float = pos[1]
        pz: float = pos[2]
        qx: float = rot[0]
        qy: float = rot[1]
        qz: float = rot[2]
        qw: float = rot[3]
        out.append((name, DeviceSample((px, py, pz), (qx, qy, qz, qw), grip)))
    return tuple(out)


def decode_tracker(data: bytes) -> TrackerFrame:
    """A recorded tracker frame; a malformed one raises ``RecordingError`` naming the field."""
    value = loads(data, topic=TRACKER_TOPIC)
    frame, time_ns = value.get("frame"), value.get("time_ns")
    if type(frame) is not int or type(time_ns) is not int:
        raise RecordingError("tracker message lacks integer frame/time_ns",
                             field=TRACKER_TOPIC, frame=frame if type(frame) is int else None)
    # What MCAP's 64-bit times and a frame counter hold; checked here, not left to a
    # parser's reading of an oversized integer.
    if not (0 <= frame < 2**63 and 0 <= time_ns < 2**64):
        raise RecordingError(f"tracker frame {frame} / time_ns {time_ns} out of range "
                             "(0 to 2**63 and 2**64)", field=f"{TRACKER_TOPIC} frame/time_ns")
    devices = value.get("devices")
    if not isinstance(devices, dict):
        raise RecordingError("tracker message lacks devices", field=TRACKER_TOPIC, frame=frame)
    fast = _decode_devices_fast(devices)
    if fast is not None:
        return TrackerFrame(frame, time_ns, fast)
    # Something in it is not what this encoder writes: each device checked on its own, so
    # that the error names it (``_vec`` keeps a fast path for the devices that are).
    samples: list[tuple[str, DeviceSample]] = []
    for name in sorted(devices):
        d = devices[name]
        if not isinstance(d, dict):
            raise RecordingError(f"device {name} is not an object", field=TRACKER_TOPIC,
                                 frame=frame)
        grip = d.get("grip")
        if grip is not None and not isinstance(grip, bool):
            raise RecordingError(f"{name}.grip must be true, false or null",
                                 field=f"{TRACKER_TOPIC} {name}.grip", frame=frame)
        samples.append((name, DeviceSample(
            _vec(d.get("position"), 3, topic=TRACKER_TOPIC, field=f"{name}.position", frame=frame),
            _vec(d.get("xyzw"), 4, topic=TRACKER_TOPIC, field=f"{name}.xyzw", frame=frame),
            grip)))
    return TrackerFrame(frame, time_ns, tuple(samples))


# Why a recording whose tracker messages are not numbered one a frame cannot be replayed.
_EDITED: Final = (": the recording was edited, filtered or merged by another tool? Its "
                  "inputs are not the ones recorded, so it cannot be replayed")


def recorded_frames(messages: Iterator[Any], topics: dict[int, str],
                    other: Callable[[Any], None],
                    pending: list[RecordedFrame]) -> Iterator[RecordedFrame]:
    """A recording's messages (``recording._messages``: ``(channel id, data)`` tuples and
    the records between them) as frames: a tracker message (decoded, ``decode_tracker``)
    and the derived messages after it. A frame is yielded when the next one begins; the
    one being read is ``pending[0]`` (the caller decides, when the messages end or the
    reading fails, whether it is whole). Any other record goes to ``other``, which keeps
    ``topics`` (channel id -> topic) up to date. Compiled, the per-message work of
    ``Recording.frames`` in C."""
    current: RecordedFrame | None = None
    parts_seen = False  # the frame's /parts message read (one a frame)
    for record in messages:
        if type(record) is tuple:
            channel_id, data = record
            topic = topics.get(channel_id)
            if topic == TRACKER_TOPIC:
                if current is not None:
                    pending.clear()
                    yield current
                expected = 0 if current is None else current.inputs.frame + 1
                try:
                    inputs = decode_tracker(data)
                except RecordingError as exc:
                    if exc.frame is None:  # (its own number unread: the one it should be)
                        exc.frame = expected
                    raise
                if inputs.frame != expected:
                    # Frames are written numbered from 0, one a message: a gap or a repeat
                    # is an edited file's, not a divergence of the physics (a researcher's
                    # trial: one message dropped by another tool read "DIVERGED" with a
                    # message's whole dict).
                    raise RecordingError(_misnumbered(expected, inputs.frame),
                                         field=f"{TRACKER_TOPIC} frame", frame=expected)
                if current is not None and inputs.time_ns < current.inputs.time_ns:
                    # (A tracker's frames may repeat a time, a duplicated sample; never go
                    # back: the step and the release-velocity fit take time as it comes.)
                    raise RecordingError(
                        f"tracker time goes backwards: {inputs.time_ns} ns after "
                        f"{current.inputs.time_ns} ns (frame {current.inputs.frame})",
                        field=f"{TRACKER_TOPIC} time_ns", frame=inputs.frame)
                current = RecordedFrame(inputs, [])
                pending.append(current)
                parts_seen = False
            elif topic is not None and topic in CHANNELS:
                if current is None:
                    raise RecordingError(f"{topic} message before the first tracker frame")
                if topic == PARTS_TOPIC:
                    if parts_seen:
                        # The next frame's derived messages with no tracker message before
                        # them: one dropped, the file's last too (a review: that one read
                        # as a divergence, found by no later frame's number).
                        missing = current.inputs.frame + 1
                        raise RecordingError(
                            f"tracker frame {missing} is missing (frame {current.inputs.frame}"
                            f" is followed by frame {missing}'s other messages)"
                            + _EDITED, field=f"{TRACKER_TOPIC} frame", frame=missing)
                    parts_seen = True
                current.derived.append((topic, data))
        else:
            other(record)


def _misnumbered(expected: int, found: int) -> str:
    """Why a tracker message's frame number is not the next one, in a user's words."""
    if found == expected - 1:
        what = f"tracker frame {found} appears twice"
    elif expected == 0:
        what = f"the first tracker frame is frame {found}, not 0: the frames before it are missing"
    elif found > expected:
        what = (f"tracker frame {expected} is missing" if found == expected + 1 else
                f"tracker frames {expected}-{found - 1} are missing") \
            + f" (frame {expected - 1} is followed by frame {found})"
    else:
        what = f"tracker frame {found} comes after frame {expected - 1}"
    return what + _EDITED


def snapshot_dict(s: PartSnapshot) -> dict:
    """A part's snapshot as a /parts message holds it."""
    return {"name": s.name, "mode": s.mode, "position": list(s.position),
            "xyzw": list(s.rotation_xyzw), "linear_velocity": list(s.linear_velocity),
            "angular_velocity": list(s.angular_velocity)}


def encode_parts(record: FrameRecord) -> dict:
    return {"frame": record.frame, "time_ns": record.time_ns,
            "base": snapshot_dict(record.base) if record.base else None,
            "parts": [snapshot_dict(p) for p in record.parts]}


def encode_foxglove(record: FrameRecord) -> dict:
    sec, nsec = divmod(record.time_ns, 10**9)
    items = ([record.base] if record.base else []) + list(record.parts)
    return {"transforms": [
        {"timestamp": {"sec": sec, "nsec": nsec}, "parent_frame_id": "world",
         "child_frame_id": s.name,
         "translation": {"x": s.position[0], "y": s.position[1], "z": s.position[2]},
         "rotation": {"x": s.rotation_xyzw[0], "y": s.rotation_xyzw[1],
                      "z": s.rotation_xyzw[2], "w": s.rotation_xyzw[3]}}
        for s in items]}


PARTS_FULL, PARTS_CHANGED = "full", "changed"
PARTS_ENCODINGS = (PARTS_FULL, PARTS_CHANGED)


def keyframe(time_ns: int, previous_time_ns: int | None) -> bool:
    """Whether a ``changed``-encoded frame lists every part: the first frame, and the first
    of each simulated second (so a reader that seeks finds a whole state within a second)."""
    return previous_time_ns is None or time_ns // 10**9 != previous_time_ns // 10**9


def derived_messages(record: FrameRecord, *, parts: str = PARTS_FULL,
                     previous_parts: tuple | None = None,
                     previous_time_ns: int | None = None) -> list[tuple[str, bytes]]:
    """Every derived message of a frame, in the order they are written.

    ``parts="full"`` (recordings made before the ``changed`` encoding): /parts and the
    transforms list every part every frame. ``parts="changed"``: they list the base and
    only the parts whose snapshot differs from the previous frame's (``previous_parts``,
    at ``previous_time_ns``), with ``"complete": true`` and every part on a key frame
    (``keyframe``); a reader carries the others forward (``decode_parts``).
    """
    if parts == PARTS_CHANGED:
        complete = previous_parts is None or keyframe(record.time_ns, previous_time_ns) \
            or len(previous_parts) != len(record.parts)
        if not complete and previous_parts is not None:
            listed = tuple(p for p, q in zip(record.parts, previous_parts) if p != q)
            record = replace(record, parts=listed)
        doc = encode_parts(record)
        doc["complete"] = complete
        out = [(PARTS_TOPIC, dumps(doc)), (FOXGLOVE_TOPIC, dumps(encode_foxglove(record)))]
    else:
        out = [(PARTS_TOPIC, dumps(encode_parts(record))),
               (FOXGLOVE_TOPIC, dumps(encode_foxglove(record)))]
    for event in record.events:
        out.append((EVENT_TOPIC_PREFIX + event.kind, dumps(ev.to_dict(event))))
    return out


_FLOAT_REPR = float.__repr__


def _repr_text(piece: str, value: float) -> str:
    """``repr(value)``, from ``piece``, orjson's text of the float ``value``. The two
    notations orjson writes where ``repr`` writes another (nearly every such number of a
    frame: velocities near rest) are rewritten as text: ``d.ddde-N`` (a one-digit negative
    exponent), where ``repr`` writes ``e-0N``; and ``0.0000ddd`` (1e-5 <= |x| < 1e-4),
    where it writes ``d.ddde-05``. The digits are the same shortest ones. Anything else
    is left to ``repr`` (CPython's dtoa: ~12,000 instructions a number, a few times what
    these string operations cost)."""
    body = piece[1:] if piece.startswith("-") else piece
    n = len(body)
    if n >= 3 and body[n - 3] == "e" and body[n - 2] == "-" and body[n - 1] != "0":
        return piece[:-1] + "0" + piece[-1]
    if n > 6 and body.startswith("0.0000") and body[6] != "0" and "e" not in body:
        sign = "-" if n < len(piece) else ""
        digits = body[6:]
        if len(digits) == 1:
            return sign + digits + "e-05"
        return sign + digits[0] + "." + digits[1:] + "e-05"
    return _FLOAT_REPR(value)


def json_numbers(values: tuple) -> list[str] | None:
    """The text ``json.dumps`` writes for each of ``values``, or ``None`` if it would refuse
    one (NaN, infinity) or ``orjson`` cannot write one.

    ``json`` writes a float as ``repr`` does: the shortest digits that read back to the same
    float64. Each costs ~0.5 us in CPython's dtoa; ``orjson`` writes a whole list in about
    the time of two. Its digits are the same shortest ones (Ryu); only the notation can
    differ: ``1e-9`` or ``1e-09``, ``1e140`` or ``1e+140``, ``0.00001`` or ``1e-05``. Every
    such text holds an ``e`` or ``0.0000``, which ``repr``'s fixed notation (1e-4 <= |x| <
    1e16) never starts with, so those (velocities near rest: two in a frame of three
    moving parts) are put in ``repr``'s notation (``_repr_text``); a false alarm
    (``100000.00001``) only costs a ``repr``. ``tests/test_codec.py`` holds the
    two to each other on every exponent, random bit patterns and hypothesis' floats.
    """
    try:
        text = orjson.dumps(values).decode()
    except TypeError:  # orjson.JSONEncodeError: a type it does not write
        return None
    if "n" in text:  # null: orjson writes NaN and infinity so; json refuses them
        return None
    pieces = text[1:-1].split(",") if len(text) > 2 else []
    if len(pieces) != len(values):
        return None
    if "e" in text or "0.0000" in text:  # "true" and "false" too: json writes the same
        for i, piece in enumerate(pieces):
            if "e" in piece or "0.0000" in piece:
                value = values[i]
                pieces[i] = _repr_text(piece, value) if type(value) is float \
                    else json.dumps(value)
    return pieces


_QUOTED_BYTES: dict[str, bytes] = {}


def _quoted_bytes(text: str) -> bytes:
    """``json_string(text)`` as bytes, remembered likewise."""
    quoted = _QUOTED_BYTES.get(text)
    if quoted is None:
        quoted = json_string(text).encode()
        if len(_QUOTED_BYTES) < 4096:
            _QUOTED_BYTES[text] = quoted
    return quoted


_NOT_NUMBER_BYTES: Final = b"0123456789.-+e"


def _json_number_py(token: bytes) -> bytes | None:
    """``json``'s text of a number from orjson's ``token`` (the digits are the same
    shortest ones: ``json_numbers``), or None. Rewritten: ``d.ddde-N`` (a one-digit
    negative exponent: repr writes ``e-0N``), ``d.ddde16`` (a positive one without its
    sign: ``e+16``), ``0.0000ddd`` (1e-5 <= |x| < 1e-4: ``d.dde-05``). As it is: a
    negative exponent of two or three digits, a signed positive one (orjson 3.13's
    ``1e+16``), and fixed notation. None: exponents of other forms, anything but
    [-+0-9.e] (orjson's ``null``, ``true``), two dots. ``_framejson.c``'s
    ``json_number``, the same cases."""
    negative = token.startswith(b"-")
    body = token[1:] if negative else token
    if not body or body.translate(None, _NOT_NUMBER_BYTES) or body.count(b".") > 1:
        return None
    if b"e" in body:
        mantissa, _, exponent = body.partition(b"e")
        if not mantissa or b"e" in exponent:
            return None
        if exponent.startswith(b"-"):
            digits = exponent[1:]
            if not digits.isdigit() or digits.startswith(b"0") or len(digits) > 3:
                return None
            return token[:-1] + b"0" + token[-1:] if len(digits) == 1 else token
        signed = exponent.startswith(b"+")
        digits = exponent[1:] if signed else exponent
        if not digits.isdigit() or digits.startswith(b"0") or not 2 <= len(digits) <= 3:
            return None
        return token if signed else token[:len(token) - len(digits)] + b"+" + digits
    at = body.find(b"0.0000")
    if at < 0:
        return token
    if at > 0:
        # An integer part ending in 0 (``10.00001``): json's notation too. A leading zero
        # (``00.00001``) is no number orjson writes.
        return None if body.startswith(b"0") else token
    digits = body[6:]
    if not digits or digits.startswith(b"0") or not digits.isdigit():
        return None
    rest = b"." + digits[1:] if len(digits) > 1 else b""
    return (b"-" if negative else b"") + digits[:1] + rest + b"e-05"


def _json_part(t: list[bytes], name: bytes, mode: bytes) -> bytes:
    return b"".join((b'{"angular_velocity":[', t[0], b",", t[1], b",", t[2],
                     b'],"linear_velocity":[', t[3], b",", t[4], b",", t[5], b'],"mode":', mode,
                     b',"name":', name, b',"position":[', t[6], b",", t[7], b",", t[8],
                     b'],"xyzw":[', t[9], b",", t[10], b",", t[11], b",", t[12], b"]}"))


def _json_transform(t: list[bytes], name: bytes, stamp: bytes) -> bytes:
    return b"".join((b'{"child_frame_id":', name,
                     b',"parent_frame_id":"world","rotation":{"w":', t[12], b',"x":', t[9],
                     b',"y":', t[10], b',"z":', t[11], b'},"timestamp":', stamp,
                     b',"translation":{"x":', t[6], b',"y":', t[7], b',"z":', t[8], b"}}"))


# A frame's "complete" key by its code: 0 the full encoding (no such key), 1 a frame of
# changes, 2 a key frame (``derived_messages``); both frame writers take the code.
_COMPLETE_TEXTS: Final = ("", ',"complete":false', ',"complete":true')


def _frame_json_py(numbers: bytes, names: list[bytes], modes: list[bytes], with_base: bool,
                   complete: Any, frame: Any, time_ns: Any) -> tuple[bytes, bytes] | None:
    """A frame's /parts and /foxglove/transforms bytes from ``numbers``, orjson's text of
    the 13 numbers of each part shown (angular velocity, linear velocity, position, xyzw),
    the base's first ``with_base``; ``names`` and ``modes`` each part's, quoted as ``json``
    quotes them; ``complete`` 0 (the full encoding: no such key), 1 (false) or 2 (true);
    ``frame`` and ``time_ns`` the frame's. None where a number is not covered
    (``_json_number_py``), the text is not 13 numbers a part, or the frame or time is not
    a non-negative integer of 64 bits. The reference of ``_framejson.frame_messages``,
    which ``FrameEncoder`` runs where it is built."""
    k = len(names)
    if k == 0 or len(numbers) < 2 or not numbers.startswith(b"[") \
            or not numbers.endswith(b"]"):
        return None
    if type(complete) is not int or not 0 <= complete <= 2 or type(frame) is not int \
            or not 0 <= frame < 2**63 or type(time_ns) is not int or not 0 <= time_ns < 2**64:
        return None
    tokens: list[bytes] = []
    for piece in numbers[1:-1].split(b","):
        text = _json_number_py(piece)
        if text is None:
            return None
        tokens.append(text)
    if len(tokens) != 13 * k:
        return None
    sec, nsec = divmod(time_ns, 10**9)
    middle = f'{_COMPLETE_TEXTS[complete]},"frame":{frame},"parts":['.encode()
    end = f'],"time_ns":{time_ns}}}'.encode()
    stamp = f'{{"nsec":{nsec},"sec":{sec}}}'.encode()
    first = 1 if with_base else 0
    base = _json_part(tokens[:13], names[0], modes[0]) if with_base else b"null"
    parts = b",".join([_json_part(tokens[13 * i:13 * i + 13], names[i], modes[i])
                       for i in range(first, k)])
    transforms = b",".join([_json_transform(tokens[13 * i:13 * i + 13], names[i], stamp)
                            for i in range(k)])
    return (b"".join((b'{"base":', base, middle, parts, end)),
            b"".join((b'{"transforms":[', transforms, b"]}")))


def _frame_json_writer():
    """``_framejson.frame_messages`` where it is built and in use (``native.c_enabled``),
    else its Python reference."""
    if native.c_enabled():
        try:
            from ._framejson import frame_messages
            return frame_messages
        except ImportError:
            pass
    return _frame_json_py


_FRAME_JSON: Final = _frame_json_writer()
# A frame showing more parts than this (a key frame of a scene with many resting ones) is
# written from the texts kept from frame to frame: a part that did not move costs nothing
# there, where the numbers' writer writes every part it is given.
_NUMBERS_AT_MOST: Final = 16


class FrameEncoder:
    """``derived_messages`` with the text of an unchanged part reused from the last frame.

    The bytes are exactly ``derived_messages``' (``tests/test_codec.py`` checks it): keys in
    sorted order, the same separators, floats written by ``float.__repr__`` as ``json``
    does. A part whose snapshot is the same object as last frame's (a resting part; see
    ``step.frame_record``) costs nothing but its share of two joins done in C; anything the
    fast path does not cover (a non-finite or non-float number) goes through ``json`` and
    its errors.
    """

    def __init__(self, parts: str = PARTS_FULL) -> None:
        if parts not in PARTS_ENCODINGS:
            raise ValueError(f"parts encoding must be one of {PARTS_ENCODINGS}")
        self.parts = parts
        self._time_ns: int | None = None  # the last frame's time (key frames)
        self._last: tuple = ()            # the last frame's snapshots, base first
        self._items: tuple = ()      # the snapshots whose texts are cached: base first
        self._texts: list[str] = []  # each item's /parts object
        self._heads: list[str] = []  # each item's transform up to its timestamp
        self._tails: list[str] = []  # and after it
        self._glue: list[str] = []   # heads[0], tails[0] + "," + heads[1], ..., tails[-1]

    def _fallback(self, record: FrameRecord, previous_items: tuple,
                  previous_time: int | None) -> list[tuple[str, bytes]]:
        """The reference encoder, for what the fast path does not cover."""
        if self.parts == PARTS_FULL:
            return derived_messages(record)
        first = 0 if record.base is None else 1
        previous = tuple(previous_items[first:]) \
            if len(previous_items) == len(record.parts) + first else None
        return derived_messages(record, parts=PARTS_CHANGED, previous_parts=previous,
                                previous_time_ns=previous_time)

    def _fragments(self, s: PartSnapshot) -> tuple[str, str, str] | None:
        name, mode = json_string(s.name), json_string(s.mode)
        # Each field read once into a local and indexed (compiled, a fixed-length tuple
        # field is a C struct: reading it into len() or a star-unpack builds a new tuple
        # of new floats each time).
        av, lv, p, q = s.angular_velocity, s.linear_velocity, s.position, s.rotation_xyzw
        if not (len(av) == len(lv) == len(p) == 3 and len(q) == 4):
            return None
        r = json_numbers((av[0], av[1], av[2], lv[0], lv[1], lv[2], p[0], p[1], p[2],
                          q[0], q[1], q[2], q[3]))
        if r is None:
            return None
        part = (f'{{"angular_velocity":[{r[0]},{r[1]},{r[2]}],"linear_velocity":[{r[3]},{r[4]},'
                f'{r[5]}],"mode":{mode},"name":{name},"position":[{r[6]},{r[7]},{r[8]}],'
                f'"xyzw":[{r[9]},{r[10]},{r[11]},{r[12]}]}}')
        head = (f'{{"child_frame_id":{name},"parent_frame_id":"world","rotation":'
                f'{{"w":{r[12]},"x":{r[9]},"y":{r[10]},"z":{r[11]}}},"timestamp":')
        tail = f',"translation":{{"x":{r[6]},"y":{r[7]},"z":{r[8]}}}}}'
        return part, head, tail

    def _by_numbers(self, record: FrameRecord, items: tuple, shown: list[int], first: int,
                    complete: int) -> list[tuple[str, bytes]] | None:
        """The two messages with every number of the parts shown written by one
        ``orjson.dumps`` and the text around them by ``_FRAME_JSON`` (C where built), or
        None where it does not cover a number."""
        numbers: list[Any] = []
        names: list[bytes] = []
        modes: list[bytes] = []
        for i in shown:
            s: PartSnapshot = items[i]
            # Each field read once into a local and indexed (compiled, a fixed-length tuple
            # field is a C struct: reading it into len() or a star-unpack builds a new
            # tuple of new floats each time).
            av, lv, p, q = s.angular_velocity, s.linear_velocity, s.position, s.rotation_xyzw
            if not (len(av) == len(lv) == len(p) == 3 and len(q) == 4):
                return None
            numbers.extend((av[0], av[1], av[2], lv[0], lv[1], lv[2], p[0], p[1], p[2],
                            q[0], q[1], q[2], q[3]))
            names.append(_quoted_bytes(s.name))
            modes.append(_quoted_bytes(s.mode))
        try:
            text = orjson.dumps(numbers)
        except TypeError:  # orjson.JSONEncodeError: a type it does not write
            return None
        # The frame's number and time are written there too (no texts made for them here).
        written = _FRAME_JSON(text, names, modes, first == 1, complete, record.frame,
                              record.time_ns)
        if written is None:
            return None
        return [(PARTS_TOPIC, written[0]), (FOXGLOVE_TOPIC, written[1])]

    def _by_texts(self, record: FrameRecord, items: tuple, listed: list[int],
                  shown: list[int], first: int,
                  complete: int) -> list[tuple[str, bytes]] | None:
        """The two messages from each part's text, kept from frame to frame while its
        snapshot is the same object; None where ``_fragments`` does not cover one."""
        n = len(items)
        if len(self._items) != n:
            self._items = (None,) * n
            self._texts, self._heads, self._tails = [""] * n, [""] * n, [""] * n
            self._glue = [""] * (n + 1)
        texts, heads, tails, glue = self._texts, self._heads, self._tails, self._glue
        for i in changed_indices(items, self._items):
            fragments = self._fragments(items[i])
            if fragments is None:
                return None
            texts[i], heads[i], tails[i] = fragments
            glue[i] = heads[i] if i == 0 else tails[i - 1] + "," + heads[i]
            glue[i + 1] = tails[i] if i == n - 1 else tails[i] + "," + heads[i + 1]
        self._items = items  # tuples: never changed in place
        frame, t = record.frame, record.time_ns
        sec, nsec = divmod(t, 10**9)
        stamp = f'{{"nsec":{nsec},"sec":{sec}}}'
        base = "null" if record.base is None else texts[0]
        parts_text = ",".join([texts[i] for i in listed])
        if len(shown) == n:
            transforms = stamp.join(glue)
        else:
            transforms = ",".join([heads[i] + stamp + tails[i] for i in shown])
        return [(PARTS_TOPIC, (f'{{"base":{base}{_COMPLETE_TEXTS[complete]},"frame":{frame},'
                               f'"parts":[{parts_text}],"time_ns":{t}}}').encode()),
                (FOXGLOVE_TOPIC, ('{"transforms":[' + transforms + "]}").encode())]

    def derived_messages(self, record: FrameRecord) -> list[tuple[str, bytes]]:
        """The same list, the same bytes, as ``derived_messages(record)``."""
        frame, t = record.frame, record.time_ns
        items = record.parts if record.base is None else (record.base, *record.parts)
        n = len(items)
        # The last frame's snapshots and time decide what a ``changed`` frame lists;
        # ``self._items`` only says which cached texts are still good.
        previous_items, self._last = self._last, items
        previous_time, self._time_ns = self._time_ns, t if type(t) is int else None
        if type(frame) is not int or type(t) is not int or n == 0:
            self._items = ()
            return self._fallback(record, previous_items, previous_time)
        first = 0 if record.base is None else 1
        listed: list[int]
        shown: list[int]
        if self.parts == PARTS_CHANGED and len(previous_items) == n \
                and not keyframe(t, previous_time):
            # Only what differs from last frame (by value: a new snapshot equal to the old
            # one is not listed), and the base, whose transform is always written. Against
            # last frame's snapshots, not the cached texts' (``changed``): after frames
            # written by numbers or checked by value the cache is older than last frame.
            listed = [i for i in changed_indices(items, previous_items)
                      if i >= first and items[i] != previous_items[i]]
            shown = [0] + listed if first else listed
            complete = 1  # (_COMPLETE_TEXTS)
        else:
            listed = list(range(first, n))
            shown = list(range(n))
            complete = 2 if self.parts == PARTS_CHANGED else 0
        out = self._by_numbers(record, items, shown, first, complete) \
            if 0 < len(shown) <= _NUMBERS_AT_MOST else None
        if out is None:
            out = self._by_texts(record, items, listed, shown, first, complete)
            if out is None:
                self._items = ()
                return self._fallback(record, previous_items, previous_time)
        for event in record.events:
            out.append((EVENT_TOPIC_PREFIX + event.kind, dumps(ev.to_dict(event))))
        return out


    def check(self, record: FrameRecord,
              recorded: list[tuple[str, bytes]]) -> list[tuple[str, bytes]] | None:
        """``None`` when ``recorded`` holds what this frame derives; else
        ``derived_messages(record)``, for the report. Either way the encoder moves past
        the frame.

        By bytes first: ours written (``derived_messages``: a frame's numbers by one
        ``orjson.dumps``, the text around them in C) and compared, which costs less than
        parsing the recorded messages (a three-part frame: ~25,000 instructions against
        ~88,000 parsed and compared by value). Where the bytes differ, by value
        (``matches``): text that reads back to the same numbers but is not this encoder's
        (another writer's spacing or notation) matches; a frame that differs is reported
        with ours."""
        last, last_time = self._last, self._time_ns
        derived = self.derived_messages(record)
        if derived == recorded:
            return None
        after, after_time = self._last, self._time_ns
        self._last, self._time_ns = last, last_time
        if self.matches(record, recorded):
            return None
        self._last, self._time_ns = after, after_time
        return derived

    def matches(self, record: FrameRecord, recorded: list[tuple[str, bytes]],
                most: int = 1 << 30) -> bool:
        """Whether ``recorded`` holds the messages ``derived_messages(record)`` would write,
        checked by value without writing them: each recorded message is parsed (orjson)
        and held to the record, every key, string and integer equal and every number the
        same float64 bit for bit (-0.0 is not 0.0). ``True`` advances the encoder past the
        frame as ``derived_messages`` would; ``False`` (a difference, or anything this
        does not cover) leaves it as it was, for ``derived_messages`` and a comparison of
        bytes. Text that reads back to the same values but is not this encoder's (other
        spacing or number notation) matches: the check is of the session, not of the
        formatting, which the writer's own tests hold (``tests/test_codec.py``).

        ``check`` calls this only where the bytes differ: parsing costs about three times
        writing ours. A frame listing more than ``most`` parts and transforms is not
        checked: ``False``, as for a difference."""
        frame, t = record.frame, record.time_ns
        base = record.base
        items = record.parts if base is None else (base, *record.parts)
        n = len(items)
        events = record.events
        if type(frame) is not int or type(t) is not int or len(recorded) != 2 + len(events):
            return False
        first = 0 if base is None else 1
        previous_items, previous_time = self._last, self._time_ns
        changed = self.parts == PARTS_CHANGED
        shown: list[int]
        if changed and len(previous_items) == n and not keyframe(t, previous_time):
            complete: bool | None = False
            # (The scan for other objects in C: a comprehension over every part cost a
            # scene of 200 resting parts ~13,000 instructions a frame.)
            listed = [i for i in changed_indices(items, previous_items)
                      if i >= first and items[i] != previous_items[i]]
            shown = [0] + listed if first else listed
        else:
            complete = True if changed else None
            listed = list(range(first, n))
            shown = list(range(n))
        if len(shown) > most:
            return False
        topic, data = recorded[0]
        if topic != PARTS_TOPIC or not _parts_match(data, frame, t, complete, base,
                                                    [items[i] for i in listed]):
            return False
        topic, data = recorded[1]
        if topic != FOXGLOVE_TOPIC or not _transforms_match(data, t,
                                                            [items[i] for i in shown]):
            return False
        for k, event in enumerate(events):
            topic, data = recorded[2 + k]
            if topic != EVENT_TOPIC_PREFIX + event.kind or data != dumps(ev.to_dict(event)):
                return False
        self._last, self._time_ns = items, t
        return True


def checked_run(encoder: FrameEncoder, batch: list[RecordedFrame], stepped: list[FrameRecord],
                start: int, add: Callable[[FrameRecord], None]) -> tuple[int, int, Any]:
    """A plain replay's check of frames ``start``, ``start + 1``, ... of a batch (the frames
    read, ``batch``, and what they stepped to, ``stepped``) as long as each matches its
    recording (``encoder.check``) and has no events: each such frame is given to ``add``
    (the analysis). Returns the index of the first frame that did not (``len(stepped)``
    where all did), the messages checked in the frames before it, and that frame's check
    (None: it matched, with events to see to; else ours, as ``check`` returns them): the
    caller sees to that frame, already checked, as to any other. Compiled: the loop of
    ``replay.replay`` for what nearly every frame is, ~1 us a frame less interpreted."""
    messages = 0
    n = len(stepped)
    i = start
    while i < n:
        recorded = batch[i].derived
        replayed = stepped[i]
        ours = encoder.check(replayed, recorded)
        if ours is not None or replayed.events:
            return i, messages, ours
        add(replayed)
        messages += len(recorded)
        i += 1
    return n, messages, None


def _same_float(recorded: Any, ours: float) -> bool:
    """A recorded number is ours: a float, equal, and of the same sign (-0.0 is not 0.0)."""
    if type(recorded) is not float:
        return False
    x: float = recorded
    return x == ours and (x != 0.0 or math.copysign(1.0, x) == math.copysign(1.0, ours))


def _same_vec3(recorded: Any, x: float, y: float, z: float) -> bool:
    if not isinstance(recorded, list):
        return False
    v: list[Any] = recorded
    return len(v) == 3 and _same_float(v[0], x) and _same_float(v[1], y) \
        and _same_float(v[2], z)


def _same_int(recorded: Any, ours: int) -> bool:
    return type(recorded) is int and recorded == ours


# (Typed as dicts and lists once narrowed: compiled, ``get`` and indexing are then C calls,
# not Python method calls on an object.)
def _snapshot_matches(recorded: Any, s: PartSnapshot) -> bool:
    """A /parts object is ``snapshot_dict(s)``, by value."""
    if not isinstance(recorded, dict):
        return False
    d: dict[str, Any] = recorded
    if len(d) != 6 or d.get("name") != s.name or d.get("mode") != s.mode:
        return False
    av, lv, p, q = s.angular_velocity, s.linear_velocity, s.position, s.rotation_xyzw
    rq = d.get("xyzw")
    if not isinstance(rq, list):
        return False
    r: list[Any] = rq
    return (_same_vec3(d.get("position"), p[0], p[1], p[2])
            and len(r) == 4 and _same_float(r[0], q[0]) and _same_float(r[1], q[1])
            and _same_float(r[2], q[2]) and _same_float(r[3], q[3])
            and _same_vec3(d.get("linear_velocity"), lv[0], lv[1], lv[2])
            and _same_vec3(d.get("angular_velocity"), av[0], av[1], av[2]))


def _parsed(data: bytes) -> Any:
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError:
        return None


def _parts_match(data: bytes, frame: int, t: int, complete: bool | None,
                 base: PartSnapshot | None, parts: list[PartSnapshot]) -> bool:
    """A /parts message is the one ``FrameEncoder`` writes for these, by value."""
    parsed = _parsed(data)
    if not isinstance(parsed, dict):
        return False
    doc: dict[str, Any] = parsed
    if len(doc) != (4 if complete is None else 5) or not _same_int(doc.get("frame"), frame) \
            or not _same_int(doc.get("time_ns"), t):
        return False
    if complete is not None and doc.get("complete") is not complete:
        return False
    if base is None:
        if "base" not in doc or doc["base"] is not None:
            return False
    elif not _snapshot_matches(doc.get("base"), base):
        return False
    listed = doc.get("parts")
    if not isinstance(listed, list):
        return False
    ps: list[Any] = listed
    if len(ps) != len(parts):
        return False
    for k, s in enumerate(parts):
        if not _snapshot_matches(ps[k], s):
            return False
    return True


def _transform_matches(recorded: Any, s: PartSnapshot, sec: int, nsec: int) -> bool:
    if not isinstance(recorded, dict):
        return False
    d: dict[str, Any] = recorded
    if len(d) != 5 or d.get("child_frame_id") != s.name or d.get("parent_frame_id") != "world":
        return False
    stamp_, move_, turn_ = d.get("timestamp"), d.get("translation"), d.get("rotation")
    if not (isinstance(stamp_, dict) and isinstance(move_, dict) and isinstance(turn_, dict)):
        return False
    stamp: dict[str, Any] = stamp_
    move: dict[str, Any] = move_
    turn: dict[str, Any] = turn_
    p, q = s.position, s.rotation_xyzw
    return (len(stamp) == 2 and _same_int(stamp.get("sec"), sec)
            and _same_int(stamp.get("nsec"), nsec)
            and len(move) == 3 and _same_float(move.get("x"), p[0])
            and _same_float(move.get("y"), p[1]) and _same_float(move.get("z"), p[2])
            and len(turn) == 4 and _same_float(turn.get("x"), q[0])
            and _same_float(turn.get("y"), q[1]) and _same_float(turn.get("z"), q[2])
            and _same_float(turn.get("w"), q[3]))


def _transforms_match(data: bytes, t: int, items: list[PartSnapshot]) -> bool:
    """A /foxglove/transforms message is the one ``FrameEncoder`` writes, by value."""
    parsed = _parsed(data)
    if not isinstance(parsed, dict):
        return False
    doc: dict[str, Any] = parsed
    transforms_ = doc.get("transforms")
    if len(doc) != 1 or not isinstance(transforms_, list):
        return False
    transforms: list[Any] = transforms_
    if len(transforms) != len(items):
        return False
    sec, nsec = divmod(t, 10**9)
    for k, s in enumerate(items):
        if not _transform_matches(transforms[k], s, sec, nsec):
            return False
    return True


def decode_parts(data: bytes, *, frame: int | None = None,
                 previous: tuple[PartSnapshot | None, tuple[PartSnapshot, ...]] | None = None
                 ) -> tuple[PartSnapshot | None, tuple[PartSnapshot, ...]]:
    """The base and every part after a frame. A ``changed`` frame (``"complete": false``)
    lists only what moved: the others are carried forward from ``previous`` (the decoded
    frame before), in its order."""
    value = loads(data, topic=PARTS_TOPIC, frame=frame)

    def vec(value, n: int) -> tuple:
        # Checked and made floats here, so that both builds read the same (compiled,
        # PartSnapshot checks its field types itself, and would make ints floats).
        if type(value) is not list or len(value) != n \
                or not all(type(v) is float or type(v) is int for v in value):
            raise TypeError(f"expected {n} numbers, got {value!r}")
        return tuple(float(v) for v in value)

    def snap(d: dict) -> PartSnapshot:
        if type(d["name"]) is not str or type(d["mode"]) is not str:
            raise TypeError("name and mode must be strings")
        return PartSnapshot(d["name"], d["mode"], vec(d["position"], 3), vec(d["xyzw"], 4),
                            vec(d["linear_velocity"], 3), vec(d["angular_velocity"], 3))
    try:
        base = snap(value["base"]) if value.get("base") else None
        listed = tuple(snap(p) for p in value["parts"])
    except (KeyError, TypeError, OverflowError) as exc:
        raise RecordingError(f"malformed part poses: {exc}", field=PARTS_TOPIC, frame=frame) \
            from None
    if value.get("complete", True) is not False:
        return base, listed
    if previous is None:
        raise RecordingError("a frame of changes with no complete frame before it",
                             field=PARTS_TOPIC, frame=frame)
    changed = {p.name: p for p in listed}
    parts = tuple(changed.pop(p.name, p) for p in previous[1])
    if changed:
        raise RecordingError(f"changes for parts the frame before does not have: "
                             f"{sorted(changed)}", field=PARTS_TOPIC, frame=frame)
    return base, parts


def decode_event(topic: str, data: bytes, *, frame: int | None = None) -> ev.Event:
    return ev.from_dict(loads(data, topic=topic, frame=frame), frame=frame)
