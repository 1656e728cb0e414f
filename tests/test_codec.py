"""The fast frame encoder writes exactly the bytes of the reference encoder (json.dumps).

Recordings are written by this encoder and must be the same bytes run after run, so it must agree
with ``codec.derived_messages`` (keys sorted, fixed separators, floats as ``repr``) on every
value, including -0.0, subnormals, ints, odd names, and parts that did not change between
frames (whose text is reused). Values json refuses (NaN, infinity) must be refused too.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import orjson
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from vade_replay import codec
from vade_replay.events import ModeChanged
from vade_replay.frames import (MAX_ABS_POSITION_M, DeviceSample, FrameRecord, PartSnapshot,
                                TrackerFrame, changed_indices)

finite = st.one_of(st.floats(allow_nan=False, allow_infinity=False),
                   st.sampled_from([0.0, -0.0, 5e-324, -1e-310, 1e300, 0.1, 1 / 3]))
number = st.one_of(finite, st.integers(-10**6, 10**6))
names = st.text(min_size=1, max_size=12)


@st.composite
def snapshots(draw, values=finite):
    vec = st.tuples(values, values, values)
    return PartSnapshot(draw(names), draw(st.sampled_from(["STATIC", "INHAND", "INSPACE"])),
                        draw(vec), draw(st.tuples(values, values, values, values)), draw(vec),
                        draw(vec))


@st.composite
def frame_sequences(draw, values=finite):
    """A few frames of the same parts, some of which keep their snapshot object."""
    n = draw(st.integers(0, 5))
    # A part keeps its (unique) name from frame to frame, as in a scene.
    parts = [replace(draw(snapshots(values)), name=f"{draw(names)}#{i}") for i in range(n)]
    with_base = draw(st.booleans())
    out = []
    for frame in range(draw(st.integers(1, 4))):
        for i in range(n):
            if draw(st.booleans()):
                parts[i] = replace(draw(snapshots(values)), name=parts[i].name)
        base = draw(snapshots(values)) if with_base else None
        events = (ModeChanged(frame, "p", "grabbed", "STATIC", "INHAND"),) \
            if draw(st.booleans()) else ()
        t = draw(st.integers(0, 10**13))
        out.append(FrameRecord(TrackerFrame(frame, t, ()), base, tuple(parts), events))
    return out


@settings(max_examples=200, deadline=None, derandomize=True)
@given(frame_sequences())
def test_fast_encoder_writes_the_reference_bytes(frames):
    encoder = codec.FrameEncoder()
    for record in frames:
        assert encoder.derived_messages(record) == codec.derived_messages(record)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(frame_sequences(values=number))
def test_ints_are_written_as_json_writes_them(frames):
    encoder = codec.FrameEncoder()
    for record in frames:
        assert encoder.derived_messages(record) == codec.derived_messages(record)


def _json_texts(values) -> list[str]:
    return [json.dumps(v) for v in values]


def test_number_texts_are_json_s_on_every_decimal_exponent_and_notation_boundary():
    """orjson's notation differs from repr's around 1e-5 and in the exponent's form: each
    decimal exponent of float64, both signs, and the neighbours of every boundary."""
    rng = np.random.default_rng(5)
    values = []
    for exponent in range(-324, 309):
        for mantissa in (1.0, 2.5, 9.999999999999998, *rng.uniform(1.0, 10.0, 6).tolist()):
            value = float(f"{mantissa!r}e{exponent}")
            if math.isfinite(value):
                values += [value, -value]
    for edge in (1e-5, 1e-4, 1e15, 1e16, 1e17, 5e-324, 2.2250738585072014e-308,
                 1.7976931348623157e308, 1.0, 0.0):
        values += [v for v in (math.nextafter(edge, 0.0), edge, math.nextafter(edge, math.inf))
                   if math.isfinite(v)]
    values += [-0.0, 100000.00001, 0.1, 1 / 3]
    for start in range(0, len(values), 13):
        chunk = tuple(values[start:start + 13])
        assert codec.json_numbers(chunk) == _json_texts(chunk), chunk


def test_repr_text_rewrites_orjson_s_notation_as_repr_writes_it():
    """``_repr_text`` turns orjson's text of any finite float into ``repr``'s, whether it
    rewrites the text or calls ``repr``: every decimal exponent, the neighbours of the
    notation boundaries, and random bit patterns."""
    rng = np.random.default_rng(8)
    values = [float(f"{m!r}e{e}") for e in range(-324, 309)
              for m in (1.0, 1.5, 9.999999999999998, *rng.uniform(1.0, 10.0, 4).tolist())]
    for edge in (1e-5, 1e-4, 1e-9, 1e-10, 1e16):
        values += [math.nextafter(edge, 0.0), edge, math.nextafter(edge, math.inf)]
    bits = rng.integers(0, 2**64, size=20_000, dtype=np.uint64)
    values += [float(v) for v in bits.view(np.float64)]
    values += [1e-5 * (1.0 + i / 1000.0) for i in range(9000)]  # 1e-5 to 1e-4
    values += [1e-9 * (1.0 + i / 1000.0) for i in range(9000)]  # 1e-9 to 1e-8
    forms = {"e-N": 0, "0.0000": 0}
    for value in (v for x in values for v in (x, -x) if math.isfinite(x)):
        text = orjson.dumps(value).decode()
        assert codec._repr_text(text, value) == repr(value), (text, value)
        if text != repr(value):
            forms["0.0000" if "0.0000" in text else "e-N"] += 1
    assert min(forms.values()) > 1000, forms  # both rewritings exercised, not only repr


def _writers():
    """The frame writer's implementations this install has: the Python reference, and the
    C extension where it is built."""
    out = [codec._frame_json_py]
    try:
        from vade_replay._framejson import frame_messages
    except ImportError:
        pass
    else:
        out.append(frame_messages)
    return out


def _one_part(values) -> tuple:
    """``frame_messages``' arguments for one part (the base) of these 13 numbers."""
    return (orjson.dumps(list(values)), [b'"p"'], [b'"INSPACE"'], True, 0, 3, 7)


def test_the_frame_writers_write_json_s_numbers():
    """Both writers (C and its Python reference) write ``derived_messages``' bytes for
    orjson's text of every decimal exponent, the notation boundaries and random bit
    patterns: every finite float, each of orjson's notations that differ from ``repr``'s
    rewritten (``e-0N``, ``e+NN``, ``e-05``) and the rest as orjson writes them."""
    rng = np.random.default_rng(11)
    values = [float(f"{m!r}e{e}") for e in range(-324, 309)
              for m in (1.0, 1.5, 9.999999999999998, *rng.uniform(1.0, 10.0, 3).tolist())]
    for edge in (1e-5, 1e-4, 1e-9, 1e-10, 1e15, 1e16):
        values += [math.nextafter(edge, 0.0), edge, math.nextafter(edge, math.inf)]
    bits = rng.integers(0, 2**64, size=13_000, dtype=np.uint64)
    values += [float(v) for v in bits.view(np.float64) if np.isfinite(v)]
    values += [1e-5 * (1.0 + i / 500.0) for i in range(4500)]  # 0.0000ddd
    values += [1e-9 * (1.0 + i / 500.0) for i in range(4500)]  # d.ddde-N
    # An integer part ending in 0 before 0.0000 (written as orjson writes them; a review
    # found both writers declining them, so those frames went the slower way).
    values += [10.00001, 20.000012345, 30.00009999, 100000.00001, 1000.0000123]
    values += [float(f"{m}0.0000{d}") for m in range(1, 100) for d in (1, 23, 9876543)]
    values = [v for x in values if math.isfinite(x) for v in (x, -x)] + [0.0, -0.0]
    writers = _writers()
    written = 0
    forms = {"e-0N": 0, "e-05": 0, "e+": 0, "e-NN": 0}
    for start in range(0, len(values) - 12, 13):
        chunk = values[start:start + 13]
        out = [w(*_one_part(chunk)) for w in writers]
        assert all(o == out[0] for o in out) and out[0] is not None, chunk
        written += 1
        part = PartSnapshot("p", "INSPACE", tuple(chunk[6:9]), tuple(chunk[9:13]),
                            tuple(chunk[3:6]), tuple(chunk[0:3]))
        reference = codec.derived_messages(FrameRecord(TrackerFrame(3, 7, ()), part, ()))
        assert list(out[0]) == [m for _, m in reference], chunk
        text = out[0][0].decode()
        forms["e-05"] += "e-05" in text
        forms["e-0N"] += any(f"e-0{d}" in text for d in range(6, 10))
        forms["e+"] += "e+" in text
        forms["e-NN"] += any(f"e-{d}" in text for d in range(1, 10))
    assert written > 3000 and min(forms.values()) > 200, (written, forms)


@pytest.mark.parametrize("token, text", [
    (b"1e16", b"1e+16"), (b"-2.5e123", b"-2.5e+123"), (b"1e+16", b"1e+16"),
    (b"1.5e-7", b"1.5e-07"), (b"-0.00001", b"-1e-05"), (b"0.0000123", b"1.23e-05"),
    (b"2e-17", b"2e-17"), (b"-0.0", b"-0.0"), (b"12", b"12"), (b"10.00001", b"10.00001"),
    (b"-100000.00001", b"-100000.00001")])
def test_the_frame_writers_put_each_notation_in_repr_s(token, text):
    """Each form either orjson writes (3.10 wrote ``1e16``, 3.13 writes ``1e+16``) in
    ``repr``'s notation: the last number of a part is its rotation's w."""
    numbers = b"[" + b",".join([b"0.5"] * 12 + [token]) + b"]"
    args = (numbers,) + _one_part([0.5] * 13)[1:]
    for writer in _writers():
        parts, transforms = writer(*args)
        assert parts.endswith(b"," + text + b"]},\"frame\":3,\"parts\":[],\"time_ns\":7}")
        assert b'"w":' + text + b"," in transforms


@pytest.mark.parametrize("tokens", [
    b"null", b"true", b"false", b"1e5", b"1.5e+6", b"1e+016", b"1e+", b"1e1234", b"1e-0001", b"1e016",
    b"e16", b"1e", b"1e-", b"1.5e-7e-1", b"1..5", b"0.00000", b"0.00001x", b"-", b"",
    b"1.0.0000", b"00.00001", b"1e-0"])
def test_the_frame_writers_decline_what_they_do_not_cover_alike(tokens):
    """Tokens orjson does not write for a finite float: None from both (the kept-text
    writer, and ``json``'s errors, then decide)."""
    numbers = b"[" + b",".join([b"0.5"] * 12 + [tokens]) + b"]"
    args = (numbers,) + _one_part([0.5] * 13)[1:]
    out = [w(*args) for w in _writers()]
    assert all(o is None for o in out), out


def test_the_frame_writers_write_the_reference_s_messages():
    """Two parts and a base, and no base: the messages ``derived_messages`` writes."""
    parts = tuple(PartSnapshot(f"p{i}", "INSPACE", (0.1 * i, 2.5e-7, -1.0), (0.0, 0.0, 3e-5, 1.0),
                               (1.0, -0.0, 1e-6), (0.0, 1.25, 7.0)) for i in range(2))
    base = PartSnapshot('base "b"\u00e9', "BASE", (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0),
                        (0.0,) * 3, (0.0,) * 3)
    for b in (base, None):
        record = FrameRecord(TrackerFrame(9, 1_500_000_001, ()), b, parts)
        items = parts if b is None else (b, *parts)
        numbers = orjson.dumps([x for s in items for v in (s.angular_velocity,
                                s.linear_velocity, s.position, s.rotation_xyzw) for x in v])
        args = (numbers, [json.dumps(s.name).encode() for s in items],
                [json.dumps(s.mode).encode() for s in items], b is not None, 0, 9,
                1_500_000_001)
        reference = [m for _, m in codec.derived_messages(record)]
        for writer in _writers():
            assert list(writer(*args)) == reference, writer


@pytest.mark.parametrize("complete", [0, 1, 2])
@pytest.mark.parametrize("frame, time_ns", [(0, 0), (3, 999_999_999), (17, 10**9),
                                            (2**63 - 1, 2**64 - 1), (123456, 3_600_000_000_001),
                                            (10, 10**19), (9, 9)])
def test_the_frame_writers_write_the_frame_s_number_time_and_completeness(complete, frame,
                                                                           time_ns):
    """The texts around the parts (``"complete"``, the frame, the time and the transforms'
    stamp) are written from the frame's integers, by both writers alike, as
    ``derived_messages`` writes them: to the largest frame and time MCAP holds."""
    part = PartSnapshot("p", "INSPACE", (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), (0.5,) * 3,
                        (0.25,) * 3)
    record = FrameRecord(TrackerFrame(frame, time_ns, ()), part, ())
    if complete == 0:
        reference = codec.derived_messages(record)
    else:
        # A changed-encoded frame: a key frame lists every part ("complete": true); one
        # whose parts did not move lists none but the base ("complete": false).
        reference = codec.derived_messages(
            record, parts=codec.PARTS_CHANGED, previous_parts=record.parts,
            previous_time_ns=time_ns if complete == 1 else None)
    texts = [m for _, m in reference]
    assert (b'"complete":true' in texts[0]) == (complete == 2)
    assert (b'"complete":false' in texts[0]) == (complete == 1)
    args = (orjson.dumps([0.25] * 3 + [0.5] * 3 + [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]),
            [b'"p"'], [b'"INSPACE"'], True, complete, frame, time_ns)
    for writer in _writers():
        assert list(writer(*args)) == texts, writer


@pytest.mark.parametrize("complete, frame, time_ns", [
    (3, 1, 1), (-1, 1, 1), (0, -1, 1), (0, 2**63, 1), (0, 1, -1), (0, 1, 2**64),
    (0, 1.0, 1), (0, 1, 1.0), (True, 1, 1)])
def test_the_frame_writers_decline_a_frame_they_cannot_write_alike(complete, frame, time_ns):
    """Anything but a non-negative 64-bit frame and time, and a known completeness: None
    from both, and the frame is written the slower way (``json``, and its errors)."""
    args = (orjson.dumps([0.5] * 13), [b'"p"'], [b'"INSPACE"'], True, complete, frame, time_ns)
    assert [w(*args) for w in _writers()] == [None] * len(_writers())


def test_number_texts_are_json_s_for_random_bit_patterns():
    """Every finite float64 is as likely: 65,000 of them."""
    bits = np.random.default_rng(6).integers(0, 2**64, size=65_000, dtype=np.uint64)
    values = [float(v) for v in bits.view(np.float64) if np.isfinite(v)]
    for start in range(0, len(values), 13):
        chunk = tuple(values[start:start + 13])
        assert codec.json_numbers(chunk) == _json_texts(chunk)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.one_of(finite, st.integers(-2**63, 2**63 - 1), st.booleans()), max_size=16))
def test_number_texts_are_json_s_for_any_floats_ints_and_bools(values):
    assert codec.json_numbers(tuple(values)) == _json_texts(values)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 2**70, -2**64])
def test_number_texts_refuse_what_json_refuses_or_orjson_cannot_write(bad):
    assert codec.json_numbers((0.5, bad, 1e-7)) is None


def test_messages_are_read_to_the_same_values_as_json_reads_them():
    """orjson reads what a replay decodes; every float64 must come back bit for bit, as
    json's reading of the same text does (random bit patterns, written by repr)."""
    bits = np.random.default_rng(7).integers(0, 2**64, size=20_000, dtype=np.uint64)
    values = [float(v) for v in bits.view(np.float64) if np.isfinite(v)]
    values += [5e-324, -0.0, 2.2250738585072011e-308, 1e-5, 9007199254740993.0]
    text = json.dumps({"values": values, "n": [0, -0, 2**63 - 1, -2**63]}).encode()
    read = codec.parse_json(text)
    assert read == json.loads(text)
    assert [v.hex() for v in read["values"]] == [v.hex() for v in values]


@pytest.mark.parametrize("text", [b'[NaN]', b'[1e400]', b'["\\ud800"]',  # orjson refuses
                                  b'{"a": 1, "a": 2}', b'[18446744073709551615, -0]'])
def test_edge_texts_are_read_as_json_reads_them(text):
    assert repr(codec.parse_json(text)) == repr(json.loads(text))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_values_are_refused_like_json(bad):
    part = PartSnapshot("a", "INSPACE", (0.0, bad, 0.0), (0.0, 0.0, 0.0, 1.0),
                        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    record = FrameRecord(TrackerFrame(0, 0, ()), None, (part,))
    with pytest.raises(ValueError):
        codec.derived_messages(record)
    with pytest.raises(ValueError):
        codec.FrameEncoder().derived_messages(record)


def test_an_unchanged_part_reuses_its_text_and_a_changed_one_does_not():
    a = PartSnapshot("a", "STATIC", (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3)
    b = PartSnapshot("b", "INSPACE", (0.5, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3,
                     (0.0,) * 3)
    b2 = PartSnapshot("b", "INSPACE", (0.5, 0.0, 0.9), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3,
                      (0.0,) * 3)
    encoder = codec.FrameEncoder()
    first = FrameRecord(TrackerFrame(0, 10, ()), None, (a, b))
    second = FrameRecord(TrackerFrame(1, 20, ()), None, (a, b2))
    assert changed_indices(second.parts, first.parts) == [1]
    for record in (first, second, first):
        assert encoder.derived_messages(record) == codec.derived_messages(record)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(frame_sequences(values=number))
def test_changed_encoding_writes_the_reference_bytes_and_decodes_back(frames):
    """The ``changed`` encoding: the fast encoder agrees with the reference, and decoding
    each frame onto the last gives every part's snapshot back."""
    encoder = codec.FrameEncoder(codec.PARTS_CHANGED)
    previous, state = None, None
    for record in frames:
        fast = encoder.derived_messages(record)
        assert fast == codec.derived_messages(
            record, parts=codec.PARTS_CHANGED,
            previous_parts=previous.parts if previous else None,
            previous_time_ns=previous.time_ns if previous else None)
        base, parts = codec.decode_parts(fast[0][1], previous=state)
        assert parts == tuple(
            type(p)(p.name, p.mode, *(tuple(float(x) for x in v) for v in
                                      (p.position, p.rotation_xyzw, p.linear_velocity,
                                       p.angular_velocity))) for p in record.parts)
        state = (base, parts)
        previous = record


def test_a_changed_frame_lists_only_what_moved_and_a_new_second_lists_all():
    a = PartSnapshot("a", "STATIC", (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3)
    b = PartSnapshot("b", "INSPACE", (0.5, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3,
                     (0.0,) * 3)
    b2 = PartSnapshot("b", "INSPACE", (0.5, 0.0, 0.9), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3,
                      (0.0,) * 3)
    encoder = codec.FrameEncoder(codec.PARTS_CHANGED)
    import json as _json
    first = _json.loads(encoder.derived_messages(
        FrameRecord(TrackerFrame(0, 0, ()), None, (a, b)))[0][1])
    assert first["complete"] is True and [p["name"] for p in first["parts"]] == ["a", "b"]
    second = _json.loads(encoder.derived_messages(
        FrameRecord(TrackerFrame(1, 16_666_666, ()), None, (a, b2)))[0][1])
    assert second["complete"] is False and [p["name"] for p in second["parts"]] == ["b"]
    new_second = _json.loads(encoder.derived_messages(
        FrameRecord(TrackerFrame(60, 10**9, ()), None, (a, b2)))[0][1])
    assert new_second["complete"] is True and len(new_second["parts"]) == 2


@pytest.mark.parametrize("compiled_branch", [True, False])
@settings(max_examples=100, deadline=None, derandomize=True)
@given(st.lists(st.integers(0, 3), max_size=40), st.lists(st.integers(0, 3), max_size=40))
def test_changed_indices_both_branches_name_the_other_objects(compiled_branch, a, b):
    """Whichever branch a build runs (frames._COMPILED), the same answer: by identity."""
    from vade_replay import frames
    pool = [object() for _ in range(4)]
    new, old = tuple(pool[i] for i in a), tuple(pool[i] for i in b)
    saved = frames._COMPILED
    frames._COMPILED = compiled_branch
    try:
        got = frames.changed_indices(new, old)
    finally:
        frames._COMPILED = saved
    expected = list(range(len(new))) if len(new) != len(old) \
        else [i for i in range(len(new)) if new[i] is not old[i]]
    assert got == expected
    assert frames.changed_indices(new, None) == list(range(len(new)))


@st.composite
def tracker_frames(draw, values=number):
    vec = st.tuples(values, values, values)
    quat = st.tuples(values, values, values, values)
    devices = draw(st.lists(st.tuples(names, st.builds(DeviceSample, vec, quat,
                                                         st.sampled_from([None, True, False]))),
                            max_size=4))
    if draw(st.booleans()):
        devices.sort(key=lambda d: d[0])  # the usual case: sorted, as a stream makes them
    return TrackerFrame(draw(st.integers(0, 10**6)), draw(st.integers(0, 10**13)),
                        tuple(devices))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(tracker_frames())
def test_tracker_messages_are_the_reference_bytes(frame):
    """Sorted or not, repeated names, any numbers: json.dumps' bytes, or its error."""
    try:
        expected = codec.dumps(codec.encode_tracker(frame))
    except ValueError:
        with pytest.raises(ValueError):
            codec.tracker_message(frame)
        return
    assert codec.tracker_message(frame) == expected


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_tracker_messages_refuse_what_json_refuses(bad):
    frame = TrackerFrame(0, 0, (("head", DeviceSample((0.0, bad, 0.0), (0.0, 0.0, 0.0, 1.0))),))
    with pytest.raises(ValueError):
        codec.tracker_message(frame)


_device_numbers = st.one_of(finite, st.sampled_from([math.nan, math.inf, -math.inf, 1e6,
                                                     -1e6, 1000000.0000000001, -0.0]),
                            st.integers(-3, 3), st.booleans())


@st.composite
def _device_docs(draw):
    """Tracker devices as a message holds them: mostly well formed, sometimes not."""
    docs = {}
    for name in draw(st.lists(st.sampled_from(["head", "left_hand", "right_hand", "tool"]),
                              max_size=3, unique=True)):
        doc = {"position": draw(st.lists(_device_numbers, min_size=2, max_size=4)),
               "xyzw": draw(st.lists(_device_numbers, min_size=3, max_size=5)),
               "grip": draw(st.sampled_from([None, True, False, 0, "yes"]))}
        if draw(st.booleans()):
            room = st.floats(-MAX_ABS_POSITION_M, MAX_ABS_POSITION_M)
            doc["position"] = [draw(room) for _ in range(3)]
            doc["xyzw"] = [draw(room) for _ in range(4)]
        docs[name] = doc
    return docs


@settings(max_examples=400, deadline=None, derandomize=True)
@given(_device_docs())
def test_the_fast_device_reading_takes_exactly_what_the_encoder_writes(devices):
    """``_decode_devices_fast`` accepts a frame's devices only if every one has 3 + 4
    floats (not ints or bools) of at most MAX_ABS_POSITION_M (so finite) and a bool or
    null grip, and then reads them as they are; anything else it leaves to the checked
    path (``None``), which names what is wrong."""
    def good(values, n):
        return len(values) == n and all(type(v) is float and abs(v) <= MAX_ABS_POSITION_M
                                        for v in values)
    accepted = all(good(d["position"], 3) and good(d["xyzw"], 4)
                   and d["grip"] in (None, True, False) and type(d["grip"]) is not int
                   for d in devices.values())
    got = codec._decode_devices_fast(devices)
    event("accepted" if accepted else "left to the checked path")
    if not accepted:
        assert got is None
        return
    assert got is not None
    assert [name for name, _ in got] == sorted(devices)
    for name, sample in got:
        assert sample.position == tuple(devices[name]["position"])
        assert sample.rotation_xyzw == tuple(devices[name]["xyzw"])
        assert sample.grip is devices[name]["grip"]
