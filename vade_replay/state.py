"""State: only what a step changes. Values built of tuples and plain floats, never changed
after they are made (not frozen dataclasses, for speed: see ``frames``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from . import spatial as sp
from .modes import Mode


@dataclass(slots=True)
class Held:
    """A part in a hand (or a tool, or both hands): its fixed offset from the grip and its
    recent CM poses. In both hands (``hand`` is ``both_hands``), the offset is from the
    frame between the hands when they took it, and ``grasp`` is that frame as of the last
    frame: its origin, the unit line from the left hand to the right, each hand's rotation,
    and the frame's rotation since the grab (``step._both_hands_grasp``)."""

    hand: str
    hand_from_part: sp.Pose
    history: tuple  # tuple[(time_ns, world CM, world rotation), ...], newest last
    # () but in both hands: (origin, line, left rotation, right rotation, rotation)
    grasp: tuple

    def __init__(self, hand: str, hand_from_part: sp.Pose, history: tuple,
                 grasp: tuple = ()) -> None:
        self.hand = hand
        self.hand_from_part = hand_from_part
        self.history = history
        self.grasp = grasp


@dataclass(slots=True)
class OnBase:
    """A part constrained on the base: its coordinates relative to the base and their rates.

    ``base_from_snap`` is the part's pose relative to the base when it snapped onto the
    mate (coordinates zero); the pose at any time is ``constraints.relative_pose``. The
    ``blocked_*`` fields remember the direction in which base geometry stopped it (a
    unilateral limit, cleared when the drive points away); ``clear_at``/``clearance`` cache
    the last measured distance to the rest of the base, so that collision queries can be
    skipped while the part cannot have closed that gap.
    """

    mate: int                          # index into the part's Assembly.mates
    base_from_snap: sp.Pose
    slide: tuple[float, ...]           # m, along Mate.slide_dirs
    slide_rate: tuple[float, ...]      # m/s
    angle: float                       # rad, about the base axis (right hand)
    angle_rate: float                  # rad/s
    cm_offset: sp.Vec3                 # r_perp in base axes at angle 0
    blocked_slide: tuple[float, ...]   # unit vector in slide coordinates, or ()
    blocked_turn: int                  # +1 / -1: turning that way is blocked
    clear_at: tuple[float, ...]        # slide coordinates where clearance was measured
    clearance: float                   # m; 0 means "unknown: query"

    def __init__(self, mate: int, base_from_snap: sp.Pose, slide: tuple[float, ...],
                 slide_rate: tuple[float, ...], angle: float = 0.0, angle_rate: float = 0.0,
                 cm_offset: sp.Vec3 = sp.ZERO3, blocked_slide: tuple[float, ...] = (),
                 blocked_turn: int = 0, clear_at: tuple[float, ...] = (),
                 clearance: float = 0.0) -> None:
        self.mate = mate
        self.base_from_snap = base_from_snap
        self.slide = slide
        self.slide_rate = slide_rate
        self.angle = angle
        self.angle_rate = angle_rate
        self.cm_offset = cm_offset
        self.blocked_slide = blocked_slide
        self.blocked_turn = blocked_turn
        self.clear_at = clear_at
        self.clearance = clearance

    def moved(self, slide: tuple[float, ...], slide_rate: tuple[float, ...], angle: float,
              angle_rate: float) -> "OnBase":
        """The same constraint at other coordinates and rates: ``dataclasses.replace``
        of those four fields, without its generic walk over the fields (once a frame)."""
        return OnBase(self.mate, self.base_from_snap, slide, slide_rate, angle, angle_rate,
                      self.cm_offset, self.blocked_slide, self.blocked_turn, self.clear_at,
                      self.clearance)


@dataclass(slots=True)
class Resting:
    """A part lying on the base part on no recognised constraint: fixed relative to the base.

    ``up`` (base axes) points away from the base at the support: against gravity when the
    part came to rest. The part stays while gravity presses it towards the base, and
    leaves when the base turns so that gravity pulls it away.
    """

    base_from_part: sp.Pose
    up: sp.Vec3

    def __init__(self, base_from_part: sp.Pose, up: sp.Vec3) -> None:
        self.base_from_part = base_from_part
        self.up = up


@dataclass(slots=True)
class PartState:
    """One part's mode, world pose (of the part frame), CM velocities and mode-specific motion."""

    name: str
    mode: Mode
    pose: sp.Pose
    linear_velocity: sp.Vec3
    angular_velocity: sp.Vec3
    # Any, not object: mypyc (vade_replay/native.py) fails on a dataclass field of `object`.
    motion: Any  # Held, free.Flight, OnBase, or None

    def __init__(self, name: str, mode: Mode, pose: sp.Pose,
                 linear_velocity: sp.Vec3 = sp.ZERO3, angular_velocity: sp.Vec3 = sp.ZERO3,
                 motion: Any = None) -> None:
        self.name = name
        self.mode = mode
        self.pose = pose
        self.linear_velocity = linear_velocity
        self.angular_velocity = angular_velocity
        self.motion = motion

    def moved(self, pose: sp.Pose, linear_velocity: sp.Vec3, angular_velocity: sp.Vec3,
              motion: object) -> "PartState":
        """The part in the same mode at another pose, with these velocities and motion:
        ``dataclasses.replace`` of those four fields, without its generic walk over the
        fields (several times a frame)."""
        return PartState(self.name, self.mode, pose, linear_velocity, angular_velocity, motion)


@dataclass(slots=True)
class BaseSample:
    """The base's last left-hand sample that moved it: its time, where its centre of mass
    was, and its rotation (``step._base_sample``). (A compiled class: one object where a
    tuple of a tuple of floats was eleven.)"""

    t_ns: int
    cm: sp.Vec3
    rotation: sp.Quat

    def __init__(self, t_ns: int, cm: sp.Vec3, rotation: sp.Quat) -> None:
        self.t_ns = t_ns
        self.cm = cm
        self.rotation = rotation


@dataclass(slots=True)
class BaseVelocity:
    """The base's velocity (its centre of mass's) and angular velocity, world, between its
    last two samples (``step._base_sample``)."""

    velocity: sp.Vec3
    omega: sp.Vec3

    def __init__(self, velocity: sp.Vec3, omega: sp.Vec3) -> None:
        self.velocity = velocity
        self.omega = omega


@dataclass(slots=True)
class WorldState:
    """The whole simulation state after a frame."""

    frame: int
    time_ns: int
    parts: tuple[PartState, ...]     # sorted by name, same order as Scene.parts
    base_pose: sp.Pose | None
    grips: tuple[tuple[str, bool], ...]  # last grip per hand, sorted by hand
    # Derived from ``parts``, kept so that a frame need not look at every part: indices of
    # the parts not at rest on the table (step._awake); None: not known, look at all.
    awake: tuple[int, ...] | None
    # The ``parts`` tuple ``awake`` was worked out for: a state copied with other parts
    # (``dataclasses.replace``) does not match it, and its awake set is worked out anew.
    awake_of: tuple | None
    # The base's last left-hand sample that moved it, or None (none yet: its session pose
    # before the hand took it is no sample, and that jump no motion), and its velocity and
    # angular velocity since the sample before, or None (physics ``velocities: world``;
    # ``step._base_sample``).
    base_sample: BaseSample | None
    base_velocity: BaseVelocity | None

    def __init__(self, frame: int, time_ns: int, parts: tuple[PartState, ...],
                 base_pose: sp.Pose | None, grips: tuple[tuple[str, bool], ...],
                 awake: tuple[int, ...] | None = None, awake_of: tuple | None = None,
                 base_sample: BaseSample | None = None,
                 base_velocity: BaseVelocity | None = None) -> None:
        self.frame = frame
        self.time_ns = time_ns
        self.parts = parts
        self.base_pose = base_pose
        self.grips = grips
        self.awake = awake
        self.awake_of = awake_of
        self.base_sample = base_sample
        self.base_velocity = base_velocity

    def awake_parts(self) -> tuple[int, ...] | None:
        """``awake`` if it belongs to these parts, else None (unknown)."""
        return self.awake if self.awake_of is self.parts else None
