"""What one frame of a session looks like once it has been simulated or read back.

These records are the hand-off between the simulator, the recording and every
consumer (replay check, rerun review, analysis). They hold plain Python values
(floats, tuples, strings) so that they encode to JSON exactly and compare with ``==``.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import compress
from operator import is_not
from typing import Final

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]  # x, y, z, w

# Tracker positions beyond this (metres) are a unit or export mistake, not a room.
MAX_ABS_POSITION_M: Final = 1e6


# The classes here, in state.py and spatial.Pose are values: never changed after they are
# made. They are not frozen dataclasses, and define their own __init__ (which dataclass
# keeps), because compiled by mypyc (vade_replay/native.py) that is a direct C call, where a
# frozen dataclass's generated __init__ runs as interpreted Python, ten times slower; a
# frame makes dozens of them.


@dataclass(slots=True)
class DeviceSample:
    """One tracker sample: a pose in world coordinates (metres) and, for gloves, the grip."""

    position: Vec3
    rotation_xyzw: Quat
    grip: bool | None

    def __init__(self, position: Vec3, rotation_xyzw: Quat, grip: bool | None = None) -> None:
        self.position = position
        self.rotation_xyzw = rotation_xyzw
        self.grip = grip


@dataclass(slots=True)
class TrackerFrame:
    """All tracker inputs of one frame: the only thing a replay reads to re-run a session."""

    frame: int
    time_ns: int
    devices: tuple[tuple[str, DeviceSample], ...]  # sorted by device name

    def __init__(self, frame: int, time_ns: int,
                 devices: tuple[tuple[str, DeviceSample], ...]) -> None:
        self.frame = frame
        self.time_ns = time_ns
        self.devices = devices

    def device(self, name: str) -> DeviceSample | None:
        for key, sample in self.devices:
            if key == name:
                return sample
        return None


@dataclass(slots=True)
class PartSnapshot:
    """A part's derived state after a frame: mode, pose of the part frame, CM velocities."""

    name: str
    mode: str
    position: Vec3
    rotation_xyzw: Quat
    linear_velocity: Vec3
    angular_velocity: Vec3

    def __init__(self, name: str, mode: str, position: Vec3, rotation_xyzw: Quat,
                 linear_velocity: Vec3, angular_velocity: Vec3) -> None:
        self.name = name
        self.mode = mode
        self.position = position
        self.rotation_xyzw = rotation_xyzw
        self.linear_velocity = linear_velocity
        self.angular_velocity = angular_velocity

    def __eq__(self, other: object) -> bool:
        # The comparison the dataclass would generate (the fields in order, each as a tuple
        # compares them: -0.0 == 0.0), written out because the generated one runs as
        # interpreted Python even when compiled; the encoder compares each moving part
        # with last frame's (codec.FrameEncoder).
        if type(other) is not PartSnapshot:
            return NotImplemented
        return (self.name == other.name and self.mode == other.mode
                and self.position == other.position
                and self.rotation_xyzw == other.rotation_xyzw
                and self.linear_velocity == other.linear_velocity
                and self.angular_velocity == other.angular_velocity)


@dataclass(slots=True)
class FrameRecord:
    """Inputs of a frame and everything the step derived from them."""

    inputs: TrackerFrame
    base: PartSnapshot | None
    parts: tuple[PartSnapshot, ...]  # sorted by part name
    events: tuple  # vade_replay.events.Event instances, in order

    def __init__(self, inputs: TrackerFrame, base: PartSnapshot | None,
                 parts: tuple[PartSnapshot, ...], events: tuple = ()) -> None:
        self.inputs = inputs
        self.base = base
        self.parts = parts
        self.events = events

    @property
    def frame(self) -> int:
        return self.inputs.frame

    @property
    def time_ns(self) -> int:
        return self.inputs.time_ns


@dataclass(slots=True)
class RecordedFrame:
    """One frame as read back: its inputs and its derived messages, bytes as recorded.
    (Here, compiled, made by ``codec.recorded_frames``: a direct C call a frame.)"""

    inputs: TrackerFrame
    derived: list[tuple[str, bytes]]

    def __init__(self, inputs: TrackerFrame, derived: list[tuple[str, bytes]]) -> None:
        self.inputs = inputs
        self.derived = derived


def changed_indices(new: tuple, old: tuple | None) -> list[int]:
    """Indices at which ``new`` holds another object than ``old`` (all, if the lengths
    differ). Snapshots of parts nothing moved are the same objects frame after frame
    (``step.frame_record``), so consumers look only at these."""
    if old is None or len(old) != len(new):
        return list(range(len(new)))
    if _COMPILED:
        # A C loop: 0.5 us for 200 parts, where compress/map is 4.5 us compiled.
        out: list[int] = []
        for i in range(len(new)):
            if new[i] is not old[i]:
                out.append(i)
        return out
    # As Python, the scan in C: 4.5 us for 200 parts, where the loop is ~8 us.
    return list(compress(range(len(new)), map(is_not, new, old)))


# Whether this module runs compiled (its file is then the extension module, not the source);
# a module flag, so that a test can run the other branch too.
_COMPILED = not __file__.endswith(".py")
