"""Record a session, and replay a recording from its inputs alone, checking every message.

``simulate`` is the fold of ``step`` over a stream of tracker frames. ``record`` runs it on
a session's tracker stream and writes the MCAP file; ``replay`` runs it on a recording's
recorded inputs, checks that each derived message holds what it derived (every key, string
and integer, and every number the same float64 bit for bit: ``codec.FrameEncoder.matches``)
and, at the first difference, walks the two messages to name the frame, channel, part,
field and both values.
"""

from __future__ import annotations

import contextlib
import copy
import difflib
import itertools
import json
import math
import operator
import re
import shlex
import signal
import sys
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterable, Iterator, TypeVar

import numpy as np

from . import codec, native
from . import constraints as cn
from . import spatial as sp
from .analysis import SessionAnalysis, compare
from .arrays import closed as _closed, dots, norms, posed_points, winding
from .collision import SKIP_COAXIAL, SKIP_COPLANAR, CollisionWorld
from .dynamics import onbase
from .errors import (ConfigError, RecordingError, SessionError, Terminated, VadeError,
                     raise_terminated)
from .frames import FrameRecord, TrackerFrame
from .modes import Cause, Mode
from .recording import (RecordedFrame, Recording, RecordingWriter, holds_recording, in_place,
                        left_partial, package_versions, partial_output, physics_metadata)
from .scene import (LENGTH_FIELDS, PAPER_DEFAULTS, UNIT_TO_M, Scene, even_inertia_trace,
                    oversize_across, physics_from_doc)
from .session import (_DENSITY_RANGE, Session, load_schema, name_warnings, parse, strict_json,
                      validate_physics)
from .spatial import Pose
from .step import Stepper, beyond_end, world_box

T = TypeVar("T")


def simulate(scene: Scene, frames: Iterable[TrackerFrame], *,
             collision: CollisionWorld | None = None) -> Iterator[FrameRecord]:
    """Fold ``step`` over tracker frames, yielding what each frame derived."""
    advance = Stepper(scene, collision or CollisionWorld(scene))
    for inputs in frames:
        yield advance(inputs)


# Frames a run takes, then steps, then checks or writes, before the next ones: each stage's
# code and data stay in the caches over the batch instead of the stages taking turns every
# frame. On a 2-core AMD EPYC (Zen 3, 512 KiB of L2 a core) a replay of the ten-minute
# session went from ~60-75 to ~40-60 us a frame, a recording's ~17 % faster; batches of 16
# to 120 frames measured alike, 1 and 480 the slowest (docs/DEVELOPMENT.md). 60 frames are
# a recording's chunk, one simulated second.
_BATCH_FRAMES = 60
_INPUTS = operator.attrgetter("inputs")  # a recorded frame's tracker frame


def _stepped(items: Iterator[T], advance: Stepper,
             inputs: Callable[[T], TrackerFrame] | None = None
             ) -> Iterator[tuple[list[T], list[FrameRecord]]]:
    """``items`` (tracker frames, or what ``inputs`` takes them from) ``_BATCH_FRAMES`` at a
    time, each batch with what its frames step to. What stops the reading or the stepping
    early (a damaged frame, an error stepping, an interrupt) is raised once the caller has
    done with the frames before it, as a run a frame at a time would have; a frame before
    the damaged one failing to step raises its own error."""
    while True:
        batch: list[T] = []
        stopped: BaseException | None = None
        try:
            for item in items:
                batch.append(item)
                if len(batch) == _BATCH_FRAMES:
                    break
        except BaseException as exc:
            stopped = exc
        stepped: list[FrameRecord] = []
        try:
            for item in batch:
                stepped.append(advance(item if inputs is None else inputs(item)))
        except BaseException as exc:
            stopped = exc
        yield batch, stepped
        if stopped is not None:
            raise stopped
        if len(batch) < _BATCH_FRAMES:
            return


class FrameBoundaryInterrupts:
    """Ctrl-C (SIGINT) while a recording is written, held off to the end of the frame being
    written: ``check`` raises ``KeyboardInterrupt`` there, so the file is closed after a
    whole frame and its partial file replays. Raised at once wherever it came, the frame
    being written was cut part way (a tracker message without its /parts, or a message
    record half in its chunk): the partial file then diverged at its last frame, or could
    not be read, and its count of frames was one off (a user's trial). A second Ctrl-C
    before the frame ends is raised at once. Only in the main thread, and only where
    SIGINT has Python's own handler (an embedding program's is left alone)."""

    def __init__(self) -> None:
        # The interrupt held off (KeyboardInterrupt, or Terminated for SIGTERM), or None.
        self.pending: type[KeyboardInterrupt] | None = None
        self._previous: dict[int, object] = {}

    def __enter__(self) -> "FrameBoundaryInterrupts":
        if threading.current_thread() is threading.main_thread():
            # SIGTERM too where a command takes it as Ctrl-C (``errors.raise_terminated``).
            for signum, ours in ((signal.SIGINT, signal.default_int_handler),
                                 (signal.SIGTERM, raise_terminated)):
                if signal.getsignal(signum) is ours:
                    self._previous[signum] = signal.signal(signum, self._held)
        return self

    def _held(self, signum, frame) -> None:
        kind = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
        if self.pending:
            raise kind  # asked twice: at once
        self.pending = kind

    def check(self) -> None:
        """At the end of a frame: the interrupt held off, if one came."""
        if self.pending:
            kind, self.pending = self.pending, None
            raise kind

    def __exit__(self, *exc) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)  # type: ignore[arg-type]
        self._previous = {}


@dataclass
class Divergence:
    """The first place where a replay differs from its recording."""

    frame: int
    time_ns: int
    channel: str
    part: str | None
    field: str
    recorded: object
    replayed: object

    def describe(self) -> str:
        where = f"part {self.part}, " if self.part else ""
        return (f"first divergence at frame {self.frame} (t = {self.time_ns * 1e-9:.6f} s), "
                f"channel {self.channel}, {where}field {self.field}: recorded {self.recorded!r}, "
                f"replayed {self.replayed!r}")


@dataclass
class RunSummary:
    """What a record or replay did; printed by ``--json``."""

    session: str
    frames: int = 0
    duration_s: float = 0.0
    parts: list[str] = field(default_factory=list)
    transitions: int = 0
    transitions_by_edge: dict[str, int] = field(default_factory=dict)
    events: int = 0
    messages_checked: int = 0
    match: bool | None = None
    first_divergence: dict | None = None
    # A what-if's first frame whose events differ from the recording's (where the change
    # shows in what happened: the first divergence may be a held part's velocity in its
    # last bits).
    first_event_change: dict | None = None
    overrides: dict = field(default_factory=dict)
    # A study's what-if keys this session could not take (a part or tool it does not
    # have): key -> why. Its other keys were applied; with none, it is a plain replay.
    not_applied: dict = field(default_factory=dict)
    counters: dict = field(default_factory=dict)
    # Physics this run used that differs from what the recording was made with, other than
    # the what-if's own changes: a default changed since (name -> recorded, now).
    physics_changed: dict = field(default_factory=dict)
    truncated: bool = False
    stopped: str | None = None  # why the recording's run ended before its end, if it did
    recorded_warnings: list[str] = field(default_factory=list)  # what vade-record warned of
    # What the session allows but is most likely a slip (``Session.warnings``): of the
    # session recorded, or of a what-if's changed one.
    warnings: list[str] = field(default_factory=list)
    # Releases of a part with constraints that did not go onto one: how far off the nearest
    # was (``release_misses``), for "why did it not snap?".
    release_misses: list[dict] = field(default_factory=list)
    # The session's length unit: what a what-if's lengths (``overrides``) are in.
    units: str = "m"
    # A replay as recorded (``as_made``): the physics defaults restored, name -> value
    # (SI); None for a replay with this version's defaults.
    as_recorded: dict | None = None
    # Each part's mass as the run had it (from its mesh and density, or its
    # mass_properties): a mesh in the wrong unit or a density in g/cm^3 shows here.
    masses_kg: dict[str, float] = field(default_factory=dict)
    # Each part's centre of mass in its own frame (m): ``--poses`` gives the part frame's
    # origin and the centre of mass's velocities (a researcher's trial differentiated the
    # one and compared it with the other), so the point itself is here.
    centers_of_mass_m: dict[str, list[float]] = field(default_factory=dict)
    # How far the run's parts went from the recording's (``Departure``): part -> the largest
    # distance between the two runs' positions (m) and angle between their orientations
    # (rad), each with its frame. Measured in a what-if, and in a replay from its first
    # divergence on; ``{}`` for a replay that matched (nothing departed); ``None`` where
    # the recording's frames could not be read to measure it.
    largest_departure: dict | None = None
    # A replay held to a tolerance (``Tolerance``, ``--tolerance``), as another machine's
    # is: the tolerance, whether the run stayed within it (a bit-for-bit match does), and
    # why not where it did not. None, None, None where none was asked for.
    tolerance: dict | None = None
    within_tolerance: bool | None = None
    beyond_tolerance: str | None = None
    # Where the recording was made otherwise than this run, in what decides round-off
    # (``made_elsewhere``): name -> {"recorded", "here"}; {} where the same or not known.
    made_elsewhere: dict = field(default_factory=dict)
    # A recording a what-if wrote (``vade-replay --set ... -o``): the recording it changed
    # and its changes (``made_by_what_if``); None for one ``vade-record`` made.
    made_by_what_if: dict | None = None
    # Which build ran the frames (native.describe): compiled or the Python sources. Both
    # give the same bits; it says where to look when two machines disagree.
    build: str = field(default_factory=native.describe)
    analysis: SessionAnalysis = field(default_factory=SessionAnalysis)
    # A what-if's: the recording's own analysis, and how the changed run's differs from it
    # (``analysis.compare``). None for a plain replay, whose analysis is the recording's.
    recorded_analysis: SessionAnalysis | None = None

    def to_dict(self) -> dict:
        """JSON-ready: what ``--json`` prints."""
        out = {k: v for k, v in self.__dict__.items()
               if k not in ("analysis", "recorded_analysis")}
        out["analysis"] = self.analysis.result()
        if self.recorded_analysis is not None:
            out["recorded_analysis"] = self.recorded_analysis.result()
            out["analysis_changes"] = compare(out["recorded_analysis"], out["analysis"])
        return out

    def count(self, record: FrameRecord, first_time_ns: int) -> None:
        self.analysis.add(record)
        self.frames += 1
        self.duration_s = (record.time_ns - first_time_ns) / 1e9
        for event in record.events:
            self.events += 1
            if event.kind == "ModeChanged":
                self.transitions += 1
                edge = f"{event.from_mode}->{event.to_mode}"
                self.transitions_by_edge[edge] = self.transitions_by_edge.get(edge, 0) + 1

    def counted(self, frames: int, last: FrameRecord, first_time_ns: int,
                messages: int) -> None:
        """``frames`` frames without events, the last ``last``, that ``codec.checked_run``
        checked (``messages`` messages) and gave to the analysis: ``count`` for each."""
        self.frames += frames
        self.duration_s = (last.time_ns - first_time_ns) / 1e9
        self.messages_checked += messages


# The analysis as a table (``vade-replay --csv``): one row per recording and part, the
# columns a user study tabulates across sessions.
# New counts go last, so that a reader of an older table's columns by position still works.
PART_COUNTS = ("grabs", "catches", "releases", "drops", "slid_off", "lifted_off", "blocked",
               "refused_grabs", "two_hand_grabs", "tool_grabs")
ANALYSIS_COLUMNS = ("recording", "session", "match", "first_divergence_frame", "frames",
                    "duration_s", "part", *PART_COUNTS, "placed_at_s",
                    *(f"s_{mode.value}" for mode in Mode), "session_refused_grabs", "error",
                    "overrides", "truncated", "release_misses", "units", "mass_kg",
                    "as_recorded", "first_event_change_frame", "not_applied",
                    "release_misses_landed", "departure_m", "departure_rad",
                    "within_tolerance", "made_with_overrides", "made_from")


# The run frame by frame as tables (``vade-replay --events``, ``--poses``), for a study's own
# plots and statistics: times in seconds from the first frame, SI units, floats as repr.
EVENT_COLUMNS = ("recording", "frame", "time_s", "kind", "part", "cause", "hand", "from_mode",
                 "to_mode", "other", "contact_time_s", "vx", "vy", "vz", "wx", "wy", "wz")
POSE_COLUMNS = ("recording", "frame", "time_s", "part", "mode", "x", "y", "z", "qx", "qy",
                "qz", "qw", "vx", "vy", "vz", "wx", "wy", "wz")
# A tracker log as a session's ``tracker.csv`` reads it (``csv_units`` m, ``csv_time_unit``
# ns, ``csv_quaternion_order`` xyzw; the first two columns are left aside): the recorded
# inputs, to run the same hand motion through another session (a changed design).
TRACKER_COLUMNS = ("recording", "frame", "time", "device", "x", "y", "z", "q0", "q1", "q2",
                   "q3", "grip")


class Departure:
    """How far a run's parts go from a recording's, frame by frame: for each part the
    largest distance between the two positions (the parts' reference points, m) and the
    largest angle between the two orientations (rad), each with the frame it was reached
    in. What a what-if's first divergence cannot say: whether the change is round-off
    (1e-13 m) or a part somewhere else."""

    def __init__(self) -> None:
        self.parts: dict[str, dict] = {}

    def add(self, recorded: FrameRecord, replayed: FrameRecord) -> None:
        theirs = {s.name: s for s in recorded.parts}
        for ours in replayed.parts:
            was = theirs.get(ours.name)
            if was is None:
                continue
            far = self.parts.setdefault(ours.name, {"distance_m": 0.0, "distance_frame": None,
                                                    "angle_rad": 0.0, "angle_frame": None})
            distance = math.dist(was.position, ours.position)
            if distance > far["distance_m"]:
                far["distance_m"], far["distance_frame"] = distance, replayed.frame
            angle = sp.quat_angle_between(was.rotation_xyzw, ours.rotation_xyzw)
            if angle > far["angle_rad"]:
                far["angle_rad"], far["angle_frame"] = angle, replayed.frame

    def result(self) -> dict:
        return {name: dict(far) for name, far in sorted(self.parts.items())}


@dataclass(frozen=True)
class Tolerance:
    """How near a replay that is not the recording bit for bit may come and still be the
    same session: another machine's round-off (``--tolerance``; the determinism contract:
    the same transitions, poses within a stated tolerance). Within it, every frame's
    messages are the recording's, field by field, but for the numbers of motion: each
    position within ``distance_m`` (a /parts position, a transform's translation), each
    orientation within ``angle_rad`` (the angle between the two), each linear and angular
    velocity within those per second, and a contact's instant within ``distance_m``'s
    metres as seconds (at 1 m/s, at least 1 ns). Names, modes, causes, hands, the parts
    listed, frame numbers and times are the recording's exactly (``frame_beyond``)."""

    distance_m: float = 1e-9
    angle_rad: float = 1e-9


WHAT_IF_TOLERANCE = ("a what-if (--set) departs from its recording on purpose: --tolerance "
                     "is for checking a replay as it was recorded")

_ANGLE_UNITS = {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "µrad": 1e-6, "deg": math.pi / 180.0}


def parse_tolerance(text: str, *, field: str = "--tolerance") -> Tolerance:
    """``1e-9`` (metres), ``1um`` or ``0.001mm``: positions within that, orientations within
    the angle that moves a point 1 m away by as much (1 um: 1e-6 rad); ``1um,1e-5rad`` or
    ``0.01mm,0.001deg``: each its own (an angle without a unit is in radians)."""
    pieces = text.split(",")
    if len(pieces) > 2 or any(not piece.strip() for piece in pieces):
        raise ConfigError(f"{text!r}: give a distance D, or D,A (a distance and an angle)",
                          field=field)

    def amount(piece: str, units: dict[str, float], default: str) -> float:
        value = _with_unit(piece, units, default, field=field)
        if not (math.isfinite(value) and value >= 0.0):
            raise ConfigError(f"{piece.strip()!r}: a tolerance is a finite number, 0 or more",
                              field=field)
        return value
    distance_m = amount(pieces[0], _LENGTH_UNITS, "m")
    # A point 1 m from a part's reference point turned by angle_rad moves angle_rad metres.
    angle_rad = amount(pieces[1], _ANGLE_UNITS, "rad") if len(pieces) == 2 else distance_m
    return Tolerance(distance_m, angle_rad)


def _vector(value) -> tuple[float, ...] | None:
    """A message's vector (a list, or a transform's ``{"x", "y", "z"[, "w"]}``) as floats;
    None if it is not one."""
    if isinstance(value, dict):
        keys = ("x", "y", "z", "w") if len(value) == 4 else ("x", "y", "z")
        if set(value) != set(keys):
            return None
        value = [value[k] for k in keys]
    if not isinstance(value, list) or not all(type(v) in (int, float) for v in value):
        return None
    try:
        return tuple(float(v) for v in value)
    except OverflowError:  # an integer past float64's range (json reads it so)
        return None


def _limit_text(value: float, limit: float, unit: str) -> str:
    shown = f"{value:.3g}"
    if shown == f"{limit:.3g}":  # past the limit, if only in a digit .3g does not show
        shown = repr(value)
    return f"is {shown} {unit} from the recording's (tolerance {limit:.3g} {unit})"


def _motion_beyond(key: str, recorded, ours, tolerance: Tolerance, event: bool) -> str | None:
    """Why a number of motion (``key``: position, orientation, velocity, a contact's
    instant) is past the tolerance, or None; "" where ``key`` is no such number."""
    if key == "time_ns" and event:
        if type(recorded) is not int or type(ours) is not int:
            return f"recorded {recorded!r}, replayed {ours!r}"
        limit = max(1.0, tolerance.distance_m * 1e9)  # D's metres as seconds at 1 m/s
        return None if abs(recorded - ours) <= limit else \
            f"is {ours - recorded:+d} ns from the recording's (tolerance {limit:.3g} ns)"
    kinds = {"position": ("m", tolerance.distance_m), "translation": ("m", tolerance.distance_m),
             "linear_velocity": ("m/s", tolerance.distance_m),
             "angular_velocity": ("rad/s", tolerance.angle_rad),
             "xyzw": ("rad", tolerance.angle_rad), "rotation": ("rad", tolerance.angle_rad)}
    if key not in kinds:
        return ""
    unit, limit = kinds[key]
    a, b = _vector(recorded), _vector(ours)
    size = 4 if unit == "rad" else 3
    # (Of the message's own shape: a list where it writes a list, an object for an object.)
    if a is None or b is None or len(a) != size or len(b) != size \
            or type(recorded) is not type(ours):
        return f"recorded {recorded!r}, replayed {ours!r}"
    if unit == "rad":
        # The angle between two unit quaternions' rotations, 4 asin(|a - b| / 2) for the
        # nearer of b and -b (the same rotation); of any other pair (scaled, zero) the same
        # formula's, which is then no angle but past the limit for what is no rotation.
        gap = min(math.dist(a, b), math.dist(a, tuple(-x for x in b)))
        far = 4.0 * math.asin(min(1.0, 0.5 * gap)) if gap == gap else math.nan
    else:
        far = math.dist(a, b)
    # (A NaN is past any limit: ``not far <= limit``.)
    return None if far <= limit else _limit_text(far, limit, unit)


def _value_beyond(recorded, ours, tolerance: Tolerance, event: bool, where: str) -> str | None:
    """Why a parsed message (or a part of it, at ``where``) is not within ``tolerance`` of
    the replay's, or None."""
    if isinstance(recorded, dict) and isinstance(ours, dict):
        # (In any order, as the check by value reads another writer's text.)
        if recorded.keys() != ours.keys():
            return f"{where or 'the message'} has fields {sorted(recorded)} in the " \
                   f"recording, {sorted(ours)} in the replay"
        for key, value in recorded.items():
            here = f"{where}.{key}" if where else key
            why = _motion_beyond(key, value, ours[key], tolerance, event)
            if why == "":
                why = _value_beyond(value, ours[key], tolerance, event, here)
            elif why is not None:
                why = f"{here} {why}" if why.startswith("is ") else f"{here}: {why}"
            if why:
                return why
        return None
    if isinstance(recorded, list) and isinstance(ours, list):
        if len(recorded) != len(ours):
            return f"{where} lists {len(recorded)} in the recording, {len(ours)} in the replay"
        for i, (a, b) in enumerate(zip(recorded, ours)):
            name = a.get("name", a.get("child_frame_id")) if isinstance(a, dict) else None
            why = _value_beyond(a, b, tolerance, event,
                                f"{where}[{name if isinstance(name, str) else i}]")
            if why:
                return why
        return None
    if type(recorded) is type(ours) and recorded == ours \
            and (type(recorded) is not float or math.copysign(1.0, recorded)
                 == math.copysign(1.0, ours)):
        return None
    return f"{where}: recorded {recorded!r}, replayed {ours!r}"


def frame_beyond(recorded: list[tuple[str, bytes]], ours: list[tuple[str, bytes]],
                 tolerance: Tolerance) -> str | None:
    """Why a frame's recorded messages are not within ``tolerance`` of the replay's
    (``Tolerance``), or None: the same messages, field by field, but for the numbers of
    motion, each within its limit."""
    def names(messages) -> str:
        return ", ".join(t[len(codec.EVENT_TOPIC_PREFIX):] if t.startswith(
            codec.EVENT_TOPIC_PREFIX) else t for t, _ in messages) or "none"
    if [t for t, _ in recorded] != [t for t, _ in ours]:
        return f"the recording has messages {names(recorded)}; the replay {names(ours)}"
    for (topic, theirs), (_, mine) in zip(recorded, ours):
        if theirs == mine:
            continue
        try:
            a = codec.parse_json(theirs)
        except ValueError:
            return f"its {topic} message cannot be read"
        why = _value_beyond(a, codec.parse_json(mine), tolerance,
                            topic.startswith(codec.EVENT_TOPIC_PREFIX), "")
        if why:
            return f"{topic} {why}"
    return None


def describe_departure(largest: dict) -> str:
    """``sleeve 3.2e-14 m (frame 90), 1.1e-13 rad (frame 91); peg none``: each part's
    largest departure from the recording."""
    items = []
    for name, far in largest.items():
        if not far["distance_m"] and not far["angle_rad"]:
            items.append(f"{name} none")
            continue
        parts = []
        if far["distance_m"]:
            parts.append(f"{far['distance_m']:.3g} m (frame {far['distance_frame']})")
        if far["angle_rad"]:
            parts.append(f"{far['angle_rad']:.3g} rad (frame {far['angle_frame']})")
        items.append(f"{name} " + ", ".join(parts))
    return "; ".join(items) if items else "none"


def event_rows(recording: str, record: FrameRecord, first_time_ns: int) -> list[dict]:
    """A row of ``EVENT_COLUMNS`` for each of a frame's events, in their order; a column an
    event does not have is empty."""
    rows = []
    for event in record.events:
        row = {"recording": recording, "frame": record.frame,
               "time_s": (record.time_ns - first_time_ns) / 1e9, "kind": event.kind,
               "part": event.part, "cause": event.cause}
        for name in ("hand", "from_mode", "to_mode", "other"):
            if hasattr(event, name):
                row[name] = getattr(event, name)
        if hasattr(event, "time_ns"):
            row["contact_time_s"] = (getattr(event, "time_ns") - first_time_ns) / 1e9
        if hasattr(event, "linear_velocity"):
            v, w = getattr(event, "linear_velocity"), getattr(event, "angular_velocity")
            row.update(vx=v[0], vy=v[1], vz=v[2], wx=w[0], wy=w[1], wz=w[2])
        rows.append(row)
    return rows


def pose_rows(recording: str, record: FrameRecord, first_time_ns: int) -> list[dict]:
    """A row of ``POSE_COLUMNS`` for the base (if any) and every part, after a frame."""
    time_s = (record.time_ns - first_time_ns) / 1e9
    snapshots = record.parts if record.base is None else (record.base, *record.parts)
    rows = []
    for s in snapshots:
        p, q, v, w = s.position, s.rotation_xyzw, s.linear_velocity, s.angular_velocity
        rows.append({"recording": recording, "frame": record.frame, "time_s": time_s,
                     "part": s.name, "mode": s.mode, "x": p[0], "y": p[1], "z": p[2],
                     "qx": q[0], "qy": q[1], "qz": q[2], "qw": q[3], "vx": v[0], "vy": v[1],
                     "vz": v[2], "wx": w[0], "wy": w[1], "wz": w[2]})
    return rows


def tracker_rows(recording: str, record: FrameRecord, first_time_ns: int) -> list[dict]:
    """A row of ``TRACKER_COLUMNS`` for each device sampled in the frame: its time in ns
    and its numbers as Python writes them (``repr``, read back to the same bits)."""
    rows = []
    for device, sample in record.inputs.devices:
        p, q = sample.position, sample.rotation_xyzw
        rows.append({"recording": recording, "frame": record.frame, "time": record.time_ns,
                     "device": device, "x": p[0], "y": p[1], "z": p[2], "q0": q[0],
                     "q1": q[1], "q2": q[2], "q3": q[3],
                     "grip": "" if sample.grip is None else int(sample.grip)})
    return rows


def analysis_rows(recording: str, summary: dict) -> list[dict]:
    """Rows of ``ANALYSIS_COLUMNS`` from a summary as ``RunSummary.to_dict`` gives it: the
    seconds in each state (0 for a state the part was never in), the counts, and the
    session's refused grabs (every cause; the same on each of its parts' rows: a refusal
    need not be of any one part). ``error`` is empty."""
    divergence = summary.get("first_divergence")
    analysis = summary["analysis"]
    session = {"recording": recording, "session": summary["session"],
               "match": summary["match"],
               "first_divergence_frame": divergence["frame"] if divergence else "",
               "frames": summary["frames"], "duration_s": summary["duration_s"],
               "session_refused_grabs": sum(analysis["refused_grabs"].values()), "error": "",
               # A what-if's changes (empty for a plain replay), so its rows stand apart.
               "overrides": "; ".join(f"{key}={_as_text(value)}" for key, value
                                      in sorted((summary.get("overrides") or {}).items())),
               # Replayed with the physics defaults it was made with (--as-recorded): those
               # restored (``none changed`` where none had), so its rows stand apart too.
               "as_recorded": "" if summary.get("as_recorded") is None else (
                   "; ".join(f"{key}={_as_text(value)}" for key, value
                             in sorted(summary["as_recorded"].items())) or "none changed"),
               # A study's what-if keys this session lacks the part or tool of.
               "not_applied": "; ".join(sorted(summary.get("not_applied") or {})),
               # A what-if's first frame whose events differ from the recording's.
               "first_event_change_frame": (summary.get("first_event_change") or {}).get(
                   "frame", ""),
               # Held to --tolerance: whether within it (empty where none was asked).
               "within_tolerance": "" if summary.get("within_tolerance") is None
               else summary["within_tolerance"],
               # A recording a what-if wrote (``-o``): its changes and the recording it
               # changed, so that its rows stand apart from the original run's.
               "made_with_overrides": "; ".join(
                   f"{key}={_as_text(value)}" for key, value in sorted(
                       ((summary.get("made_by_what_if") or {}).get("overrides") or {}).items())),
               "made_from": (summary.get("made_by_what_if") or {}).get("from", ""),
               # Cut short (a crash while recording): the frames it held, not the session.
               "truncated": bool(summary.get("truncated")),
               # The session's length unit, which a what-if's lengths are in (a study may
               # mix sessions in mm and in m).
               "units": summary.get("units", "m")}
    rows = []
    for name, stats in sorted(analysis["parts"].items()):
        times = stats["time_in_state_s"]
        row = {**session, "part": name,
               "placed_at_s": "" if stats["placed_at_s"] is None else stats["placed_at_s"]}
        row.update({key: stats[key] for key in PART_COUNTS})
        row.update({f"s_{mode.value}": times.get(mode.value, 0.0) for mode in Mode})
        # Its releases that went onto no constraint (the distances are in --json).
        row["release_misses"] = sum(miss["part"] == name
                                    for miss in summary.get("release_misses") or ())
        # Of them, those after which the part landed on a constraint in flight (``landed``:
        # a pin dropped into its bore), for a study that counts failed placements.
        row["release_misses_landed"] = sum(miss["part"] == name and bool(miss.get("landed"))
                                           for miss in summary.get("release_misses") or ())
        # How far the part went from the recording's (a what-if's, or a replay's since it
        # diverged): 0 where it did not, empty where that could not be measured.
        largest = summary.get("largest_departure")
        far = (largest or {}).get(name) or {}
        row["departure_m"] = "" if largest is None else far.get("distance_m", 0.0)
        row["departure_rad"] = "" if largest is None else far.get("angle_rad", 0.0)
        mass = (summary.get("masses_kg") or {}).get(name, "")
        # (To 12 digits: a mesh's mass properties carry round-off, 0.34559999999999996.)
        row["mass_kg"] = float(f"{mass:.12g}") if isinstance(mass, float) else mass
        rows.append({column: row[column] for column in ANALYSIS_COLUMNS})
    return rows


def _as_text(value) -> str:
    """A value in a table cell: text as itself (``two_frame``), anything else as JSON."""
    return value if isinstance(value, str) else json.dumps(value)


def _first_difference(a, b, path: str = ""):
    """Path of the first differing leaf between two decoded JSON values, with both values."""
    if isinstance(a, dict) and isinstance(b, dict):
        # A part's mode first: the difference a user reads first.
        for key in sorted(set(a) | set(b), key=lambda k: (k != "mode", k)):
            if key not in a or key not in b:
                return f"{path}.{key}".lstrip("."), a.get(key, "<missing>"), b.get(key, "<missing>")
            found = _first_difference(a[key], b[key], f"{path}.{key}")
            if found:
                return found
        return None
    if isinstance(a, list) and isinstance(b, list):
        for i, (x, y) in enumerate(zip(a, b)):
            found = _first_difference(x, y, f"{path}[{i}]")
            if found:
                return found
        if len(a) != len(b):
            return f"{path} length".lstrip("."), len(a), len(b)
        return None
    if a != b or type(a) is not type(b) or (
            isinstance(a, float) and math.copysign(1.0, a) != math.copysign(1.0, b)):
        return path.lstrip("."), a, b  # -0.0 and 0.0 are different bits
    return None


def _part_as_listed(name: str, listed: list, record: FrameRecord | None) -> dict | None:
    """The part's snapshot as a /parts message lists it: from ``listed`` (a message's parts)
    if there, else from ``record`` (a frame it is unchanged since)."""
    for item in listed:
        if isinstance(item, dict) and item.get("name") == name:
            return item
    for snapshot in (record.parts if record is not None else ()):
        if snapshot.name == name:
            return codec.snapshot_dict(snapshot)
    return None


def _divergence(inputs: TrackerFrame, recorded: list[tuple[str, bytes]],
                replayed: list[tuple[str, bytes]], replayed_record: FrameRecord | None = None,
                previous: FrameRecord | None = None) -> Divergence | None:
    """Where two frames' messages first differ. ``replayed_record`` and ``previous`` (the
    replayed frame and the one before, which matched the recording) give the state of a
    part that one side's changed-only frame does not list."""
    frame, t = inputs.frame, inputs.time_ns
    for index in range(max(len(recorded), len(replayed))):
        if index >= len(recorded) or index >= len(replayed):
            extra = replayed[index] if index < len(replayed) else recorded[index]
            message = codec.loads(extra[1], topic=extra[0], frame=frame)
            return Divergence(frame, t, extra[0], message.get("part"), "message",
                              "<none>" if index >= len(recorded) else message,
                              "<none>" if index >= len(replayed) else message)
        (topic_a, data_a), (topic_b, data_b) = recorded[index], replayed[index]
        if topic_a != topic_b:
            return Divergence(frame, t, topic_a, None, "channel", topic_a, topic_b)
        if data_a == data_b:
            continue
        # The recorded side may be damaged: a message that is not JSON is a RecordingError
        # naming the channel and frame (replay() adds the file), not a traceback.
        a = codec.loads(data_a, topic=topic_a, frame=frame)
        b = codec.loads(data_b, topic=topic_b, frame=frame)
        if topic_a == codec.PARTS_TOPIC and isinstance(a, dict) and isinstance(b, dict) \
                and a.get("complete") is False and b.get("complete") is False:
            # A frame that lists only what changed: a part listed by one run and not the
            # other moved in one and not in the other; name it, not the list's length.
            names_a = [p.get("name") for p in a.get("parts") or [] if isinstance(p, dict)]
            names_b = [p.get("name") for p in b.get("parts") or [] if isinstance(p, dict)]
            for name in names_a + names_b:
                if (name in names_a) != (name in names_b):
                    # Unlisted in the recording: as it was last frame, when the two runs
                    # still agreed. Unlisted in the replay: as it is in the replayed frame.
                    was = _part_as_listed(name, a.get("parts") or [], previous)
                    now = _part_as_listed(name, b.get("parts") or [], replayed_record)
                    found = _first_difference(was, now) if was and now else None
                    if found is None:
                        return Divergence(frame, t, topic_a, name, "listed as changed",
                                          "yes" if name in names_a else "no (unchanged)",
                                          "yes" if name in names_b else "no (unchanged)")
                    return Divergence(frame, t, topic_a, name, *found)
        found = _first_difference(a, b)
        if found is None:
            # The same values in other text (spacing, number notation): the same session,
            # as the check by value (``codec.FrameEncoder.matches``) finds it.
            continue
        path, value_a, value_b = found
        part = None
        if topic_a == codec.PARTS_TOPIC and path.startswith("parts["):
            index_part = int(path[6:path.index("]")])
            part = a["parts"][index_part]["name"] if index_part < len(a["parts"]) else None
            path = path[path.index("]") + 2:] if "]." in path else path
        elif topic_a == codec.PARTS_TOPIC and path.startswith("base."):
            part, path = (a.get("base") or {}).get("name"), path[5:]
        elif topic_a == codec.FOXGLOVE_TOPIC and path.startswith("transforms["):
            i = int(path[11:path.index("]")])
            part = a["transforms"][i]["child_frame_id"] if i < len(a["transforms"]) else None
            path = path[path.index("]") + 2:] if "]." in path else path
        elif isinstance(a, dict) and "part" in a:
            part = a["part"]
        return Divergence(frame, t, topic_a, part, path, value_a, value_b)
    return None


_FRICTION_KEYS = {"friction_static": "static", "friction_dynamic": "dynamic",
                  "friction_rotational": "rotational",
                  "friction_holding_torque": "holding_torque"}


def _finite_numbers(value) -> bool:
    """No infinite number in a JSON value (``strict_json`` already refuses NaN)."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, list):
        return all(_finite_numbers(item) for item in value)
    if isinstance(value, dict):
        return all(_finite_numbers(item) for item in value.values())
    return True


class AbsentTarget(ConfigError):
    """A ``--set`` of a part or tool this session does not have (a study's other sessions
    may: ``apply_overrides(absent=...)``); ``reason`` says so without the usage."""

    def __init__(self, reason: str, usage: str, *, field: str) -> None:
        self.reason = reason
        super().__init__(f"{reason}; {usage}", field=field)


def _override_target(doc: dict, physics: dict, key: str) -> dict:
    """The block of the session document that ``key`` (``physics.NAME`` or
    ``tools.TOOL.FIELD``) changes; a key that names nothing is a ConfigError naming it."""
    if key.startswith("physics.") and key[8:] and "." not in key[8:]:
        return physics
    if key.startswith("tools."):
        tool, _, name = key[6:].partition(".")
        if not tool or not name or "." in name:
            raise ConfigError("a tool's field is tools.TOOL.FIELD=VALUE: one tool, one field",
                              field=f"--set {key}")
        if name == "name":
            raise ConfigError("a tool's name is its device in the recorded tracker stream, "
                              "and cannot be changed", field=f"--set {key}")
        for candidate in doc.get("tools", []):
            if candidate.get("name") == tool:
                return candidate
        known = ", ".join(t.get("name", "?") for t in doc.get("tools", [])) or "none"
        raise AbsentTarget(f"no tool {tool!r} in this session (its tools: {known})",
                           "use tools.TOOL.FIELD=VALUE", field=f"--set {key}")
    if key.startswith("parts."):
        return _constraint_target(doc, key)
    raise ConfigError("only physics parameters, tools and parts can be changed: "
                      "physics.NAME=VALUE, tools.TOOL.FIELD=VALUE, "
                      "parts.PART.constraints.NAME.FIELD=VALUE or parts.PART.FIELD=VALUE "
                      "(mass, density, final_tolerance.distance, final_tolerance.angle_deg)",
                      field=f"--set {key}")


# What a what-if may change of a part's constraint or final pose: the recognition tolerances
# and the friction (would a looser fit have been recognised? a stickier shaft held it?).
_CONSTRAINT_FIELDS = ("tolerance.distance", "tolerance.angle_deg", "friction.static",
                      "friction.dynamic", "friction.rotational", "friction.holding_torque")
_FINAL_FIELDS = ("final_tolerance.distance", "final_tolerance.angle_deg")


def _constraint_target(doc: dict, key: str) -> dict:
    """``parts.PART.constraints.NAME.tolerance.distance`` (or another of
    ``_CONSTRAINT_FIELDS``), ``parts.PART.final_tolerance.distance``, ``parts.PART.mass``
    (kg) or ``parts.PART.density`` (would a heavier part still be lifted?): the block it
    changes. Names may hold dots: the
    session's own names are matched, not the key split at every dot."""
    usage = ("a part's field is parts.PART.constraints.NAME.FIELD=VALUE (FIELD: "
             f"{', '.join(_CONSTRAINT_FIELDS)}) or parts.PART.FIELD=VALUE (FIELD: mass, density, "
             f"{', '.join(_FINAL_FIELDS)})")
    rest = key[6:]
    parts = {str(p.get("name")): p for p in doc.get("parts", [])}
    named = [name for name in parts if rest.startswith(name + ".")]
    if not named:
        first = rest.split(".")[0]
        raise AbsentTarget(f"no part {first!r} in this session (its parts: "
                           f"{', '.join(sorted(parts)) or 'none'})", usage, field=f"--set {key}")
    name = max(named, key=len)
    part, field = parts[name], rest[len(name) + 1:]
    if field == "mass":
        return part  # kg: any part's, its density or mass_properties spreading it
    if field == "density":
        if "mass" in part:
            raise ConfigError(f"part {name!r} gives its mass (mass), which its density "
                              f"only spreads; change parts.{name}.mass", field=f"--set {key}")
        if "density" not in part or "mass_properties" in part:
            raise ConfigError(f"part {name!r} has its mass from mass_properties, not a "
                              f"density; change parts.{name}.mass (kg)", field=f"--set {key}")
        return part
    leaf = next((f for f in _CONSTRAINT_FIELDS if field.endswith("." + f)), None)
    if field not in _FINAL_FIELDS and (not field.startswith("constraints.") or leaf is None):
        # (A newcomer's trial: parts.peg.mas=1 on a part with no assembly was told the part
        # has none, though parts.peg.mass is any part's.)
        fields = ["mass", "density", *_FINAL_FIELDS, *(f"constraints.NAME.{f}"
                                                       for f in _CONSTRAINT_FIELDS)]
        close = difflib.get_close_matches(field, fields, n=1, cutoff=0.6)
        raise ConfigError(f"unknown field {field!r} of part {name!r}"
                          + (f" (a typo of {close[0]!r}?)" if close else "") + f"; {usage}",
                          field=f"--set {key}")
    assembly = part.get("assembly")
    if assembly is None:
        raise ConfigError(f"part {name!r} has no assembly (no constraints, no final pose)",
                          field=f"--set {key}")
    if field in _FINAL_FIELDS:
        if "final_pose" not in assembly:
            raise ConfigError(f"part {name!r} has no final pose", field=f"--set {key}")
        return assembly.setdefault(field.split(".")[0], {})
    assert leaf is not None
    wanted = field[len("constraints."):-len(leaf) - 1]
    constraints = assembly.get("constraints", [])
    names = [c.get("name", f"{c.get('type')}{i}") for i, c in enumerate(constraints)]
    if wanted not in names:
        raise ConfigError(f"no constraint {wanted!r} on part {name!r} (its constraints: "
                          f"{', '.join(names) or 'none'})", field=f"--set {key}")
    if names.count(wanted) > 1:
        raise ConfigError(f"part {name!r} has {names.count(wanted)} constraints named "
                          f"{wanted!r}: which one to change cannot be told (give each its "
                          "own name in the session)", field=f"--set {key}")
    return constraints[names.index(wanted)].setdefault(leaf.split(".")[0], {})


_WITH_UNIT = re.compile(r"\s*(-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-zµμ]+)\s*")
# Units a --set value may carry: lengths (converted to the session's unit) and masses (kg).
_LENGTH_UNITS = {**UNIT_TO_M, "cm": 0.01, "um": 1e-6, "µm": 1e-6, "nm": 1e-9}
_MASS_UNITS = {"kg": 1.0, "g": 1e-3}
# Every unit a --set or --tolerance value may carry (``cli.replay`` tells one split off
# its number by a space from a recording's name).
VALUE_UNITS = frozenset([*_LENGTH_UNITS, *_MASS_UNITS, *_ANGLE_UNITS])


def _is_length(key: str) -> bool:
    """A ``--set`` key whose value is a length (in the session's units unless it says)."""
    field = key.rpartition(".")[2]
    return field in LENGTH_FIELDS or key.endswith("tolerance.distance")


def _is_mass(key: str) -> bool:
    """A ``--set`` key whose value is a mass (kg unless it says)."""
    return key.startswith("parts.") and key.endswith(".mass") \
        or key.rpartition(".")[2] in ("one_hand_max_mass_kg", "two_hand_max_mass_kg",
                                      "max_mass_kg")


def _number_and_unit(text: str) -> tuple[str, str] | None:
    """``15mm`` as ``("15", "mm")``; None for text with no unit (``1e-9``, ``NaN``)."""
    match = _WITH_UNIT.fullmatch(text)
    if match is None or match.group(2) in ("e", "E", "Infinity", "NaN"):
        return None  # not a unit: a plain number's reading decides
    # (The Greek mu, U+03BC, typed for the micro sign, U+00B5.)
    return match.group(1), match.group(2).replace("\u03bc", "\u00b5")


def _with_unit(text: str, units: dict[str, float], default: str, *, field: str) -> float:
    """``text`` as a number in ``units``' base unit: ``15mm``, or a plain number in
    ``default``."""
    found = _number_and_unit(text)
    if found is not None and found[1] not in units:
        raise ConfigError(f"{text.strip()!r}: unknown unit {found[1]!r} (use "
                          f"{', '.join(units)})", field=field)
    number, unit = found if found is not None else (text, default)
    try:
        if "_" in number:  # (float() reads 1_000; nothing else here does)
            raise ValueError
        return float(number) * units[unit] + 0.0  # (+ 0.0: no -0)
    except ValueError:
        raise ConfigError(f"{text.strip()!r} is not a number", field=field) from None


def _finite_text(value: float, text: str, key: str) -> str:
    """A converted value as JSON text; one past a float's range (``1e400mm``) refused as
    a bare one is (a review: it read as the string 'inf', "not of type 'number'")."""
    if not math.isfinite(value):
        raise ConfigError(f"{text} is not a finite number", field=f"--set {key}")
    return repr(value)


def _in_session_units(key: str, text: str, units: str) -> str:
    """``15mm``, ``1.5cm``, ``0.6 in``, ``0.015m``: a length in its own unit, as the
    session's unit writes it (a study's --set then means one length in sessions of mm and
    of metres); ``12g``, ``0.012kg``: a mass, in kg."""
    found = _number_and_unit(text)
    if found is None:
        return text
    number, unit = found
    known = f"lengths: {', '.join(_LENGTH_UNITS)}; masses: {', '.join(_MASS_UNITS)}"
    if unit in _LENGTH_UNITS:
        if not _is_length(key):
            raise ConfigError(f"{text!r} has a length unit, and this is not a length",
                              field=f"--set {key}")
        return _finite_text(float(number) * _LENGTH_UNITS[unit] / UNIT_TO_M[units], text, key)
    if unit in _MASS_UNITS:
        if not _is_mass(key):
            raise ConfigError(f"{text!r} has a mass unit, and this is not a mass",
                              field=f"--set {key}")
        return _finite_text(float(number) * _MASS_UNITS[unit], text, key)
    if unit in _ANGLE_UNITS:
        # (A researcher's trial: 35deg refused for a tolerance's angle_deg, which
        # --tolerance takes.)
        if not key.endswith("_deg"):
            raise ConfigError(f"{text!r} has an angle unit, and this is not an angle",
                              field=f"--set {key}")
        # (In degrees as given: 30deg through radians came back 29.999999999999996.)
        degrees = float(number) if unit == "deg" \
            else float(number) * _ANGLE_UNITS[unit] * 180.0 / math.pi
        return _finite_text(degrees, text, key)
    raise ConfigError(f"{text!r}: unknown unit {unit!r} ({known}; angles: "
                      f"{', '.join(_ANGLE_UNITS)}; or a plain number: a length in the "
                      "session's units, a mass in kg, an angle in degrees)",
                      field=f"--set {key}")


def apply_overrides(session: Session, overrides: dict[str, str], *,
                    absent: dict[str, str] | None = None) -> tuple[Session, dict]:
    """The session as if its ``physics`` block said ``NAME: VALUE`` for each override
    ``physics.NAME``, its tool ``TOOL`` said ``FIELD: VALUE`` for each ``tools.TOOL.FIELD``
    (a tool's lifting limit or reach: would a smaller hoist have done?), and a part's
    constraint or final pose said so for ``parts.PART.constraints.NAME.tolerance.distance``
    and the like (would a looser fit have been recognised?).

    Values are JSON (numbers, strings, lists) in the session's own units, exactly as they
    would be written in the session file, or a length with its unit (``15mm``, ``0.6in``,
    ``0.015m``), converted to the session's; the changed document is validated against the
    session schema and the scene is built from it, so what depends on physics follows the
    change: ``model`` brings that model's own schemes (the session's explicit choices of
    them are dropped unless also overridden), and a friction override applies to every
    constraint, also those that set their own friction in the session.

    With ``absent`` (a dict), a part or tool the session does not have is not an error: the
    key is left out of what is applied and put in ``absent`` with why (a study's what-if
    of a part that only some of its sessions have).
    """
    if not overrides:
        return session, {}
    doc = copy.deepcopy(session.doc)
    physics = doc.setdefault("physics", {})
    applied: dict[str, object] = {}
    # A part's own values after physics' (a physics friction clears the constraints' own).
    for key, text in sorted(overrides.items(), key=lambda kv: (kv[0].startswith("parts."),
                                                             kv[0])):
        try:
            target = _override_target(doc, physics, key)
        except AbsentTarget as exc:
            if absent is None:
                raise
            absent[key] = exc.reason
            continue
        text = _in_session_units(key, text, doc.get("units", "m"))
        try:
            value = strict_json(text)
        except json.JSONDecodeError:
            value = text
        except ValueError as exc:
            raise ConfigError(str(exc), field=f"--set {key}") from None
        if not _finite_numbers(value):  # 1e400 reads as infinity
            raise ConfigError(f"{text} is not a finite number", field=f"--set {key}")
        target[key.rpartition(".")[2]] = value
        applied[key] = value
        if key == "physics.model":
            # A model what-if brings the model's own schemes, whatever the session chose.
            for governed in PAPER_DEFAULTS:
                if f"physics.{governed}" not in overrides:
                    physics.pop(governed, None)
        if key.startswith("physics.") and key[8:] in _FRICTION_KEYS:
            # A what-if of friction means every contact: constraints lose their own value.
            for part in doc.get("parts", []):
                for constraint in part.get("assembly", {}).get("constraints", []):
                    constraint.get("friction", {}).pop(_FRICTION_KEYS[key[8:]], None)
    try:
        changed = parse(json.dumps(doc, indent=2).encode(), session.files, source="--set")
        # On the physics a recording was made with, where the session came so (``as_made``).
        changed = replace(changed, physics_defaults=session.physics_defaults)
        changed.build_scene()
    except (SessionError, ValueError) as exc:
        # Named by the --set that made it (a trial: "field parts[0].mass" for a --set of
        # parts.sleeve.mass), with the session's field it landed in.
        message = exc.message if isinstance(exc, SessionError) else str(exc)
        where = exc.field if isinstance(exc, SessionError) else None
        option = f"--set {next(iter(applied))}" if len(applied) == 1 else "--set"
        raise ConfigError(message + (f" (the changed session's {where})" if where else ""),
                          field=option) from None
    return changed, applied


class TrackerWatch:
    """What a tracker stream shows that its session file does not, seen frame by frame as
    it is recorded: a device farther from the origin than a room (millimetres read as
    metres), every position of a CSV log within millimetres of it (metres read as
    millimetres), and a device jumping faster than a hand moves between two of its samples
    (a keyframe in another unit, a tracker losing track)."""

    # A room is no larger than this (m); no hand moves this fast (m/s) by this far (m).
    ROOM_M, HAND_SPEED_M_S, JUMP_M = 20.0, 25.0, 0.05
    # No hand is this far from its head (m): an arm reaches ~0.8 m, scripted sessions
    # with a head left standing put a hand up to ~1.5 m from it (the goldens).
    ARM_M = 3.0
    HANDS = ("left_hand", "right_hand")

    def __init__(self, session: Session, obstacles=()) -> None:
        tracker = session.doc["tracker"]
        self.csv = "csv" in tracker
        self.units = tracker.get("csv_units", session.doc.get("units", "m")) if self.csv \
            else session.doc.get("units", "m")
        self.field = "tracker.csv" if self.csv else "tracker.devices"
        self.reach: dict[str, tuple[float, int]] = {}
        self.last: dict[str, tuple[int, object, int]] = {}
        self.jumps: dict[str, list] = {}
        # ``obstacles``: (name, lo, hi) world boxes, z up, of what nothing passes through
        # (the table, a fixed base). A device over one and then under it, within its
        # footprint, passed through it (an engineer's trial: a keyframe typed 85 for 805
        # dragged the held part 650 mm below the table without a word; a held part is not
        # stopped by anything). Per (device, obstacle): the side it was last seen on.
        self.obstacles = list(obstacles)
        self.side: dict[tuple[str, int], int] = {}
        self.through: dict[str, list] = {}
        # Per hand: the farthest it was from the head, where farther than an arm reaches
        # (a researcher's trial: 11.0 typed for 1.1 m carried a part 10 m up, where it was
        # still flying at the end, its drop uncounted, without a word).
        self.off_head: dict[str, tuple[float, int]] = {}

    def see(self, frame: TrackerFrame) -> None:
        head = None
        for name, sample in frame.devices:
            if name == "head":
                head = sample.position
        for name, sample in frame.devices:
            p = sample.position
            r = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
            if r > self.reach.get(name, (-1.0, 0))[0]:
                self.reach[name] = (r, frame.frame)
            if head is not None and name in self.HANDS:
                d = math.dist(p, head)
                if d > self.ARM_M and d > self.off_head.get(name, (0.0, 0))[0]:
                    self.off_head[name] = (d, frame.frame)
            for k, (obstacle, lo, hi) in enumerate(self.obstacles):
                if not (lo[0] <= p[0] <= hi[0] and lo[1] <= p[1] <= hi[1]):
                    self.side.pop((name, k), None)  # beside it: going round is no passing
                    continue
                side = 1 if p[2] > hi[2] else -1 if p[2] < lo[2] else 0
                if side == 0:
                    continue  # within it: the side it came from stands
                before = self.side.get((name, k))
                self.side[(name, k)] = side
                if before is not None and before != side:
                    self.through.setdefault(name, []).append((obstacle, frame.frame,
                                                              frame.time_ns))
            last = self.last.get(name)
            if last is not None and last[1] is sample:
                continue  # carried over from an earlier row of a log: not a new sample
            self.last[name] = (frame.time_ns, sample, frame.frame)
            if last is None:
                continue
            t0, s0, f0 = last
            p0 = s0.position  # type: ignore[attr-defined]
            d = math.sqrt(sum((a - b) ** 2 for a, b in zip(p, p0)))
            dt = (frame.time_ns - t0) * 1e-9
            if d > self.JUMP_M and (dt <= 0.0 or d / dt > self.HAND_SPEED_M_S):
                self.jumps.setdefault(name, []).append((f0, frame.frame, frame.time_ns, d, dt))

    def warnings(self, first_time_ns: int) -> list[str]:
        out = []
        for name, (r, at) in sorted(self.reach.items()):
            if r > self.ROOM_M:
                out.append(f"{self.field}: {name} is {r:.3g} m from the origin at frame {at}, "
                           f"farther than any room: positions in millimetres read as "
                           f"{self.units}?")
        if self.csv and self.units != "m" and self.reach \
                and 0.0 < max(r for r, _ in self.reach.values()) < 0.003:
            out.append(f"{self.field}: every position of the log is within 3 mm of the origin: "
                       f"written in metres and read as {self.units} (tracker.csv_units)?")
        for name, (d, at) in sorted(self.off_head.items()):
            out.append(f"{self.field}: {name} is {d:.3g} m from the head at frame {at}, "
                       "farther than an arm reaches: a position mistyped (a part it holds "
                       "goes there with it)?")
        for name, passes in sorted(self.through.items()):
            obstacle, at, t = passes[0]
            more = f" ({len(passes) - 1} more such)" if len(passes) > 1 else ""
            out.append(f"{self.field}: {name} passes through {obstacle} by frame {at} (t = "
                       f"{(t - first_time_ns) * 1e-9:.3f} s){more}: a part it holds goes "
                       "through with it (a held part is stopped by nothing); a position "
                       "mistyped?")
        for name, jumps in sorted(self.jumps.items()):
            f0, f1, t, d, dt = jumps[0]
            more = f" ({len(jumps) - 1} more such)" if len(jumps) > 1 else ""
            rate = f"; {d / dt:.3g} m/s" if dt > 0.0 else " at one time stamp"
            out.append(f"{self.field}: {name} jumps {d:.3g} m between frames {f0} and {f1} "
                       f"(t = {(t - first_time_ns) * 1e-9:.3f} s{rate}){more}: faster than a "
                       "hand moves; a position in another unit, or the tracker losing track?")
        return out


def _obstacles(scene: Scene) -> list[tuple[str, list[float], list[float]]]:
    """What no hand passes through, as ``TrackerWatch`` looks at it: the environment and a
    fixed base, as world boxes, where gravity is down z (the boxes' z is then up)."""
    g = scene.physics.gravity
    if not (g[2] < 0.0 and abs(g[0]) + abs(g[1]) <= 1e-9 * abs(g[2])):
        return []
    return [(body.name, *world_box(body, body.initial_pose)) for body in _fixed_bodies(scene)]


def _fixed_bodies(scene: Scene) -> list:
    """What does not move: the environment, then a fixed base."""
    bodies = list(scene.environment)
    if scene.base is not None and scene.base_fixed:
        bodies.append(scene.base)
    return bodies


def _size(path: Path) -> str:
    size = path.stat().st_size
    return f"{size / 1e6:.1f} MB" if size >= 100_000 else f"{size:,} bytes"


def refuse_replacing(out: str | Path, session: Session, scene: Scene) -> str | None:
    """``vade-record``'s and ``vade-replay -o``'s guard (``--force`` skips it), before a
    run writes ``out``: a file there that is a recording of another session, or no
    recording, is refused (an engineer's trial found a study's recording replaced by
    another session's without a word), and so is one of this session with other tracker
    input (another take: its input may exist nowhere else). One with the same input is
    replaced: silently where it is this recording made again (the same session and
    physics), else with the note returned, for the command to print (the loop of editing
    a session's parts or physics and recording it again is not refused; a review found an
    older version's recording replaced without a word)."""
    path = Path(out)
    kept = left_partial(path)
    if kept is not None:
        # (A user's trial: an interrupted take's frames, kept there, were written over by
        # the next run to the same output without a word. Not replaced even by a run of the
        # same session: a replay's frames come from its recording's inputs, and a version
        # may make other frames of the same session and physics: a review.)
        held = {True: "the frames a run that stopped early kept",
                False: "something that is not a recording",
                None: "what a run left there"}[holds_recording(kept)]
        raise ConfigError(f"{kept} holds {held} ({_size(kept)}); move it away to keep it, "
                          "or pass --force to write over it", file=str(out))
    if not path.exists() or in_place(path):
        return None
    try:
        existing = Recording(path)
        theirs = existing.session
        physics = existing.metadata.get("physics")
    except (VadeError, OSError, ValueError):
        raise ConfigError("it holds a file that is not a readable recording; pass --force "
                          "to replace it, or choose another output", file=str(out)) from None
    if theirs.name != session.name:
        raise ConfigError(f"it holds a recording of another session ({theirs.name!r}); pass "
                          "--force to replace it, or choose another output", file=str(out))
    # The tracker's own file (a CSV log) is its input; the others (meshes) are the
    # design's, which an engineer edits between takes (a trial: a mesh added to the base
    # was refused as "other tracker input").
    logs = {name for name in (theirs.doc.get("tracker", {}).get("csv"),
                              session.doc.get("tracker", {}).get("csv")) if name}
    if theirs.doc.get("tracker") != session.doc.get("tracker") \
            or any(theirs.files.get(name) != session.files.get(name) for name in logs):
        # Another take, or another participant on the same session template: its tracker
        # input may exist nowhere else (a review).
        raise ConfigError(f"it holds a recording of {session.name!r} with other tracker input "
                          "(another take?); pass --force to replace it, or choose another "
                          "output", file=str(out))
    ours = physics_metadata(scene.physics)
    differs = []
    if theirs.doc != session.doc:
        differs.append("its session, in " + ", ".join(_changed_fields(theirs.doc, session.doc)))
    files = sorted(name for name in set(theirs.files) | set(session.files)
                   if name not in logs and theirs.files.get(name) != session.files.get(name))
    if files:
        differs.append("its files, " + ", ".join(files))
    if physics is not None and physics != ours:
        differs.append(f"its physics, in {', '.join(_changed_fields(physics, ours))}")
    if not differs:
        return None
    return (f"replacing {out}, a recording of {session.name!r} made otherwise "
            f"({'; '.join(differs)})")


def _changed_fields(theirs: dict, ours: dict, *, most: int = 6) -> list[str]:
    """The fields that differ between two documents, a part by its name (``parts.peg``),
    at most ``most`` and a count of the rest: what a note on replacing a recording names
    (a researcher's trial: it said only that the session differed)."""
    out = []
    for key in sorted(set(theirs) | set(ours)):
        a, b = theirs.get(key), ours.get(key)
        if a == b:
            continue
        if key == "parts" and isinstance(a, list) and isinstance(b, list):
            named_a = {str(p.get("name")): p for p in a if isinstance(p, dict)}
            named_b = {str(p.get("name")): p for p in b if isinstance(p, dict)}
            names = sorted(n for n in set(named_a) | set(named_b)
                           if named_a.get(n) != named_b.get(n))
            out += [f"parts.{n}" for n in names] or ["parts"]
        else:
            out.append(key)
    return out[:most] + ([f"{len(out) - most} more"] if len(out) > most else [])


def _part_figures(scene: Scene) -> dict:
    """What a run's summary says of each part's body: its mass and centre of mass."""
    return {"masses_kg": {p.name: p.mass_kg for p in scene.parts},
            "centers_of_mass_m": {p.name: list(p.center_of_mass) for p in scene.parts}}


def record(session: Session, out: str | Path, *,
           on_frame: Callable[[FrameRecord], None] | None = None,
           replace_other: bool = True,
           on_warnings: Callable[[list[str]], None] | None = None,
           keep_partial: bool = True) -> RunSummary:
    """Run a session's tracker stream and write the recording to ``out``.

    The file is written as ``out.partial`` and renamed when complete. If the run fails part
    way, the partial file is closed properly (readable, indexed) and kept, and the error is
    raised with the frame it happened at. With ``replace_other`` False, a file at ``out``
    other than this recording made again is refused first (``refuse_replacing``). With
    ``on_warnings``, the warnings known before the first frame (the session's and its
    scene's) are given to it then: a long run's slip is seen as it starts, and stopped
    (the summary's ``warnings`` hold them too, with those found as it ran). With
    ``keep_partial`` False, a run that fails or is interrupted removes its partial file and
    says nothing of it (a golden's take: the session makes it again, ``vade-goldens``).
    """
    scene = session.build_scene()
    if not replace_other:
        note = refuse_replacing(out, session, scene)
        if note:
            print(f"note: {note}", file=sys.stderr)
    # A log is read and checked whole before its first frame (``inputs.from_csv``): a bad
    # row is an error here, before anything is written.
    try:
        stream = session.tracker_frames()
        first_input = next(stream, None)
    except KeyboardInterrupt as exc:
        # (A researcher's trial: "interrupted" alone, while a long log was read.)
        exc.add_note("nothing was recorded (the tracker log was being read)")
        raise
    partial, target = partial_output(out)
    collision = CollisionWorld(scene)
    summary = RunSummary(session.name, parts=[p.name for p in scene.parts],
                         warnings=session.warnings() + name_warnings(
                             scene_warnings(scene, collision, session.doc), session.doc),
                         units=session.doc.get("units", "m"),
                         **_part_figures(scene))
    if on_warnings is not None and summary.warnings:
        on_warnings(list(summary.warnings))
    first_time = None
    open_misses: dict[str, int] = {}  # part -> its miss still in flight (``landed``)
    frame = None
    watch = TrackerWatch(session, _obstacles(scene))
    writer = RecordingWriter(partial, session, scene)
    writer.warnings = summary.warnings
    # Held off from here to the file's close: to a frame's end while frames are written,
    # then to the end of closing the file (a review: a second Ctrl-C raised inside the
    # close of an interrupted run lost every frame kept).
    with FrameBoundaryInterrupts() as interrupts:
        try:
            inputs = _watched(itertools.chain(() if first_input is None else (first_input,),
                                              stream), watch)
            advance = Stepper(scene, collision)
            # A batch at a time (``_stepped``): what stops the run part way is raised after
            # the frames before it are written.
            for _, stepped in _stepped(inputs, advance):
                for record_ in stepped:
                    frame = record_.frame
                    if first_time is None:
                        first_time = record_.time_ns
                    writer.write_frame(record_)
                    summary.count(record_, first_time)
                    if record_.events:
                        landed(summary.release_misses, open_misses, record_)
                        summary.release_misses += release_misses(scene, record_, first_time)
                        _opened(summary.release_misses, open_misses, record_)
                        summary.warnings += release_overlaps(scene, collision, record_,
                                                             first_time)
                        summary.warnings += stopped_on_a_wall(scene, collision, record_,
                                                              first_time)
                    if on_frame:
                        on_frame(record_)
                    interrupts.check()
            interrupts.check()  # (one that came as the input ran out)
        except VadeError as exc:
            if writer.frames and exc.frame is None and exc.field is None and frame is not None:
                exc.frame = frame + 1  # the frame being made when it failed
            if not keep_partial:
                _close_stopped(writer, exc)
                if target is not None:  # (not a device or pipe written in place)
                    partial.unlink(missing_ok=True)
                raise
            kept = _kept_after(writer, target, partial, exc, "")
            if kept is None:
                raise
            raise kept from None
        except BaseException as exc:
            _close_stopped(writer, exc)
            if not keep_partial:
                if target is not None:
                    partial.unlink(missing_ok=True)
            elif isinstance(exc, KeyboardInterrupt) and writer.frames:
                exc.add_note(_kept(writer.frames, partial))
            raise
        if first_time is not None:
            summary.warnings += watch.warnings(first_time)  # (kept in the file: the same list)
            if summary.frames > 1 and summary.duration_s == 0.0:
                # (An engineer's trial: epoch times in ms written as 1.765e+12 read as one
                # time, "recorded 540 frames (0.00 s)" and nothing else.)
                summary.warnings.append(
                    f"every one of the {summary.frames} frames has the same time: a "
                    "tracker log's times written with too few digits (1.765e+12), or in "
                    "another unit than tracker.csv_time_unit? Nothing moves in no time")
            summary.warnings += fallen_past_everything(scene, record_, first_time)
        writer.close(complete_as=target)
    if interrupts.pending:
        raise _interrupted_when_complete(target or partial, interrupts.pending)
    summary.counters = dict(collision.stats)
    return summary


def release_overlaps(scene: Scene, collision: CollisionWorld, record: FrameRecord,
                     first_time_ns: int) -> list[str]:
    """Parts let go overlapping the base part (``released_touching_base`` deeper than
    ``_INSIDE_BASE_M``): how deep, after the frame. Such a part rides on the base where it
    is, the two overlapping, and nothing else says so (an engineer's trial: a sleeve let go
    7 mm off its shaft's axis, the shaft 7 mm into its wall; the miss line said why it did
    not snap, not that the two overlap). Parts let go a few tenths of a millimetre into a
    flat face are moved out of it first (``step._out_of_flat_overlap``) and are not warned
    of. The depth as at the start (``_depth_inside``: points of each surface the other
    winds about); its fcl queries are not the run's (its counters stay a replay's). Parts
    let go wholly inside the table or another environment object (a hand pushed them in)
    are left there, STATIC, and warned of too."""
    out: list[str] = []
    t = (record.time_ns - first_time_ns) / 1e9
    for event in record.events:
        if event.kind != "PartReleased" or event.cause not in (
                Cause.RELEASED_ON_BASE_PART.value, Cause.RELEASED_ON_TABLE.value):
            continue
        body = next((b for b in scene.parts if b.name == event.part), None)
        snap = next((p for p in record.parts if p.name == event.part), None)
        if body is None or snap is None:
            continue
        pose = Pose(snap.position, snap.rotation_xyzw)
        counters = dict(collision.stats)
        if event.cause == Cause.RELEASED_ON_TABLE.value:
            # Let go wholly inside the table (or another object): left there, STATIC.
            near = collision.environment_near(pose.apply(body.center_of_mass),
                                              body.radius_about_cm)
            inside = collision.inside_environment(body.name, pose, near) if near else -1
            collision.stats.update(counters)
            if inside >= 0:
                out.append(f"frame {record.frame} (t = {t:.3f} s): {body.name} was let go "
                           f"wholly inside {collision.environment_name(inside)}; it stays "
                           "there, STATIC (released_touching_environment), until a hand "
                           "moves it")
            continue
        if scene.base is None or record.base is None:
            continue
        base_pose = Pose(record.base.position, record.base.rotation_xyzw)
        depth = max(_depth_inside(collision, body, scene.base, base=True,
                                  poses=(pose, base_pose)),
                    _depth_inside(collision, scene.base, body, poses=(base_pose, pose)))
        collision.stats.update(counters)
        if depth > _INSIDE_BASE_M:
            out.append(f"frame {record.frame} (t = {t:.3f} s): {body.name} was let go about "
                       f"{depth * 1e3:.2g} mm inside the base part ({scene.base.name}); it "
                       "rides on the base so, the two overlapping (released_touching_base), "
                       "until a hand moves it")
    return out


def stopped_on_a_wall(scene: Scene, collision: CollisionWorld, record: FrameRecord,
                      first_time_ns: int) -> list[str]:
    """Parts the table (or another environment object) stopped on a face that cannot hold
    them up: steeper than 84 degrees or facing down (the base's rule for what holds a
    part). The paper's rule stops a part at the table wherever it touches it, STATIC, so a
    part thrown at the table's side hangs on it (a physics trial: a cube stuck to the
    side of the table, a "drop" no study would count as one); said, not changed. And
    parts stopped wholly inside one (let go there, or on a base the hand held in it)."""
    out: list[str] = []
    g = scene.physics.gravity
    norm = math.sqrt(sp.dot(g, g))
    if norm == 0.0:
        return out
    up = sp.scale(g, -1.0 / norm)
    t = (record.time_ns - first_time_ns) / 1e9
    for event in record.events:
        if event.kind != "ContactMade" or event.cause != Cause.HIT_ENVIRONMENT.value:
            continue
        snap = next((p for p in record.parts if p.name == event.part), None)
        index = next((i for i, b in enumerate(scene.environment) if b.name == event.other),
                     None)
        if snap is None or index is None or snap.mode != Mode.STATIC.value:
            continue
        counters = dict(collision.stats)
        pose = Pose(snap.position, snap.rotation_xyzw)
        # (Nested in it, the two are at a distance: whether it is inside is asked first.)
        inside = collision.inside_environment(event.part, pose, (index,)) >= 0
        normal = None if inside else collision.environment_normal(event.part, pose, index)
        collision.stats.update(counters)
        if inside:
            # (Let go on a base the hand held in the table: it stays there, inside it.)
            out.append(f"frame {record.frame} (t = {t:.3f} s): {event.part} stopped wholly "
                       f"inside {event.other}, where it stays, STATIC, until a hand moves it "
                       "(let go there, or on a base held in it)")
        elif normal is not None and sp.dot(normal, up) <= _WALL_COS:
            steep = math.degrees(math.acos(max(-1.0, min(1.0, sp.dot(normal, up)))))
            out.append(f"frame {record.frame} (t = {t:.3f} s): {event.part} stopped on "
                       f"{event.other} at a face {steep:.0f} degrees from level, which cannot "
                       "hold it up: a part stops wherever it touches the table (the "
                       "paper's rule), so it stays there, STATIC, until a hand moves it")
    return out


# A face whose normal is no nearer up than this (84 degrees) cannot hold a part up
# (``step._MIN_SUPPORT_COS``, the base's rule).
_WALL_COS = 0.1


def fallen_past_everything(scene: Scene, last: FrameRecord, first_time_ns: int) -> list[str]:
    """Parts still flying at the end, below everything of the scene (along gravity): there
    is no floor, so they fall for ever, and a study's table says only "never placed" (a
    researcher's trial: a sleeve thrown past the table ended 0.55 m under the floor's
    level, flying)."""
    g = scene.physics.gravity_free
    norm = math.sqrt(sp.dot(g, g))
    if norm == 0.0 or not scene.environment:
        return []
    down = sp.scale(g, 1.0 / norm)
    lowest = max(sp.dot(corner, down) for body in scene.environment
                 for corner in _corners(body, body.initial_pose))
    out = []
    t = (last.time_ns - first_time_ns) / 1e9
    for snap in last.parts:
        if snap.mode != Mode.INSPACE.value:
            continue
        below = sp.dot(snap.position, down) - lowest
        if below > 0.0:
            out.append(f"{snap.name} is still falling at the end (t = {t:.3f} s), "
                       f"{below:.3g} m past everything in the scene: there is no floor")
    return out


def _corners(body, pose) -> list[sp.Vec3]:
    """The corners of the body's own box, posed."""
    lo, hi = body.bbox_min, body.bbox_max
    return [pose.apply((x, y, z)) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
            for z in (lo[2], hi[2])]


def _watched(frames: Iterable[TrackerFrame], watch: TrackerWatch) -> Iterator[TrackerFrame]:
    for frame in frames:
        watch.see(frame)
        yield frame


def _introduced(changed: Session, recorded: Session) -> list[str]:
    """A what-if's warnings: those of the changed session that the recorded one lacks (the
    slips of its ``--set`` values, not the recording's own, warned of when it was made)."""
    before = set(recorded.warnings())
    return [warning for warning in changed.warnings() if warning not in before]


# Releases that put a part onto a constraint or its final pose: no miss to tell of.
_ON_A_MATE = frozenset({Cause.RELEASED_ON_BASE.value, Cause.RELEASED_AT_FINAL_POSE.value})


def release_misses(scene: Scene, record: FrameRecord, first_time_ns: int) -> list[dict]:
    """For each part released in ``record`` that has constraints but went onto none, near
    enough to one to have been meant for it (within ``_NEAR`` times its tolerances): the
    constraint it came nearest (by the larger of its angle and distance over their
    tolerances) and how far off it was, at its pose after the frame."""
    out: list[dict] = []
    if record.base is None:
        return out
    base_pose = Pose(record.base.position, record.base.rotation_xyzw)
    for event in record.events:
        if event.kind != "PartReleased" or event.cause in _ON_A_MATE:
            continue
        body = next((b for b in scene.parts if b.name == event.part), None)
        snap = next((p for p in record.parts if p.name == event.part), None)
        if body is None or snap is None or body.assembly is None or not body.assembly.mates:
            continue
        base_from_part = base_pose.inverse().compose(Pose(snap.position, snap.rotation_xyzw))
        best = None
        for k, mate in enumerate(body.assembly.mates):
            angle, distance = cn.misalignment(mate, base_from_part)
            # On an axis's line, within both tolerances, but beyond the end of its shaft
            # or bore (an engineer's trial: "1 mm off (tolerance 4 mm)" said nothing of the
            # 5 mm above the bore that was the miss).
            snapped = cn.recognise(mate, base_from_part) \
                if mate.kind == "axis" and mate.slide_dirs else None
            beyond = max(0.0, beyond_end(mate, k, snapped)) if snapped is not None else 0.0
            score = max(_over(angle, mate.angle_tolerance),
                        _over(distance, mate.distance_tolerance),
                        _over(beyond, mate.distance_tolerance))
            if best is None or score < best[0]:
                best = (score, mate, angle, distance, beyond)
        score, mate, angle, distance, beyond = best  # type: ignore[misc]
        if not score <= _NEAR:
            continue  # put down or thrown elsewhere: not an attempt at this constraint
        # A part that does not fit the shaft or bore is not put onto it however near
        # (``step._release_on_base``): that, not an end, is the miss.
        misfit = mate.misfit if mate.kind == "axis" \
            and scene.physics.coaxial_fit == "radial" else ()
        # Within its tolerances and on it, but gravity pulls the part off a face of it (a
        # physics audit: a two-plane corner leaning so that the part falls off the wall
        # read "released 0 mm and 0 deg off corner", saying nothing of why).
        lifted = mate.kind != "axis" and score <= 1.0 and not misfit and beyond <= 0.0 \
            and onbase.normal_load(mate.kind, mate.base_dirs, None, sp.quat_rotate(
                sp.quat_conj(base_pose.rotation), scene.physics.gravity_slide))[1]
        out.append({"frame": record.frame,
                    "time_s": (record.time_ns - first_time_ns) / 1e9, "part": event.part,
                    "cause": event.cause, "nearest_constraint": mate.name,
                    "off_distance_m": distance, "distance_tolerance_m": mate.distance_tolerance,
                    "off_angle_deg": math.degrees(angle),
                    "angle_tolerance_deg": math.degrees(mate.angle_tolerance),
                    "beyond_end_m": 0.0 if misfit else beyond,
                    "misfit_m": list(misfit) if misfit else None,
                    "pulled_off": bool(lifted), "landed": None})
    return out


_LANDINGS = frozenset({Cause.LANDED_ON_CONSTRAINT.value, Cause.LANDED_AT_FINAL_POSE.value})


def landed(misses: list[dict], open_misses: dict[str, int], record: FrameRecord) -> None:
    """A part let go off its constraints that then came onto one in flight (physics
    ``landing: constraints``: a pin dropped above its bore): its miss says so, with the
    frame and the cause (``landed``), so the miss does not read as the end of it. Only
    the flight that followed the miss's release (``open_misses``, part -> the miss's
    index: closed by the part's next change of mode, whatever it is; a review found an
    old miss credited with a later release's landing)."""
    for event in record.events:
        if event.kind == "ModeChanged":
            k = open_misses.pop(event.part, None)
            if k is not None and event.cause in _LANDINGS:
                misses[k]["landed"] = {"frame": record.frame, "cause": event.cause,
                                       "mode": event.to_mode}


def _opened(misses: list[dict], open_misses: dict[str, int], record: FrameRecord) -> None:
    """The misses of ``record`` (the last ones of ``misses``) are open until their part's
    next change of mode (``landed``)."""
    for k in range(len(misses) - 1, -1, -1):
        if misses[k]["frame"] != record.frame:
            break
        open_misses[misses[k]["part"]] = k


# A part resting at the start this far from anything under it is said to float (m).
_FLOATING_M = 0.005
# A final pose this far into the base (along its constraint) is said to be unreachable (m).
_INSIDE_BASE_M = 0.001
# A final pose that puts its part farther than this (or than half the part's reach) from
# the base part: not an assembled place (``scene_warnings``).
_FINAL_CLEAR_M = 0.01


def _box_gap(a: tuple[list[float], list[float]], b: tuple[list[float], list[float]]) -> float:
    """Distance between two axis-aligned boxes (0 when they overlap): a lower bound of the
    distance between anything inside them."""
    return math.sqrt(sum(max(0.0, b[0][k] - a[1][k], a[0][k] - b[1][k]) ** 2
                         for k in range(3)))


def _depth_into_base(collision: CollisionWorld, part: str, k: int, mate: cn.Mate, pose,
                     reach: float, passes: list[float] | None = None,
                     tol: float = 0.0) -> float:
    """How far short of ``pose`` the base stops the part coming along its constraint from
    outside the base: from either end of an axis, from the open side of a plane; 0 if it
    gets there (touching is there). The part starts beyond everything (``reach``: its own
    size) and is moved in by its distance to the base each step, which no translation of
    that length can pass through; within the contact tolerance it has hit. (fcl's distance
    is 0 for overlapping meshes and a gap between nested ones, so a pose is not judged by
    its own distance.)

    On an axis the steps are measured to the base faces a move along the axis can meet:
    a face lying radially apart from the part (a bore's rim round a pin, 0.2 mm clear) is
    never met, so it does not shorten them (``CollisionWorld.axial_split``; a 100k-face pin
    passing such a rim took ~0.2 mm steps of a whole-mesh query each). What an approach
    that gets there passes (``passes``, as the passing warnings with contact tolerance
    ``tol`` read it) is the nearest its steps came to the faces it is measured to, with
    the faces apart radially by their radial gap where that is twice ``tol`` or more, and
    those nearer by their distance with the part beside the nearest of them, taken where
    nothing the warnings tell lies between it and their radial gap (``_passed``); else that
    way is approached as it was, measured to every face (``_approach``)."""
    mode = SKIP_COAXIAL if mate.kind == "axis" else SKIP_COPLANAR
    axis = mate.base_dirs[0]
    far = collision.base_radius + math.sqrt(sp.dot(pose.position, pose.position)) + reach \
        + 0.01
    if mate.kind != "axis":
        if collision.base_distance(part, k, pose, mode) == math.inf:
            return 0.0
        s, nearest = _approach(collision, part, k, mode, pose, axis, 1.0, far)
        if passes is not None and s <= _INSIDE_BASE_M:
            passes.append(nearest)
        return s
    split = collision.axial_split(part, k, pose, _APART_M, 2.0 * tol)
    if split.empty:
        return 0.0
    short = []
    for sign in (1.0, -1.0):
        s, nearest = _steps(lambda moved: collision.split_distance(part, split.blocking,
                                                                   moved), pose, axis, sign, far)
        if passes is not None and s <= _INSIDE_BASE_M:
            passed = _passed(collision, part, split, pose, axis, sign, far, tol)
            if passed is None:
                s, nearest = _approach(collision, part, k, mode, pose, axis, sign, far)
            else:
                nearest = min(nearest, passed, split.far_gap)
            if s <= _INSIDE_BASE_M:
                passes.append(nearest)  # an approach that gets there: what it passed on the way
        short.append(max(s, 0.0))
    return min(short)


def _approach(collision: CollisionWorld, part: str, k: int, mode, pose, axis, sign: float,
              far: float) -> tuple[float, float]:
    """One way of ``_depth_into_base`` measured to every face the mode checks (``_steps``)."""
    return _steps(lambda moved: collision.base_distance(part, k, moved, mode), pose, axis,
                  sign, far)


def _steps(distance: Callable[[Pose], float], pose, axis, sign: float,
           far: float) -> tuple[float, float]:
    """One way of ``_depth_into_base``, from ``far`` along ``axis`` (``sign``: which way),
    each step the part's ``distance`` to the base: how far short of ``pose`` the part stops,
    and the nearest it passes the base far (> 2 mm) from it."""
    s = far
    nearest = math.inf
    for _ in range(_APPROACH_STEPS):
        moved = Pose(tuple(p + sign * s * a for p, a in zip(pose.position, axis)),
                     pose.rotation)
        d = distance(moved)
        if d <= _APPROACH_TOL_M or s <= 0.0:
            break
        if s > _PASSING_FAR_M:
            nearest = min(nearest, d)
        s = max(0.0, s - d)
    return max(s, 0.0), nearest


def _passed(collision: CollisionWorld, part: str, split, pose, axis, sign: float, far: float,
            tol: float) -> float | None:
    """How near an approach along ``axis`` (``sign``: which way) passes the base faces
    lying radially apart from the part by under twice ``tol``, more than 2 mm from
    ``pose`` (inf: none): their distance with the part moved to where the nearest of them
    is beside the part face nearest it radially (``CollisionWorld.passed_distance``). No
    move comes nearer them than their radial and axial gaps allow, so the least distance
    of the way lies between that bound and the distance met; None where that leaves it
    open (a contact tolerance or a printed digit between them: a coarse polygon's rim,
    whose radial gap is its chord's, or nothing beside them met)."""
    if not split.passing:
        return math.inf
    t_lo, t_hi = (_PASSING_FAR_M, far) if sign > 0.0 else (-far, -_PASSING_FAR_M)
    bound, met = collision.passed_distance(part, split, pose, axis, t_lo, t_hi, 2.0 * tol)
    if math.isnan(met):
        return None
    value = met if met < math.inf else bound
    return value if _told_alike(bound, value, tol) else None


def _told_alike(low: float, high: float, tol: float) -> bool:
    """Whether every value in [low, high] makes the same passing warnings (``scene_warnings``:
    under twice ``tol`` the turned approaches run; under ``tol`` it is warned of, printed
    to two digits)."""
    if any(low < limit <= high for limit in (tol, 2.0 * tol)):
        return False
    return low >= tol or f"{low * 1e3:.2g}" == f"{high * 1e3:.2g}"


def _floating_final(collision: CollisionWorld, body, i: int, k: int, mate: cn.Mate, pose,
                    final_distance: float) -> list[str]:
    """A final pose on an axis that nothing of the base but the axis's own faces touches (a
    pin 10 mm up its bore, short of the bore's end): a part slid along the axis is placed
    as it passes, floating, and nothing else tells a seat from a clearance (an engineer's
    trial). Warned of where that gap is over ``final_tolerance``'s distance, with how far
    along the axis the base would stop the part each way."""
    gap = collision.base_distance(body.name, k, pose, SKIP_COAXIAL)
    if not final_distance < gap < math.inf:
        return []
    axis, stops = mate.base_dirs[0], []
    limit = collision.base_radius + body.reach_from_origin
    for sign, way in ((-1.0, "against"), (1.0, "along")):
        s, d = 0.0, gap
        for _ in range(_APPROACH_STEPS):
            s += d
            if s > limit:
                break
            moved = Pose(tuple(p + sign * s * a for p, a in zip(pose.position, axis)),
                         pose.rotation)
            d = collision.base_distance(body.name, k, moved, SKIP_COAXIAL)
            if d <= _APPROACH_TOL_M:
                stops.append(f"{s * 1e3:.3g} mm {way} its base direction")
                break
    where = (f"the base would stop it {' or '.join(stops)}" if stops
             else "nothing of the base stops it either way along the axis")
    return [f"parts[{i}].assembly.final_pose: leaves {body.name} {gap * 1e3:.3g} mm clear of "
            f"every face of the base but {mate.name}'s, over final_tolerance.distance "
            f"({final_distance * 1e3:.3g} mm): a part slid along {mate.name} is placed there "
            f"as it passes, floating; {where}: if it should rest on a shoulder or a bore's "
            "end, move the pose there"]


# An approach passing the base this near (m) while still this far from the pose is passing
# it (a pin its bore's rim), not arriving (``scene_warnings``: a fit tighter than the
# contact tolerance).
_PASSING_FAR_M = 0.002
# The approach of ``_depth_into_base``: its contact tolerance (m) and its step budget.
_APPROACH_TOL_M = 1e-5
_APPROACH_STEPS = 5000
# A base face radially farther than this (m) from a part moved along an axis is left out of
# the approach's steps (``axial_split``): twice its contact tolerance, so it can neither
# end an approach nor be met.
_APART_M = 2.0 * _APPROACH_TOL_M


def _overlap(a: tuple[list[float], list[float]], b: tuple[list[float], list[float]]) -> float:
    """How deep two boxes overlap: the least of their overlaps along the axes (<= 0 apart)."""
    return min(min(a[1][k], b[1][k]) - max(a[0][k], b[0][k]) for k in range(3))


def _diagonal(box: tuple[list[float], list[float]]) -> float:
    return math.sqrt(sum((box[1][k] - box[0][k]) ** 2 for k in range(3)))


def _sunk(collision: CollisionWorld, body, box, environment: list, gravity) -> \
        tuple[float, int] | None:
    """How far inside an environment object a resting part starts, and which: the part is
    let down onto it from above (against gravity, from beyond both boxes, by its distance
    each step), and stops that far short of its pose. None where its box is not inside an
    object's box by more than a millimetre (a part lying on the table is not), or where it
    gets there. (fcl's distance is 0 for touching and overlapping alike.)"""
    near = tuple(k for k, other in enumerate(environment)
                 if _overlap(box, other) > _INSIDE_BASE_M)
    g = math.sqrt(sp.dot(gravity, gravity))
    if not near or g == 0.0:
        return None
    up = sp.scale(gravity, -1.0 / g)
    pose = body.initial_pose
    s = 1.5 * (_diagonal(box) + max(_diagonal(environment[k]) for k in near)) + 0.01
    which = near[0]
    for _ in range(_APPROACH_STEPS):
        moved = Pose(tuple(p + s * u for p, u in zip(pose.position, up)), pose.rotation)
        d, which = collision.distance_to_environment(body.name, moved, near)
        if d <= _APPROACH_TOL_M or s <= 0.0:
            break
        s = max(0.0, s - d)
    return (s, which) if s > _INSIDE_BASE_M else None




def mesh_scale_warnings(scene: Scene, doc: dict | None) -> list[str]:
    """A part or the base part over 5 m across: a mesh file (``shape.file`` with no
    ``shape.units``, or such a child of a compound shape) drawn in other units than the
    session's, or, of shapes of its own, the session's numbers in another unit. (A user's trial: a mesh drawn in
    millimetres in a metre session was warned of only as starting 6e+04 mm inside the
    table, and its grab refused as too heavy.)"""
    if not doc:
        return []
    units = doc.get("units", "m")
    listed = [(f"parts[{i}]", p) for i, p in enumerate(doc.get("parts") or [])
              if isinstance(p, dict)]
    if isinstance(doc.get("base"), dict):
        listed.append(("base", doc["base"]))
    bodies = {b.name: b for b in scene.parts}
    if scene.base is not None:
        bodies[scene.base.name] = scene.base
    out = []
    for where, item in listed:
        shape, body = item.get("shape"), bodies.get(str(item.get("name")))
        meshes = _unitless_meshes(shape, f"{where}.shape")
        given = _meshes_with_units(shape, f"{where}.shape")
        if body is None:
            continue
        across = oversize_across(body, UNIT_TO_M[units])
        if across is None:
            continue
        if not (meshes or given):
            # Shapes of its own (box, cylinder, ...): the session's numbers in another unit
            # than its "units" (a researcher's trial: a session in mm written as "units":
            # "m" built an 80 m pin of 23,533 t and a 1.2 km table, and said nothing).
            out.append(f"{where}.shape: the part is {across} {units} across, too large for "
                       f"a part of an assembly: are the session's numbers in another unit "
                       f"than its \"units\": \"{units}\"? (its mass and inertia follow its "
                       "size)")
            continue
        if not meshes:
            # Every mesh gives its units, and the part is still that large (an engineer's
            # trial: an STL drawn in mm given "units": "m" made a 50 m pin of 4e7 kg,
            # seen only through what followed: a misfit, a sunk part, a refused grab).
            named = ", ".join(f"{at} ({name!r} in {unit})" for at, name, unit in given)
            out.append(f"{where}.shape: the part is {across} {units} across, too large for "
                       f"a part of an assembly, from meshes whose units are given: {named}: "
                       "are those units right? (its mass and inertia follow its size)")
            continue
        if len(meshes) == 1 and meshes[0][0] == f"{where}.shape":
            out.append(f"{where}.shape: the mesh {meshes[0][1]!r} is {across} {units} "
                       "across, too large for a part of an assembly: drawn in millimetres? "
                       "give shape.units (its mass and inertia follow its size)")
        else:
            # A compound: the part is that large; its mesh children without units are the
            # likely cause (each child's shape.units applies to it alone).
            named = ", ".join(f"{at} ({name!r})" for at, name in meshes)
            out.append(f"{where}.shape: the part is {across} {units} across, too large for a "
                       f"part of an assembly, with mesh children of no units: {named}: "
                       "drawn in millimetres? give each one's shape.units (its mass and "
                       "inertia follow its size)")
    # An environment object (a table, a floor) over 50 m across: the same slip (a review: a
    # table of 1200 x 800 x 40 in a session in "m" was not warned of).
    f = UNIT_TO_M[units]
    for i, (item, body) in enumerate(zip([e for e in doc.get("environment") or []
                                          if isinstance(e, dict)], scene.environment)):
        size = [body.bbox_max[k] - body.bbox_min[k] for k in range(3)]
        if max(size) > _ENVIRONMENT_LARGEST_M:
            across = " x ".join(f"{extent / f:.3g}" for extent in size)
            out.append(f"environment[{i}].shape: {body.name} is {across} {units} across: "
                       f"are the session's numbers in another unit than its \"units\": "
                       f"\"{units}\"?")
    return out


# An environment object larger than this across (m) is taken for a slip of units.
_ENVIRONMENT_LARGEST_M = 50.0


def body_count(faces: np.ndarray) -> int:
    """How many separate bodies a mesh's faces make (faces that share a vertex are one):
    labels spread along the faces' edges to the least, with pointer jumping, in numpy (the
    commands keep scipy, whose graph search trimesh uses, out of their imports)."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return 0
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    label = np.arange(int(faces.max()) + 1)
    while True:
        least = np.minimum(label[a], label[b])
        spread = label.copy()
        np.minimum.at(spread, a, least)
        np.minimum.at(spread, b, least)
        spread = spread[spread]
        if np.array_equal(spread, label):
            break
        label = spread
    return len(np.unique(label[a]))


def mesh_body_warnings(scene: Scene, doc: dict | None) -> list[str]:
    """A part drawn by one mesh file that holds several separate bodies (a CAD user's
    trial: an assembly exported as one STL made one part of twice the mass, its centre of
    mass in the air between them, and nothing said so). A compound's children are separate
    on purpose, and the base and the environment are fixtures: only a part's own file."""
    out = []
    bodies = {b.name: b for b in scene.parts}
    for i, item in enumerate((doc or {}).get("parts") or []):
        if not isinstance(item, dict) or not isinstance(item.get("shape"), dict):
            continue
        shape, body = item["shape"], bodies.get(str(item.get("name")))
        if shape.get("type") != "mesh" or body is None:
            continue
        count = body_count(body.faces)
        if count > 1:
            out.append(f"parts[{i}].shape: the mesh {shape.get('file')!r} holds {count} "
                       f"separate bodies, taken as one rigid part of {body.mass_kg:.4g} kg "
                       "with one centre of mass between them: an assembly exported as one "
                       "file? give each part a file of its own")
    return out


def _unitless_meshes(shape, at: str) -> list[tuple[str, str]]:
    """The mesh files of a shape (itself, or the children of a compound, at any depth)
    that give no ``units``: ``(where, file)``."""
    if not isinstance(shape, dict):
        return []
    if shape.get("type") == "mesh":
        return [] if "units" in shape else [(at, str(shape.get("file")))]
    if shape.get("type") == "compound" and isinstance(shape.get("children"), list):
        return [found for i, child in enumerate(shape["children"])
                for found in _unitless_meshes(child, f"{at}.children[{i}]")]
    return []


def _meshes_with_units(shape, at: str) -> list[tuple[str, str, str]]:
    """The mesh files of a shape that give their ``units``: ``(where, file, units)``."""
    if not isinstance(shape, dict):
        return []
    if shape.get("type") == "mesh":
        return [(at, str(shape.get("file")), str(shape["units"]))] if "units" in shape else []
    if shape.get("type") == "compound" and isinstance(shape.get("children"), list):
        return [found for i, child in enumerate(shape["children"])
                for found in _meshes_with_units(child, f"{at}.children[{i}]")]
    return []


def mass_warnings(scene: Scene, doc: dict | None, *, as_set: bool = False) -> list[str]:
    """What a part's mass says of a slip in its units: a ``mass`` alone (spread evenly)
    making no solid's density; ``mass_properties`` whose mass makes no solid's density in
    its closed mesh, whose inertia is far (100 times) from that shape's at that mass
    spread evenly, or is more than any body of that shape can have (a moment above the
    mass times its farthest vertex from the centre of mass squared), or whose centre of
    mass lies outside the shape's box. Grams for kilograms, kg mm^2 for kg m^2. Each names
    the session's field (``parts[2].mass``), or, ``as_set``, the key a what-if's ``--set``
    gives it by (``parts.spacer.mass``: an engineer's trial read the index as another part)."""
    listed = list((doc or {}).get("parts") or [])
    index = {str(p.get("name")): i for i, p in enumerate(listed)}
    out = []
    lo, hi = _DENSITY_RANGE
    for body in scene.parts:
        i = index.get(body.name)
        part = listed[i] if i is not None else {}
        if not ("mass" in part or "mass_properties" in part):
            continue
        where = (f"parts.{body.name}" if as_set else f"parts[{i}]") + \
            f".{'mass' if 'mass' in part else 'mass_properties'}"
        closed = _closed(body.faces)
        volume = _volume(body.vertices, body.faces) if closed else 0.0
        if volume > 0.0 and not lo <= body.mass_kg / volume <= hi:
            out.append(f"{where}: {body.mass_kg:g} kg in {volume * 1e6:.3g} cm^3 is "
                       f"{body.mass_kg / volume:.3g} kg/m^3, no solid's (steel is about "
                       "7850); masses are in kg whatever the session's units")
            continue
        if "mass_properties" not in part:
            continue
        reach = body.radius_about_cm
        top = max(body.principal_moments)
        if top > 1.01 * body.mass_kg * reach * reach:
            out.append(f"{where}: a principal moment of inertia of {top:.3g} kg m^2 is more "
                       f"than any body of this shape and mass can have ({body.mass_kg:g} kg "
                       f"within {reach * 1e3:.3g} mm of its centre of mass: at most "
                       f"{body.mass_kg * reach * reach:.3g}); inertia in other units?")
            continue
        cm = body.center_of_mass
        if any(not body.bbox_min[k] - 1e-9 <= cm[k] <= body.bbox_max[k] + 1e-9
               for k in range(3)):
            out.append(f"{where}: the centre of mass "
                       f"({', '.join(f'{c * 1e3:.3g}' for c in cm)}) mm in the part's axes "
                       "lies outside the part's shape; in other units, or other axes?")
            continue
        if volume > 0.0:
            ratio = sum(body.principal_moments) / even_inertia_trace(
                body.vertices, body.faces, body.mass_kg / volume)
            if not 0.01 <= ratio <= 100.0:
                out.append(f"{where}: its inertia is {ratio:.3g} times that of its shape "
                           "at its mass spread evenly; in other units (kg mm^2 for kg "
                           "m^2 is a million)?")
    return out


def _volume(vertices, faces) -> float:
    """The volume a closed mesh encloses (m^3): its signed tetrahedra from the origin."""
    v = vertices[faces]
    return float(dots(v[:, 0], np.cross(v[:, 1], v[:, 2])).sum()) / 6.0


def _overlapping_pairs(boxes: list[tuple[list[float], list[float]]]) -> list[tuple[int, int]]:
    """Pairs of boxes overlapping by more than a millimetre, by a sweep along x (a scene of
    200 parts lying apart asks a few hundred pairs, not 20,000)."""
    order = sorted(range(len(boxes)), key=lambda k: boxes[k][0][0])
    out = []
    for n, a in enumerate(order):
        for b in order[n + 1:]:
            if boxes[b][0][0] >= boxes[a][1][0] - _INSIDE_BASE_M:
                break
            if _overlap(boxes[a], boxes[b]) > _INSIDE_BASE_M:
                out.append((min(a, b), max(a, b)))
    return sorted(out)


# The most points of a part held to another's solid (``_depth_inside``), and about how
# many are spread over its faces besides its vertices.
_INSIDE_POINTS = 512
_SURFACE_POINTS = 512


def _surface_points(vertices: np.ndarray, faces: np.ndarray, n: int) -> np.ndarray:
    """Points spread over a mesh's faces about as far apart as ``n`` evenly spread would
    be: the centroids of a k x k subdivision of each face, k its longest edge over that
    spacing (at least one a face: a long thin face gets its length's worth)."""
    tri = vertices[faces]
    area = 0.5 * norms(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    total = float(area.sum())
    if not total > 0.0:
        return np.zeros((0, 3))
    spacing = np.sqrt(total / n)
    longest = np.max(norms(tri - np.roll(tri, 1, axis=1)), axis=1)
    ks = np.maximum(1, np.ceil(longest / spacing)).astype(int)
    out = []
    for k in np.unique(ks):
        ij = [(i + 1 / 3, j + 1 / 3) for i in range(k) for j in range(k - i)] \
            + [(i + 2 / 3, j + 2 / 3) for i in range(k - 1) for j in range(k - 1 - i)]
        u, v = (np.array(c) / k for c in zip(*ij))
        t = tri[ks == k]
        out.append((t[:, None, 0] + u[None, :, None] * (t[:, None, 1] - t[:, None, 0])
                    + v[None, :, None] * (t[:, None, 2] - t[:, None, 0])).reshape(-1, 3))
    return np.concatenate(out) if out else np.zeros((0, 3))


def _depth_inside(collision: CollisionWorld, body, other, *, base: bool = False,
                  poses: tuple[Pose, Pose] | None = None) -> float:
    # (``base``: ``other`` is the base part; ``poses``: the two's, if not their start poses.)
    """How deep the deepest point of ``body``'s surface lies inside ``other`` at their
    start poses (its distance to the other's surface; 0 if none is inside): its vertices
    and points spread over its faces (``_surface_points``: two bars laid across each other
    have no vertex in the other), those within the other's box that the other's surface
    winds about, each measured by fcl. A part in a tube's bore or an L-bracket's corner
    has no point inside the other's solid, so it is not taken for one inside it (bringing
    it in along a line, the first version, went through the walls)."""
    if not _closed(other.faces):
        return 0.0  # an open mesh (a tray, a cover) has no inside to be in
    pose, there = poses or (body.initial_pose, other.initial_pose)
    to_other = there.inverse().compose(pose)
    points = posed_points(np.concatenate([body.vertices, _surface_points(
        body.vertices, body.faces, _SURFACE_POINTS)]), to_other)
    lo, hi = np.array(other.bbox_min), np.array(other.bbox_max)
    points = points[np.all((points > lo) & (points < hi), axis=1)]
    if len(points) == 0:
        return 0.0
    if len(points) > _INSIDE_POINTS:
        # Fine meshes: an even sample, so the winding costs at most this many points times
        # the other's triangles (2,000 vertices against 20k triangles took 8 s).
        points = points[np.linspace(0, len(points) - 1, _INSIDE_POINTS).astype(int)]
    inside = points[winding(other.vertices, other.faces, points) > 0.5]
    if len(inside) > 64:  # each measured by an fcl query: an even sample of them
        inside = inside[np.linspace(0, len(inside) - 1, 64).astype(int)]
    return max((collision.point_distance(other.name, tuple(map(float, q)), base=base)
                for q in inside), default=0.0)


def scene_warnings(scene: Scene, collision: CollisionWorld,
                   doc: dict | None = None) -> list[str]:
    """What the built scene shows that its document does not (``vade-record`` prints them
    with the session's own warnings): a constraint's part side on no face of the part; a
    final pose on none of the part's constraints, or
    inside the base along the one it is on (never reached by sliding); a part resting at
    the start in mid-air (resting parts do not fall until touched). ``doc``, the session
    document, numbers the parts as the session lists them (the scene sorts them by name)."""
    listed = {str(p.get("name")): i for i, p in enumerate((doc or {}).get("parts") or [])}
    index = {b.name: listed.get(b.name, k) for k, b in enumerate(scene.parts)}
    # A mesh in other units first: what follows from it (a misfit, a part inside the base
    # or the table) is warned of after it.
    out = mesh_scale_warnings(scene, doc) + mesh_body_warnings(scene, doc)
    counters = dict(collision.stats)  # a run's counters count the run's own queries
    for body in scene.parts:
        i = index[body.name]
        for k, mate in enumerate(body.assembly.mates if body.assembly else ()):
            if mate.kind == "axis" and mate.misfit:
                # (An engineer's trial: a pin wider than its bore fell through the boss, a
                # sleeve narrower than its shaft passed over it, nothing said.)
                low, high, wall = mate.misfit
                then = "it is not put onto the constraint when let go" \
                    if scene.physics.coaxial_fit == "radial" \
                    else "with coaxial_fit faces it is put on, and passes through the wall"
                out.append(f"parts[{i}].assembly.constraints[{k}]: {body.name} does not fit "
                           f"{mate.name}: a face of it lies {low * 1e3:.4g} to "
                           f"{high * 1e3:.4g} mm from the axis, across the wall of the shaft "
                           f"or bore at {wall * 1e3:.4g} mm (a pin wider than its bore, a "
                           f"sleeve narrower than its shaft, a part with no bore); {then}: "
                           "check the shapes, point, direction and radius")
            elif len(mate.part_feature_faces) == 0:
                # The base's side is refused so (scene.py); a part's bore may be a little
                # wider than the shaft's radius, so its side is only warned of.
                where = f"parts[{i}].assembly.constraints[{k}].part"
                if mate.kind == "axis":
                    # The face that comes nearest to lying within: its farthest corner.
                    _, most = cn.radial_extent(body.vertices, body.faces,
                                               mate.part_points[0], mate.part_dirs[0])
                    reach = float(most.min())
                    out.append(f"{where}: no face of {body.name} lies within {mate.name}'s "
                               f"radius ({mate.radius * 1e3:.4g} mm) of its axis: the "
                               f"nearest reaches {reach * 1e3:.4g} mm from it: check point, "
                               "direction and radius (with a clearance, give the larger of "
                               "the shaft's and the bore's)")
                else:
                    out.append(f"{where}: no face of {body.name} lies in {mate.name}'s "
                               "plane, facing out along its normal: check point and normal")
        assembly = body.assembly
        if assembly is None or assembly.final_pose is None or not assembly.mates:
            continue
        final = assembly.final_pose
        tol = scene.physics.contact_tolerance
        if assembly.final_distance < tol:
            # (An engineer's trial: final_tolerance 0.01 mm never placed a pin the base
            # stopped 0.05 mm short of its seat, and nothing said why.)
            out.append(f"parts[{i}].assembly.final_tolerance.distance "
                       f"({assembly.final_distance * 1e3:.3g} mm) is under "
                       f"physics.contact_tolerance ({tol * 1e3:.3g} mm): a part the base "
                       "stops comes to rest up to that far short of where it touches, so "
                       "it may never come within it of its final pose")
        clear = collision.distance_to_base(body.name, final)
        if clear > max(_FINAL_CLEAR_M, 0.5 * body.reach_from_origin):
            # (An engineer's trial: a final pose written in world coordinates, 740 mm past
            # the bore's end, was "never placed" without a reason.)
            out.append(f"parts[{i}].assembly.final_pose: puts {body.name} "
                       f"{clear * 1e3:.3g} mm from the base part: a final pose is in the "
                       "base's frame, not the world's; is it?")
            continue
        # With final_tolerance.angle_deg 180 the orientation is not asked for: a part on the
        # constraint reaches the pose's place whatever its turn (and is then turned to it).
        any_turn = assembly.final_angle >= math.pi
        offs = []
        for k, mate in enumerate(assembly.mates):
            angle, distance = cn.misalignment(mate, final)
            offs.append((max(_over(distance, mate.distance_tolerance),
                             0.0 if any_turn else _over(angle, mate.angle_tolerance)),
                         k, angle, distance))
        worst, k, angle, distance = min(offs)
        mate = assembly.mates[k]
        if worst <= 1.0 and angle > mate.angle_tolerance:
            out.append(f"parts[{i}].assembly.final_pose: turned {math.degrees(angle):.3g} deg "
                       f"off {mate.name} (tolerance {math.degrees(mate.angle_tolerance):.3g} "
                       f"deg): with final_tolerance.angle_deg 180 the part is placed where it "
                       "passes the pose's place and then turned to that orientation, off its "
                       "constraint")
            continue
        if worst > 1.0:
            out.append(f"parts[{i}].assembly.final_pose: on none of {body.name}'s constraints "
                       f"(nearest {mate.name}: {distance * 1e3:.3g} mm and "
                       f"{math.degrees(angle):.3g} deg off; tolerances "
                       f"{mate.distance_tolerance * 1e3:.3g} mm, "
                       f"{math.degrees(mate.angle_tolerance):.3g} deg): the part cannot slide "
                       "or turn into it; it is placed only if let go within final_tolerance "
                       "of it")
            continue
        snapped = cn.recognise(mate, final) or final
        passes: list[float] = []
        depth = _depth_into_base(collision, body.name, k, mate, snapped,
                                 body.reach_from_origin, passes, tol)
        if depth > _INSIDE_BASE_M:
            out.append(f"parts[{i}].assembly.final_pose: puts {body.name} about "
                       f"{depth * 1e3:.2g} mm into the base (on {mate.name}): the base stops "
                       "the part that far short of it, so it is placed only if that gap is "
                       "within final_tolerance")
        if mate.kind == "axis" and passes and min(passes) < 2.0 * tol:
            # A polygon's clearance to another turns with it, and a part keeps the angle
            # about the axis it is let go at: a few angles (a 32-gon repeats every 11.25
            # degrees).
            u, c = mate.base_dirs[0], mate.base_points[0]
            for angle in (0.05, 0.1, 0.15):
                q = sp.quat_unit_axis_angle(u, angle)
                turned = Pose(sp.add(c, sp.quat_rotate(q, sp.sub(snapped.position, c))),
                              sp.quat_mul(q, snapped.rotation))
                _depth_into_base(collision, body.name, k, mate, turned,
                                 body.reach_from_origin, passes, tol)
        if mate.kind == "axis" and depth <= _INSIDE_BASE_M:
            out += _floating_final(collision, body, i, k, mate, snapped,
                                   assembly.final_distance)
        clear = min(passes, default=math.inf)
        if clear < tol and scene.physics.passing_contact == "block":
            # (An engineer's trial: a pin 0.05 mm clear of its bore's rim was held there,
            # never placed, and nothing said why.)
            # (With coaxial_fit radial, what passes within the tolerance is not a fit about
            # the axis: faces beside each other, a key in its keyway.)
            radial = scene.physics.coaxial_fit == "radial"
            what, or_radial = ("", "") if radial \
                else (" (a bore's rim?)", ", or physics.coaxial_fit radial")
            out.append(f"parts[{i}].assembly.constraints[{k}]: {body.name} passes the base "
                       f"{clear * 1e3:.2g} mm clear on its way along {mate.name} to its "
                       f"final pose{what}, within physics.contact_tolerance "
                       f"({tol * 1e3:.2g} mm): it is blocked there; set contact_tolerance "
                       f"under {clear * 1e3:.2g} mm (in the session's units){or_radial}")
    # What a resting part can lie on: the environment, a fixed base, another part.
    fixed = [world_box(b, b.initial_pose) for b in _fixed_bodies(scene)]
    boxes = {b.name: world_box(b, b.initial_pose) for b in scene.parts}
    for body in scene.parts:
        if body.initial_mode is not Mode.STATIC or len(fixed) + len(boxes) < 2:
            continue
        box = boxes[body.name]
        # Most parts lie on the table: the other parts are looked at only for those that
        # do not (a 200-part scene asks 200 boxes, not 40,000 pairs).
        gap = min((_box_gap(box, other) for other in fixed), default=math.inf)
        if gap > _FLOATING_M:
            gap = min([gap] + [_box_gap(box, other) for name, other in boxes.items()
                               if name != body.name])
        if gap > _FLOATING_M:
            i = index[body.name]
            out.append(f"parts[{i}].pose: {body.name} starts at least {gap * 1e3:.3g} mm from "
                       "the table and every other object, and stays there until a hand "
                       "touches it: resting parts do not fall")
            continue
        sunk = _sunk(collision, body, boxes[body.name], fixed[:len(scene.environment)],
                     scene.physics.gravity)
        if sunk is not None:
            depth, which = sunk
            out.append(f"parts[{index[body.name]}].pose: {body.name} starts about "
                       f"{depth * 1e3:.2g} mm inside {collision.environment_name(which)} "
                       "(let down onto it from above, it stops that far short of its pose)")
    out += mass_warnings(scene, doc)
    # Parts that start inside one another stay so: parts do not collide with each other.
    parts = list(scene.parts)
    part_boxes = [boxes[b.name] for b in parts]
    for j, k in _overlapping_pairs(part_boxes):
        first, second = sorted((parts[j], parts[k]), key=lambda b: index[b.name])
        depth = max(_depth_inside(collision, first, second),
                    _depth_inside(collision, second, first))
        if depth > _INSIDE_BASE_M:
            out.append(f"parts[{index[first.name]}].pose: {first.name} and {second.name} "
                       f"(parts[{index[second.name]}]) start about {depth * 1e3:.2g} mm "
                       "into each other; parts do not collide with each other, so they "
                       "stay so until a hand moves one")
    # A part inside a fixed base (whose start pose is known: a held one follows the hand).
    if scene.base is not None and scene.base_fixed:
        base_box = world_box(scene.base, scene.base.initial_pose)
        for body in parts:
            if _overlap(boxes[body.name], base_box) <= _INSIDE_BASE_M:
                continue
            depth = max(_depth_inside(collision, body, scene.base, base=True),
                        _depth_inside(collision, scene.base, body))
            if depth > _INSIDE_BASE_M:
                out.append(f"parts[{index[body.name]}].pose: {body.name} starts about "
                           f"{depth * 1e3:.2g} mm inside the base part "
                           f"({scene.base.name}); it is not pushed out, and stays so until a "
                           "hand moves it")
    collision.stats.update(counters)
    return out


# A release counts as a miss of a constraint when it was within this many times both of its
# tolerances (50 mm and 100 deg at the defaults): near enough to have been meant for it.
_NEAR = 10.0


def _over(value: float, tolerance: float) -> float:
    return value / tolerance if tolerance > 0.0 else (0.0 if value == 0.0 else math.inf)


def describe_miss(miss: dict) -> str:
    """One line: ``frame 84 (t = 1.400 s): peg released 6.1 mm and 2.0 deg off
    bore_on_shaft (tolerances 5 mm, 5 deg)``."""
    beyond = miss.get("beyond_end_m") or 0.0
    end = f", {beyond * 1e3:.3g} mm beyond its end" if beyond > 0.0 else ""
    misfit = miss.get("misfit_m")
    if misfit:
        end = (f", which it does not fit (a face of it {misfit[0] * 1e3:.4g} to "
               f"{misfit[1] * 1e3:.4g} mm from the axis, across the wall at "
               f"{misfit[2] * 1e3:.4g} mm)")

    if miss.get("pulled_off"):
        end = (", where gravity pulls it off a face of it (the base leans so that it does "
               "not press the part onto each)")

    def small(value: float) -> float:
        return 0.0 if abs(value) < 1e-9 else value  # round-off, not an offset (3.9e-14 mm)
    return (f"frame {miss['frame']} (t = {miss['time_s']:.3f} s): {miss['part']} released "
            f"{small(miss['off_distance_m']) * 1e3:.3g} mm and "
            f"{small(miss['off_angle_deg']):.3g} deg off "
            f"{miss['nearest_constraint']}{end} (tolerances "
            f"{miss['distance_tolerance_m'] * 1e3:.3g} mm, {miss['angle_tolerance_deg']:.3g} "
            f"deg): {miss['cause']}{_landed_text(miss.get('landed'))}")


def miss_line(miss: dict) -> str:
    """The line a command prints of a release miss: ``not on a constraint: ...``, or, for a
    part that then landed on one in flight, ``let go off a constraint, then landed on one:
    ...`` (an engineer's trial: a pin dropped into its bore and placed read as a failure)."""
    head = "let go off a constraint, then landed on one" if miss.get("landed") \
        else "not on a constraint"
    return f"{head}: {describe_miss(miss)}"


def _landed_text(landing: dict | None) -> str:
    if not landing:
        return ""
    where = "at its final pose" if landing["mode"] == "PLACED" else "on a constraint"
    return (f"; then landed {where} in flight at frame {landing['frame']} "
            f"({landing['cause']}, {landing['mode']})")


def _kept_after(writer: RecordingWriter, target: Path | None, partial: Path,
                exc: VadeError, what: str) -> VadeError | None:
    """A run that failed part way: its file closed, with why it stopped; the error to raise,
    saying where the frames written are kept, or None to raise ``exc`` as it is (no frame
    was written: nothing is left behind)."""
    try:
        if writer.frames == 0 and target is not None:
            writer.discard()
            return None
        writer.close(stopped=exc.describe())
    except RecordingError:
        pass  # (the file could not be finished either: ``writer.unfinished``, below)
    if writer.frames == 0 or (writer.unfinished and target is None):
        return None  # (nothing kept; or written in place, to a device that took what it took)
    if writer.unfinished:
        # (A full disk: frames counted were not all written, and the file has no summary.)
        kept = (f"the {what}frames written before it are kept in {partial}, cut short: "
                "vade-replay reads them")
    else:
        kept = (f"the {what}frame before it is" if writer.frames == 1
                else f"the {writer.frames} {what}frames before it are") + f" kept in {partial}"
    exc.message += f" ({kept})"
    return type(exc)(exc.message, file=exc.file, field=exc.field, frame=exc.frame,
                     item=exc.item)


def _interrupted_when_complete(path: Path, kind: type[KeyboardInterrupt] = KeyboardInterrupt
                               ) -> KeyboardInterrupt:
    """A Ctrl-C (or SIGTERM: ``kind``) that came after the last frame, while the file was
    being finished: the run stops there (a study's loop of runs with it), its file
    complete."""
    stop = kind()
    stop.add_note(f"the run had reached its end: {path} is complete")
    return stop


def _close_stopped(writer: RecordingWriter, exc: BaseException) -> None:
    """Close the file of a run that ``exc`` stops, saying why; an interrupt stays the
    interrupt where the file cannot be finished either (a full disk: a review saw Ctrl-C
    turned into exit 2 and its "kept in" note lost)."""
    try:
        writer.close(stopped=_why_stopped(exc))
    except RecordingError:
        if not isinstance(exc, (KeyboardInterrupt, VadeError)):
            raise


def _why_stopped(exc: BaseException) -> str:
    """What a recording that stopped early keeps as its reason (``STOPPED_METADATA``)."""
    if isinstance(exc, Terminated):
        return "terminated"
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    return f"{type(exc).__name__}: {exc}"[:500]


def _kept(frames: int, partial: Path) -> str:
    """Where an interrupted run's frames are (``run`` prints the note)."""
    kept = "the frame written so far is" if frames == 1 \
        else f"the {frames} frames written so far are"
    return f"{kept} kept in {partial}"


@dataclass
class ReplayFrame:
    """One replayed frame: what was recorded, what the replay derived, and the check."""

    recorded: RecordedFrame
    replayed: FrameRecord
    # The messages the replay derived: where the frame matched, the recorded ones (the same
    # values, checked without writing them); elsewhere, and with an output file, its own.
    derived: list[tuple[str, bytes]]
    divergence: Divergence | None


def replay_frames(recording: Recording, scene: Scene, *, check: bool = True,
                  collision: CollisionWorld | None = None) -> Iterator[ReplayFrame]:
    """Re-run a recording's inputs through ``scene``, comparing each frame's messages:
    ``replay`` without its summary and outputs, for a script of one's own (and for
    measuring the step with the check off)."""
    advance = Stepper(scene, collision or CollisionWorld(scene))
    encoder = codec.FrameEncoder(recording.parts_encoding)
    previous = None
    for recorded in recording.frames():
        replayed = advance(recorded.inputs)
        if check:
            ours = encoder.check(replayed, recorded.derived)  # as ``replay`` checks
            derived = recorded.derived if ours is None else ours
            divergence = None if ours is None else _divergence(
                recorded.inputs, recorded.derived, derived, replayed, previous)
        else:
            derived, divergence = encoder.derived_messages(replayed), None
        previous = replayed
        yield ReplayFrame(recorded, replayed, derived, divergence)


# Effective values that follow from fields: not a change of their own when one of these is
# overridden.
_DERIVED = {"slide_step_s": ("slide_integrator", "slide_max_step_s", "onbase_max_step_s"),
            "turn_step_s": ("turn_integrator", "turn_max_step_s", "onbase_max_step_s")}
# What a recording made before a physics key existed was made with: the behaviour that
# the key's other value keeps, for replaying such recordings as they were made.
_BEFORE_THE_KEY = {"slide_onset": "sub_step", "slide_off": "frame_end",
                   "final_pose_check": "frame_end", "block_cut": "both",
                   "block_event": "always", "flight_grace": "whole_base",
                   "coaxial_fit": "faces", "landing": "rests",
                   "contact_sweep": "frame_end", "velocities": "relative",
                   "snap_velocity": "zero", "release_point": "cm", "release_span_s": 0.0,
                   "environment_contact": "flying"}


def _step_in_effect(recorded: dict, bound: str, before: float):
    """The sub-step a recording without ``*_step_s`` metadata ran with: its own bound, else
    the shared one, else the default of the time (sliding 1/180 s, turning 1/120 s)."""
    for name in (bound, "onbase_max_step_s"):
        value = recorded.get(name)
        if value is not None:
            return value
    return before


# What a recording's ``versions`` metadata holds that decides a run's round-off: the
# machine (its libm and C library, the processor's fused multiply-adds) and the numerical
# packages (the scene's meshes and mass properties, fcl's distances).
_ROUND_OFF_VERSIONS = ("system", "machine", "libc", "cpu", "python", "numpy", "python-fcl",
                       "trimesh")


def made_elsewhere(recording: Recording) -> dict:
    """How the machine and packages a recording was made with differ from this run's, in
    what can change round-off: name -> {"recorded", "here"}. A recording from before a
    name was kept does not compare it."""
    recorded = recording.metadata.get("versions", {})
    here = package_versions()
    return {name: {"recorded": recorded[name], "here": here[name]}
            for name in _ROUND_OFF_VERSIONS
            if name in recorded and recorded[name] != here.get(name)}


def made_by_what_if(recording: Recording) -> dict | None:
    """The what-if a recording was written by (``vade-replay --set ... -o``): ``{"from":
    the recording it first changed, "overrides": {key: value}}`` (a what-if of a what-if's
    recording: both runs' changes, the later winning), or None for a recording
    ``vade-record`` made. Its session already holds the changes, so a replay of it matches
    like any other; this is what tells its rows apart from the original run's in a study
    (a researcher's trial: a what-if written with ``-o``, replayed, looked like the
    original). Metadata that does not read as such (edited by hand) is left out."""
    block = recording.metadata.get("session") or {}
    text = block.get("what_if")
    if text is None:
        return None
    try:
        overrides = json.loads(text)
    except ValueError:
        return None
    if not isinstance(overrides, dict) or not overrides:
        return None
    return {"from": str(block.get("what_if_of", block.get("replayed_from", ""))),
            "overrides": overrides}


def _what_if_metadata(recording: Recording, applied: dict) -> dict[str, str]:
    """What a regenerated recording's metadata says of the run that wrote it: the recording
    it was replayed from, and, for a what-if (or a recording one wrote, replayed again),
    its changes and the recording they were first made to (``made_by_what_if``)."""
    out = {"replayed_from": str(recording.path)}
    before = made_by_what_if(recording)
    overrides = {**(before["overrides"] if before else {}), **applied}
    if overrides:
        out["what_if"] = json.dumps(overrides, sort_keys=True)
        out["what_if_of"] = before["from"] if before else str(recording.path)
    return out


def physics_changes(recording: Recording, physics, applied: dict) -> dict:
    """Physics of a replay that differs from what ``recording`` was made with (its
    ``physics`` metadata; a key it lacks is what came before that key), leaving out what
    the overrides ``applied`` changed on purpose: what a newer version's defaults changed.
    Name -> ``{"recorded": ..., "now": ...}``. Empty for a recording without physics
    metadata (not written by vade-record)."""
    recorded = {}
    for name, text in (recording.metadata.get("physics") or {}).items():
        try:
            recorded[name] = codec.parse_json(text.encode())  # (orjson: faster than json)
        except ValueError:
            recorded[name] = text
    if not recorded:
        return {}
    for name, before in _BEFORE_THE_KEY.items():
        recorded.setdefault(name, before)
    # Before two hands lifted anything, they lifted what one hand lifts.
    if "two_hand_max_mass_kg" not in recorded and "one_hand_max_mass_kg" in recorded:
        recorded["two_hand_max_mass_kg"] = recorded["one_hand_max_mass_kg"]
    if "slide_step_s" not in recorded:
        recorded["slide_step_s"] = _step_in_effect(recorded, "slide_max_step_s", 1.0 / 180.0)
    if "turn_step_s" not in recorded:
        recorded["turn_step_s"] = _step_in_effect(recorded, "turn_max_step_s", 1.0 / 120.0)
    now = {name: codec.parse_json(text.encode())
           for name, text in physics_metadata(physics).items()}
    changed_on_purpose = {key[8:] for key in applied if key.startswith("physics.")}
    if "model" in changed_on_purpose:
        changed_on_purpose |= set(PAPER_DEFAULTS)
    out = {}
    for name in sorted(set(recorded) & set(now)):
        if name in changed_on_purpose or changed_on_purpose & set(_DERIVED.get(name, ())):
            continue
        if recorded[name] != now[name]:
            out[name] = {"recorded": recorded[name], "now": now[name]}
    return out


def as_made(recording: Recording) -> tuple[Session, dict | None]:
    """``recording``'s session set to build with the physics defaults it was made with (its
    ``physics`` metadata, ``physics_changes``), and the values restored: each default
    changed since then is the recorded one again, where the session leaves it to the
    default, before anything is built from it (a constraint's friction is the physics
    default only where the session gives it none). An effective sub-step is restored
    through the ``*_max_step_s`` that fixes it where the recorded schemes do not bring it.
    ``None`` for the values of a recording without physics metadata (not made by
    vade-record): its session as it is. The recording itself is not changed."""
    session = recording.session
    if not recording.metadata.get("physics"):
        return session, None
    block = session.doc.get("physics", {})
    f = UNIT_TO_M[session.doc.get("units", "m")]
    changes = physics_changes(recording, physics_from_doc(block, f), {})
    defaults = {name: change["recorded"] for name, change in changes.items()
                if name not in _DERIVED}
    _restorable(recording, session, block, defaults)
    try:
        brought = physics_from_doc(block, f, defaults=defaults)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"its physics metadata cannot be used by this version ({exc})",
                             file=str(recording.path), field="metadata physics") from None
    derived = {name.replace("_step_s", "_max_step_s"): change["recorded"]
               for name, change in changes.items()
               if name in _DERIVED and getattr(brought, name) != change["recorded"]}
    restored = {**defaults, **derived}
    if derived:  # (a review: an effective step of 0 or "abc" went on unchecked)
        _restorable(recording, session, block, restored)
    return replace(session, physics_defaults=restored), restored


def _restorable(recording: Recording, session: Session, block: dict, values: dict) -> None:
    """The physics values ``as_made`` restores, held to the session schema as if the
    session gave them: MCAP's metadata has no CRC (a user's trial changed "general" to
    "General" there and it ran unchecked). Those the schema does not list (this version's
    own bookkeeping) are left to ``physics_from_doc``."""
    allowed = load_schema("session.schema.json")["properties"]["physics"]["properties"]
    given = {name: value for name, value in values.items() if name in allowed}
    try:
        validate_physics({**block, **given}, file=str(recording.path))
    except SessionError as exc:
        raise RecordingError(f"its physics metadata cannot be restored: {exc.message} (the "
                             "file damaged, or made by another version): replay it without "
                             "--as-recorded", file=str(recording.path),
                             field=f"metadata {exc.field}" if exc.field else "metadata physics"
                             ) from None


def replay(recording: Recording, *, overrides: dict[str, str] | None = None,
           out: str | Path | None = None,
           on_frame: Callable[[ReplayFrame], None] | None = None,
           as_recorded: bool = False, replace_other: bool = True,
           absent_ok: bool = False, tolerance: Tolerance | None = None) -> RunSummary:
    """Replay a recording from its inputs alone and check every derived message.

    With ``overrides`` the scene's physics is changed first (a what-if replay); the check
    then reports where the changed run departs from the recording. With ``out`` the
    regenerated recording is written there (as ``out.partial``, renamed when complete; a
    run that fails part way keeps the partial file, as ``record`` does, and says so); the
    original file is never modified. With ``as_recorded`` the physics defaults are those
    the recording was made with (``as_made``), not this version's: a replay that proves an
    older recording still reproduces where a default moved since (with ``overrides``, a
    what-if of that physics). With ``replace_other`` False, a file at ``out`` other than
    this regenerated recording made again is refused first (``refuse_replacing``). With
    ``absent_ok``, an override of a part or tool the session does not have is left out
    (``RunSummary.not_applied``, and a warning) instead of an error: one of a study's
    sessions in a what-if of a part the others have. With ``tolerance`` a replay that is
    not the recording bit for bit is also held to it (``RunSummary.within_tolerance``):
    another machine's run of the same session.
    """
    if tolerance is not None and overrides:
        raise ConfigError(WHAT_IF_TOLERANCE, field="--tolerance")
    restored = None
    session = recording.session
    if as_recorded:
        # A what-if (``overrides``) then changes the physics the recording was made with.
        session, restored = as_made(recording)
    absent: dict[str, str] = {}
    session, applied = apply_overrides(session, overrides or {},
                                       absent=absent if absent_ok else None)
    scene = session.build_scene()
    collision = CollisionWorld(scene)
    summary = RunSummary(session.name, parts=[p.name for p in scene.parts], overrides=applied,
                         units=session.doc.get("units", "m"),
                         **_part_figures(scene),
                         physics_changed=physics_changes(recording, scene.physics, applied),
                         made_elsewhere=made_elsewhere(recording),
                         made_by_what_if=made_by_what_if(recording),
                         warnings=_introduced(session, recording.session) if applied else [],
                         not_applied=absent)
    summary.warnings += [f"--set {key} not applied: {why}" for key, why in absent.items()]
    if any(key.startswith("parts.") and key.endswith((".mass", ".density"))
           for key in applied):
        # (A mass is weighed against the part's shape: the scene's warning, not the file's.)
        was = set(mass_warnings(recording.session.build_scene(), recording.session.doc,
                                as_set=True))
        summary.warnings += [w for w in mass_warnings(scene, session.doc, as_set=True)
                             if w not in was]
    writer = None
    partial = target = None
    if out is not None:
        if Path(out).resolve() == recording.path.resolve():
            raise ConfigError("refusing to overwrite the recording being replayed", file=str(out))
        if Path(str(out) + ".partial").resolve() == recording.path.resolve():
            raise ConfigError("refusing to write over the recording being replayed (it is "
                              "this output's .partial file)", file=str(out))
        if not replace_other:
            note = refuse_replacing(out, session, scene)
            if note:
                print(f"note: {note}", file=sys.stderr)
        partial, target = partial_output(out)
        # A what-if's recording embeds the changed session, so that it replays itself.
        writer = RecordingWriter(partial, session, scene,
                                 extra_metadata=_what_if_metadata(recording, applied),
                                 parts_encoding=recording.parts_encoding)
    first_time = None
    unreadable = False  # a recorded frame could not be decoded to measure the departure
    open_misses: dict[str, int] = {}  # part -> its miss still in flight (``landed``)
    advance = Stepper(scene, collision)
    encoder = codec.FrameEncoder(recording.parts_encoding)
    previous: FrameRecord | None = None
    # A what-if also folds the recorded frames, decoded, for the comparison of analyses.
    decoded: FrameRecord | None = None
    # And measures how far its parts go from the recording's; a plain replay does from its
    # first divergence on (before it, the two are the same bits).
    departure: Departure | None = Departure() if applied else None
    beyond: str | None = None  # (with a tolerance: the first frame past it, and why)
    if applied:
        summary.recorded_analysis = SessionAnalysis()
    # Writing a recording, a Ctrl-C is held off to the end of the frame being written, and
    # of closing the file (as ``record`` holds it).
    with FrameBoundaryInterrupts() if writer is not None else contextlib.nullcontext() \
            as interrupts:
        try:
            try:
                # No generators between the reader and the check, and a ReplayFrame only for an
                # on_frame: ~2 us a frame less. Read, stepped and checked a batch at a time
                # (``_stepped``): ~25 % less a frame on a 2-core EPYC (vade-bench --replay).
                for batch, stepped in _stepped(recording.frames(), advance, _INPUTS):
                    i, n = 0, len(stepped)
                    while i < n:
                        checked = False
                        if writer is None and departure is None and on_frame is None:
                            # A plain replay while it matches: the frames that match and
                            # have no events checked and counted by compiled code, the
                            # next one (if any) checked there and seen to below.
                            j, messages, ours = codec.checked_run(encoder, batch, stepped, i,
                                                                  summary.analysis.add)
                            if j > i:
                                if first_time is None:
                                    first_time = stepped[i].time_ns
                                previous = stepped[j - 1]
                                summary.counted(j - i, previous, first_time, messages)
                            if j == n:
                                break
                            i, checked = j, True
                        recorded, replayed = batch[i], stepped[i]
                        i += 1
                        if writer is None:
                            if not checked:
                                # The check by bytes, and by value where they differ
                                # (``FrameEncoder.check``).
                                ours = encoder.check(replayed, recorded.derived)
                            derived = recorded.derived if ours is None else ours
                        else:
                            derived = encoder.derived_messages(replayed)
                            ours = None if recorded.derived == derived else derived
                        divergence = None if ours is None \
                            else _divergence(recorded.inputs, recorded.derived, derived, replayed,
                                             previous)
                        if divergence and not applied and departure is None \
                                and summary.first_divergence is None:
                            # The frame before matched: it is the recording's, decoded.
                            departure, decoded = Departure(), previous
                        previous = replayed
                        if first_time is None:
                            first_time = replayed.time_ns
                        summary.count(replayed, first_time)
                        summary.messages_checked += len(recorded.derived)
                        if replayed.events:
                            landed(summary.release_misses, open_misses, replayed)
                            summary.release_misses += release_misses(scene, replayed, first_time)
                            _opened(summary.release_misses, open_misses, replayed)
                        if departure is not None:
                            try:
                                decoded = recorded_record(recorded, decoded)
                            except VadeError as exc:
                                # A recorded message this cannot read (a plain replay names it as
                                # a divergence): the run goes on, without the comparisons.
                                if summary.recorded_analysis is not None:
                                    summary.warnings.append(
                                        "no comparison with the recording's analysis or "
                                        f"poses: its frame {recorded.inputs.frame} cannot be "
                                        f"read ({exc.message})")
                                summary.recorded_analysis = departure = decoded = None
                                unreadable = True
                            else:
                                departure.add(decoded, replayed)
                                if summary.recorded_analysis is not None:
                                    summary.recorded_analysis.add(decoded)
                        if divergence and summary.first_divergence is None:
                            summary.first_divergence = divergence.__dict__ | {
                                "text": divergence.describe()}
                        if applied and ours is not None and summary.first_event_change is None:
                            summary.first_event_change = _event_change(recorded.derived, ours,
                                                                        replayed, first_time)
                        if tolerance is not None and divergence and beyond is None:
                            why = frame_beyond(recorded.derived, ours, tolerance)
                            if why is not None:
                                t = (replayed.time_ns - (replayed.time_ns if first_time is None
                                                         else first_time)) / 1e9
                                beyond = f"frame {replayed.frame} (t = {t:.6f} s): {why}"
                        if writer:
                            writer.write_frame(replayed, derived)
                        if on_frame:
                            on_frame(ReplayFrame(recorded, replayed, derived, divergence))
                        if interrupts is not None:
                            interrupts.check()
                if interrupts is not None:
                    interrupts.check()  # (one that came as the recording's frames ran out)
            except RecordingError as exc:
                if exc.file is None:
                    exc.file = str(recording.path)
                raise
        except VadeError as exc:
            if writer is None or partial is None:
                raise
            kept = _kept_after(writer, target, partial, exc, "regenerated ")
            if kept is None:
                raise
            raise kept from None
        except BaseException as exc:
            if writer:
                _close_stopped(writer, exc)
                if isinstance(exc, KeyboardInterrupt) and writer.frames and partial is not None:
                    exc.add_note(_kept(writer.frames, partial))
            raise
        if writer and partial is not None:
            if summary.frames == 0:
                if target is not None:
                    writer.discard()  # nothing was written: leave nothing behind
                else:
                    writer.close()
            else:
                # The regenerated file keeps what the recording's run warned of, and that it
                # stopped early (or was cut short), with a what-if's own warnings.
                writer.warnings = list(recording.warnings) + summary.warnings
                stopped = recording.stopped or ("the recording replayed was cut short"
                                                if recording.truncated else None)
                writer.close(complete_as=target, stopped=stopped)
    if interrupts is not None and interrupts.pending and summary.frames:
        raise _interrupted_when_complete(target or partial, interrupts.pending)
    if summary.frames == 0:
        raise VadeError("recording holds no frames", file=str(recording.path))
    if applied and previous is not None and first_time is not None:
        # A what-if's own: a part that now falls past everything (the recording's are
        # repeated as recorded).
        summary.warnings += [w for w in fallen_past_everything(scene, previous, first_time)
                             if w not in recording.warnings]
    if recording.end_damaged is not None:
        summary.warnings.append(
            "the file is damaged after its last frame (its summary or footer: reading "
            f"stopped at byte {recording.end_damaged} of {recording.path.stat().st_size}): "
            "every frame is whole and was replayed, but other MCAP tools may refuse it; "
            f"vade-replay {shlex.quote(str(recording.path))} -o WHOLE.mcap writes it again "
            "whole")
    elif recording.crc_mismatches:
        summary.warnings.append(
            f"the file is damaged: the CRC-32 of {' and of '.join(recording.crc_mismatches)} "
            "does not match its bytes; every frame and the stored session are whole (their "
            "own CRCs match) and were replayed, but other MCAP tools may read it wrong; "
            f"vade-replay {shlex.quote(str(recording.path))} -o WHOLE.mcap writes it again "
            "whole")
    elif recording.end_lost:
        summary.warnings.append(
            "the file ends after its last frame, short of its end (its summary, footer or "
            "closing bytes missing or unreadable: cut short there?): every frame is whole "
            "and was replayed, but other MCAP tools may refuse it; vade-replay "
            f"{shlex.quote(str(recording.path))} -o WHOLE.mcap writes it again whole")
    summary.match = summary.first_divergence is None
    summary.largest_departure = departure.result() if departure is not None \
        else None if unreadable else {}
    if tolerance is not None:
        summary.tolerance = {"distance_m": tolerance.distance_m,
                             "angle_rad": tolerance.angle_rad}
        summary.beyond_tolerance = None if summary.match else beyond
        summary.within_tolerance = summary.beyond_tolerance is None
    summary.counters = dict(collision.stats)
    summary.truncated = recording.truncated
    summary.stopped = recording.stopped
    summary.recorded_warnings = list(recording.warnings)
    if as_recorded:
        summary.as_recorded = restored
        if restored is None:
            summary.warnings.append("--as-recorded: the recording holds no physics metadata "
                                    "(not made by vade-record): replayed with this version's "
                                    "defaults")
        else:
            # A sub-step bound set to restore a recorded step is no changed default.
            for name in [n for n in summary.physics_changed if n in restored]:
                del summary.physics_changed[name]
    return summary


def _event_change(recorded: list[tuple[str, bytes]], ours: list[tuple[str, bytes]],
                  replayed: FrameRecord, first_time_ns: int | None) -> dict | None:
    """Where a what-if's frame's events differ from the recording's: the frame, and what
    each run had (kind, part, cause); None where they are the same."""
    def events(messages):
        return [(topic, data) for topic, data in messages
                if topic.startswith(codec.EVENT_TOPIC_PREFIX)]
    theirs, mine = events(recorded), events(ours)
    if theirs == mine:
        return None

    def listed(messages) -> str:
        out = []
        for topic, data in messages:
            try:
                d = json.loads(data)
                # (A change of mode names where to: a what-if that holds a part the
                # recording let slide has the same events but for that.)
                out.append(f"{topic[len(codec.EVENT_TOPIC_PREFIX):]} {d.get('part')} "
                           f"({d.get('cause')})"
                           + (f" to {d['to_mode']}" if d.get("to_mode") else ""))
            except (ValueError, AttributeError):
                out.append(topic[len(codec.EVENT_TOPIC_PREFIX):])
        return ", ".join(out) or "none"
    before, after = listed(theirs), listed(mine)
    t = (replayed.time_ns - (replayed.time_ns if first_time_ns is None else first_time_ns)) / 1e9
    text = f"frame {replayed.frame} (t = {t:.6f} s): recorded {before}; what-if {after}"
    if before == after:
        text += " (the same events, other values)"
    return {"frame": replayed.frame, "time_s": t, "recorded": before, "what_if": after,
            "text": text}


def recorded_record(frame: RecordedFrame, previous: FrameRecord | None = None) -> FrameRecord:
    """A recorded frame decoded into the shape the review consumes. ``previous`` is the
    frame before, decoded: a ``changed`` frame carries its unlisted parts forward."""
    base, parts = None, ()
    events = []
    for topic, data in frame.derived:
        if topic == codec.PARTS_TOPIC:
            base, parts = codec.decode_parts(
                data, frame=frame.inputs.frame,
                previous=(previous.base, previous.parts) if previous is not None else None)
        elif topic.startswith(codec.EVENT_TOPIC_PREFIX):
            events.append(codec.decode_event(topic, data, frame=frame.inputs.frame))
    return replace(FrameRecord(frame.inputs, base, parts), events=tuple(events))


def recorded_records(recording: Recording) -> Iterator[FrameRecord]:
    """Every recorded frame, decoded, each onto the one before."""
    previous = None
    for frame in recording.frames():
        previous = recorded_record(frame, previous)
        yield previous
