"""Tracker streams: keyframes resampled at a fixed rate (with seeded noise) or a CSV log.

This runs at record time only. What it yields is recorded, and a replay reads those
recorded values, never this module: the recording is the source of truth.
"""

from __future__ import annotations

import csv
import io
import math
from array import array
from typing import Iterator

import numpy as np

from . import spatial as sp
from .errors import SessionError
from .frames import MAX_ABS_POSITION_M, DeviceSample, TrackerFrame
from .scene import HAND_DEVICES, UNIT_TO_M

# The devices of a session without tools; a session's tools add their names (``devices``).
DEVICES = HAND_DEVICES
TIME_TO_NS = {"s": 10**9, "ms": 10**6, "us": 10**3, "ns": 1}
CSV_COLUMNS = ("time", "device", "x", "y", "z", "q0", "q1", "q2", "q3", "grip")


def frame_time_ns(frame: int, rate_hz: int) -> int:
    """Integer time of a resampled frame: exact, so every run agrees on it."""
    return frame * 10**9 // rate_hz


def _keyframes(device: str, frames: list[dict], factor: float, file: str) -> list[tuple]:
    out = []
    position, rotation, grip = sp.ZERO3, sp.IDENTITY_QUAT, False
    last_t = -1.0
    for i, kf in enumerate(frames):
        where = f"tracker.devices.{device}[{i}]"
        if kf["t"] == last_t:
            raise SessionError("two keyframes at the same time", file=file, field=where)
        if kf["t"] < last_t:
            # Sorting them would hide a typo (1.2 written 0.1) behind a quiet session.
            raise SessionError(f"keyframes out of time order: t = {kf['t']:g} s after "
                               f"t = {last_t:g} s (keyframes are listed in time order)",
                               file=file, field=f"{where}.t")
        last_t = kf["t"]
        if "xyzw" in kf and "euler_deg" in kf:
            # (A researcher's trial: euler_deg added to a template's keyframe was ignored,
            # and the held peg never turned.)
            raise SessionError("both xyzw and euler_deg are given: keep one", file=file,
                               field=where)
        if "position" in kf:
            position = tuple(float(v) * factor for v in kf["position"])
            if any(abs(v) > MAX_ABS_POSITION_M for v in position):
                raise SessionError(f"position is more than {MAX_ABS_POSITION_M:g} m from the "
                                   "origin", file=file, field=f"{where}.position")
        if "xyzw" in kf:
            try:
                rotation = sp.quat_normalize(tuple(float(v) for v in kf["xyzw"]))
            except ValueError as exc:
                raise SessionError(str(exc), file=file, field=f"{where}.xyzw") from None
        elif "euler_deg" in kf:
            rotation = sp.quat_from_euler_deg(*(float(v) for v in kf["euler_deg"]))
        grip = bool(kf.get("grip", grip))
        out.append((float(kf["t"]), position, rotation, grip))
    return out


def _sample(keys: list[tuple], t: float, has_grip: bool) -> DeviceSample:
    if t <= keys[0][0]:
        _, p, q, g = keys[0]
        return DeviceSample(p, q, g if has_grip else None)
    for (t0, p0, q0, g0), (t1, p1, q1, _) in zip(keys, keys[1:]):
        if t < t1:
            a = (t - t0) / (t1 - t0)
            p = (p0[0] + a * (p1[0] - p0[0]), p0[1] + a * (p1[1] - p0[1]),
                 p0[2] + a * (p1[2] - p0[2]))
            return DeviceSample(p, sp.slerp(q0, q1, a), g0 if has_grip else None)
    _, p, q, g = keys[-1]
    return DeviceSample(p, q, g if has_grip else None)


def devices(doc: dict) -> tuple[str, ...]:
    """The devices a session's tracker stream may hold: the head, the hands, its tools."""
    return DEVICES + tuple(tool["name"] for tool in doc.get("tools", []))


def keyframe_frame_count(tracker: dict) -> int:
    """How many frames ``from_keyframes`` makes of a tracker block: one every 1/rate_hz s
    from 0 to duration_s."""
    rate = int(tracker.get("rate_hz", 60))
    return int(math.floor(float(tracker["duration_s"]) * rate + 1e-9)) + 1


def from_keyframes(tracker: dict, units: str, *, file: str,
                   known: tuple[str, ...] = DEVICES) -> Iterator[TrackerFrame]:
    """Resample keyframes (linear position, slerp rotation, held grip) at ``rate_hz``."""
    for name in sorted(tracker["devices"]):
        if name not in known:
            raise SessionError(f"unknown device {name!r} (use {', '.join(known)}, or declare "
                               "a tool of that name under tools)", file=file,
                               field=f"tracker.devices.{name}")
    factor = UNIT_TO_M[units]
    rate = int(tracker.get("rate_hz", 60))
    count = keyframe_frame_count(tracker)
    devices = {name: _keyframes(name, frames, factor, file)
               for name, frames in sorted(tracker["devices"].items())}
    noise = tracker.get("noise")
    rng = np.random.default_rng(noise["seed"]) if noise else None
    pos_std = float(noise.get("position_std", 0.0)) * factor if noise else 0.0
    rot_std = math.radians(float(noise.get("rotation_std_deg", 0.0))) if noise else 0.0
    for n in range(count):
        t_ns = frame_time_ns(n, rate)
        samples = []
        for name, keys in devices.items():
            sample = _sample(keys, t_ns * 1e-9, name != "head")
            if rng is not None:
                dp = rng.normal(0.0, 1.0, 3) * pos_std
                dr = rng.normal(0.0, 1.0, 3) * rot_std
                position = (sample.position[0] + float(dp[0]), sample.position[1] + float(dp[1]),
                            sample.position[2] + float(dp[2]))
                rotation = sp.quat_normalize(sp.quat_mul(
                    sp.quat_from_rotvec((float(dr[0]), float(dr[1]), float(dr[2]))),
                    sample.rotation_xyzw))
                sample = DeviceSample(position, rotation, sample.grip)
            samples.append((name, sample))
        yield TrackerFrame(n, t_ns, tuple(samples))


def _parse_time_ns(text: str, unit: str) -> int:
    if unit == "ns":
        return int(text)
    return round(float(text) * TIME_TO_NS[unit])


def _csv_row(row: list[str], col: dict[str, int], line_no: int, *, file: str, factor: float,
             time_unit: str, quaternion_order: str, known: tuple[str, ...],
             width: int) -> tuple[int, str, DeviceSample]:
    """One row of a tracker log: time, device and its sample; a bad row names its line."""
    where = f"line {line_no}"
    if len(row) < len(col) or len(row) <= max(col.values()) \
            or (len(row) > width and any(cell.strip() for cell in row[width:])):
        # (More values than the header names, a user's trial: a column inserted in the rows
        # and not the header was read shifted, without a word. Empty ones past it, as a
        # trailing comma leaves, are nothing.)
        raise SessionError(f"{len(row)} values where the header has {width} columns",
                           file=file, field=where)
    column = "time"
    try:
        t_ns = _parse_time_ns(row[col["time"]].strip(), time_unit)
        device = row[col["device"]].strip()
        values = []
        for column in ("x", "y", "z", "q0", "q1", "q2", "q3"):
            values.append(float(row[col[column]]))
        position = (values[0] * factor, values[1] * factor, values[2] * factor)
        q = values[3:]
        grip_text = row[col["grip"]].strip().lower()
    except (ValueError, IndexError, OverflowError) as exc:
        # (Naming the column: an engineer's trial read "could not convert string to
        # float: ''" of an empty cell, and looked for it.)
        text = row[col[column]].strip() if col[column] < len(row) else ""
        what = "empty" if not text else repr(text)
        raise SessionError(f"unreadable row: {column} is {what}, not a number ({exc})",
                           file=file, field=f"{where}: {column}") from None
    if not 0 <= t_ns < 2**63:
        raise SessionError("time must be at least 0 and below 2^63 ns (292 years)", file=file,
                           field=f"{where}: time")
    if device not in known:
        raise SessionError(f"unknown device {device!r} (use {', '.join(known)}, or declare "
                           "a tool of that name under tools)", file=file,
                           field=f"{where}: device")
    for name, v in zip(("x", "y", "z", "q0", "q1", "q2", "q3"), (*position, *q)):
        if not math.isfinite(v):
            raise SessionError(f"non-finite number ({row[col[name]].strip()})", file=file,
                               field=f"{where}: {name}")
    if any(abs(v) > MAX_ABS_POSITION_M for v in position):
        raise SessionError(f"position is more than {MAX_ABS_POSITION_M:g} m from the origin",
                           file=file, field=f"{where}: x, y, z")
    xyzw = (q[0], q[1], q[2], q[3]) if quaternion_order == "xyzw" else (q[1], q[2], q[3], q[0])
    try:
        rotation = sp.quat_normalize(xyzw)
    except ValueError:
        raise SessionError("zero quaternion", file=file, field=f"{where}: q0..q3") from None
    if grip_text in ("", "none"):
        grip = None
    elif grip_text in ("1", "true", "yes"):
        grip = True
    elif grip_text in ("0", "false", "no"):
        grip = False
    else:
        raise SessionError(f"grip must be 0/1, true/false or yes/no (or empty: unknown), got "
                           f"{grip_text!r}", file=file,
                           field=f"{where}: grip")
    return t_ns, device, DeviceSample(position, rotation, grip if device != "head" else None)


CSV_BETWEEN = ("interpolate", "hold")


def from_csv(data: bytes, *, file: str, units: str, time_unit: str,
             quaternion_order: str, known: tuple[str, ...] = DEVICES,
             between: str = "interpolate") -> Iterator[TrackerFrame]:
    """Frames from a tracker log: one row per device sample, rows in time order.

    Rows with the same time form one frame; a device seen twice at the same time starts a
    new frame with that time (a duplicated sample). A device not sampled at a frame's time
    is, with ``between`` interpolate (the default), where its own samples before and after
    put it then (position linear, rotation slerp, the grip of the one before, as keyframes
    are resampled); after its last sample, and with ``between`` hold, it keeps its last
    sample. (A researcher's trial: a headset at 90 Hz and a controller at 120 Hz, or both
    at 90 Hz 5.5 ms apart, as real logs are, held the hand still in the headset's frames
    and moved it in steps: the held part's velocity swung between 0.57 and 1.36 m/s for a
    hand at 1.0 m/s, and its release velocity was 16-28 % off.) The whole log is read and
    checked before the first frame: a bad row is an error naming its line, and nothing is
    yielded. Kept as compact arrays, ~70 bytes a row.
    """
    if between not in CSV_BETWEEN:
        raise SessionError(f"must be one of {', '.join(CSV_BETWEEN)}", file=file,
                           field="tracker.csv_between")
    factor = UNIT_TO_M[units]
    text = data.decode("utf-8-sig", errors="replace")
    reader = csv.reader(io.StringIO(text))
    try:
        header = [h.strip().lower() for h in next(reader)]
    except StopIteration:
        raise SessionError("tracker log is empty", file=file) from None
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise SessionError(f"the header lacks {', '.join(missing)} (it reads "
                           f"{','.join(header)}; a log's header is {','.join(CSV_COLUMNS)}, "
                           "in any order)", file=file, field="header")
    col = {name: header.index(name) for name in CSV_COLUMNS}
    names = sorted(known)
    index = {name: i for i, name in enumerate(names)}
    times, devs, values, grips = array("q"), array("h"), array("d"), array("b")
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        t_ns, device, sample = _csv_row(row, col, line_no, file=file, factor=factor,
                                        time_unit=time_unit,
                                        quaternion_order=quaternion_order, known=known,
                                        width=len(header))
        if times and t_ns < times[-1]:
            # A log written a device at a time (every head row, then every hand row: a
            # researcher's trial) restarts its time at a device's first row.
            grouped = "" if index[device] in devs else (
                f": {device}'s first row goes back to an earlier time than the row before; "
                "is the log grouped by device? Rows are in time order, the devices' rows "
                "interleaved (sort it by time)")
            raise SessionError("time goes backwards" + grouped, file=file,
                               field=f"line {line_no}: time")
        times.append(t_ns)
        devs.append(index[device])
        values.extend(sample.position)
        values.extend(sample.rotation_xyzw)
        grips.append(-1 if sample.grip is None else int(sample.grip))
    count = len(times)
    if count == 0:
        raise SessionError("tracker log has no samples", file=file)
    # Each row's device's next row (-1: none), for the interpolation.
    following = array("q", [-1]) * count
    seen: dict[int, int] = {}
    for i in range(count - 1, -1, -1):
        following[i] = seen.get(devs[i], -1)
        seen[devs[i]] = i

    def own(i: int) -> DeviceSample:
        v = values[7 * i:7 * i + 7]
        g = grips[i]
        return DeviceSample((v[0], v[1], v[2]), (v[3], v[4], v[5], v[6]),
                            None if g < 0 else bool(g))

    latest: dict[int, tuple[int, DeviceSample]] = {}  # device -> its row and sample so far
    frame, i = 0, 0
    while i < count:
        t_ns, fresh = times[i], set()
        while i < count and times[i] == t_ns and devs[i] not in fresh:
            fresh.add(devs[i])
            latest[devs[i]] = (i, own(i))
            i += 1
        samples = []
        for d, (row, sample) in latest.items():
            if d not in fresh and between == "interpolate" and times[row] < t_ns \
                    and following[row] >= 0:
                nxt = following[row]
                a = (t_ns - times[row]) / (times[nxt] - times[row])
                p0, q0 = sample.position, sample.rotation_xyzw
                v = values[7 * nxt:7 * nxt + 7]
                sample = DeviceSample(
                    (p0[0] + a * (v[0] - p0[0]), p0[1] + a * (v[1] - p0[1]),
                     p0[2] + a * (v[2] - p0[2])),
                    sp.slerp(q0, (v[3], v[4], v[5], v[6]), a), sample.grip)
            samples.append((names[d], sample))
        yield TrackerFrame(frame, t_ns, tuple(sorted(samples)))
        frame += 1
