"""One pure step: ``step(scene, collision, state, inputs) -> (state, events)``.

The body of ``step`` is the list of stages, one call per line. Its result depends on its
arguments only: no clock, no globals, no unseeded randomness, dicts walked in sorted order.
The collision world is a cache of geometry built once from the scene; its counters are
instrumentation and never change a result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Final, cast

from . import constraints as cn
from . import spatial as sp
from .collision import KEEP_COPLANAR, SKIP_COAXIAL, SKIP_COPLANAR, CollisionWorld
from .constraints import Assembly
from .dynamics import free, onbase, velocity
from .events import ContactMade, Event, GrabRefused, ModeChanged, PartGrabbed, PartReleased
from .frames import FrameRecord, PartSnapshot, TrackerFrame
from .modes import Cause, Mode, check_transition
from .scene import BOTH_HANDS, Body, Physics, Scene
from .state import BaseSample, BaseVelocity, Held, OnBase, PartState, Resting, WorldState

# Final: compiled, a C constant (a plain module name is a lookup in the module dict at every use).
RIGHT: Final = "right_hand"
LEFT: Final = "left_hand"
# The modes, read once. Compiled, ``Mode.STATIC`` is a lookup on the enum class through
# ``EnumType.__getattr__`` (~700 instructions, dozens a frame); a Final name of this
# module is a C static.
INHAND: Final = Mode.INHAND
ONTOOL: Final = Mode.ONTOOL
ONBASESLIDE: Final = Mode.ONBASESLIDE
ONBASESTATIC: Final = Mode.ONBASESTATIC
INSPACE: Final = Mode.INSPACE
STATIC: Final = Mode.STATIC
PLACED: Final = Mode.PLACED
_GRABBABLE: Final = (STATIC, INSPACE, ONBASESLIDE, ONBASESTATIC, PLACED)
# What a tool attaches: what a hand could grab, and a part in a hand (handed over).
_TOOL_GRABBABLE: Final = (*_GRABBABLE, INHAND)
_HANDS: Final = (LEFT, RIGHT)
def _zero3() -> sp.Vec3:
    """``sp.ZERO3``, compiled a C struct made in place (``sp.ZERO3`` is a module attribute
    looked up and its three floats unboxed at every use; mypyc 2.4 cannot keep a Final
    tuple of floats: "value for final name ... was not set")."""
    return (0.0, 0.0, 0.0)


_CA_MAX_ITERATIONS: Final = 10_000
_MIN_SUPPORT_COS: Final = 0.1


@dataclass(slots=True)
class _Frame:
    """Scratch space of one step: the parts being rebuilt and the events so far."""

    scene: Scene
    collision: CollisionWorld
    inputs: TrackerFrame
    t_prev_ns: int
    parts: list[PartState]
    hands: dict[str, sp.Pose] = field(default_factory=dict, init=False)
    grips: dict[str, bool] = field(default_factory=dict, init=False)
    base_pose: sp.Pose | None = None
    base_prev: sp.Pose | None = None   # the base pose at the previous frame
    awake: tuple[int, ...] = ()        # parts not at rest on the table, at the frame start
    events: list[Event] = field(default_factory=list, init=False)
    modes_changed: bool = field(default=False, init=False)
    taken: list[int] = field(default_factory=list, init=False)  # parts grabbed this frame
    # Parts that came onto a constraint in flight this frame (``_onto_base``): at rest on
    # it from the contact to the frame's end, they move on it from the next frame, as a
    # part let go onto one does.
    landed: tuple[int, ...] = field(default=(), init=False)

    def __init__(self, scene: Scene, collision: CollisionWorld, inputs: TrackerFrame,
                 t_prev_ns: int, parts: list[PartState], *, base_pose: sp.Pose | None = None,
                 base_prev: sp.Pose | None = None, awake: tuple[int, ...] = ()) -> None:
        # Its own __init__ (dataclass keeps it): a direct call when compiled (see frames).
        self.scene = scene
        self.collision = collision
        self.inputs = inputs
        self.t_prev_ns = t_prev_ns
        self.parts = parts
        self.hands = {}
        self.grips = {}
        self.base_pose = base_pose
        self.base_prev = base_prev
        self.awake = awake
        self.events = []
        self.modes_changed = False
        self.taken = []
        self.landed = ()

    @property
    def dt_s(self) -> float:
        return (self.inputs.time_ns - self.t_prev_ns) * 1e-9

    @property
    def t_ns(self) -> int:
        return self.inputs.time_ns

    def change_mode(self, index: int, new: PartState, cause: Cause) -> None:
        old = self.parts[index]
        check_transition(old.mode, new.mode, cause, part=old.name, frame=self.inputs.frame)
        self.parts[index] = new
        self.modes_changed = True
        self.events.append(ModeChanged(self.inputs.frame, old.name, cause.value, old.mode.value,
                                       new.mode.value))


def initial_state(scene: Scene, *, time_ns: int = 0) -> WorldState:
    """Every part at rest at its initial pose, before the first frame."""
    parts = tuple(PartState(body.name, body.initial_mode, body.initial_pose)
                  for body in scene.parts)
    base_pose = scene.base.initial_pose if scene.base else None
    grips = tuple(sorted((name, False) for name in _grip_devices(scene)))
    return WorldState(-1, time_ns, parts, base_pose, grips, _awake(parts), parts)


def _awake(parts: tuple[PartState, ...]) -> tuple[int, ...]:
    """Indices of the parts a frame has to look at: all but those at rest on the table
    (STATIC), which nothing but a grab moves; the grab stage looks at every part."""
    awake: list[int] = []  # (a loop: compiled, a generator here cost ~200 instructions a part)
    for i in range(len(parts)):
        if parts[i].mode is not STATIC:
            awake.append(i)
    return tuple(awake)


def step(scene: Scene, collision: CollisionWorld, state: WorldState,
         inputs: TrackerFrame, *,
         scratch: list[PartState] | None = None) -> tuple[WorldState, tuple[Event, ...]]:
    """Advance the world by one frame of tracker inputs.

    ``scratch`` (``Stepper``'s): a list holding the objects of ``state.parts``, which the
    step works in and leaves holding the new state's; without it, a copy. (A copy of a
    scene of 200 parts and its freeing were ~5,000 instructions a frame.)"""
    awake = state.awake_parts()
    if awake is None:
        awake = _awake(state.parts)
    f = _Frame(scene, collision, inputs, state.time_ns,
               list(state.parts) if scratch is None else scratch,
               base_pose=state.base_pose, base_prev=state.base_pose, awake=awake)
    _read_hands(f, state)
    _move_base(f)
    base_sample, base_velocity = state.base_sample, state.base_velocity
    if f.base_pose is not state.base_pose and scene.physics.velocities == "world" \
            and scene.base is not None:
        base_sample, base_velocity = _base_sample(f, scene.base, base_sample, base_velocity)
    elif base_velocity is not None:
        base_velocity = None  # no left-hand sample this frame: the base did not move
    _follow_hands(f)
    _move_free_parts(f)
    _check_resting_on_base(f)
    _move_on_base(f)
    _carry_with_base(f)
    _releases(f, state)
    _meet_environment(f, state.parts)
    _grabs(f, state)
    parts = tuple(f.parts)
    grips = f.grips  # _read_hands sets both hands (LEFT < RIGHT) and every tool
    new_state = WorldState(inputs.frame, inputs.time_ns, parts, f.base_pose,
                           ((LEFT, grips[LEFT]), (RIGHT, grips[RIGHT])) if not scene.tools
                           else tuple(sorted(grips.items())),
                           _awake(parts) if f.modes_changed else awake, parts,
                           base_sample, base_velocity)
    return new_state, tuple(f.events)


def _base_sample(f: _Frame, base: Body, last: BaseSample | None,
                 motion: BaseVelocity | None) -> tuple[BaseSample, BaseVelocity | None]:
    """The base moved to a left-hand sample: that sample, and the base's velocity (its
    centre of mass's) and angular velocity since the sample before, over their times
    (physics ``velocities: world``; recorded, they drive nothing). None with no sample
    before: the hand taking the base from its session pose is no motion (a review: a
    one-frame difference of poses read 57 m/s there). A sample closer than the release
    fit's ``MIN_INTERVAL_NS`` to the one before (a duplicated timestamp) is passed over,
    the velocity the one before (``motion``). A one-sample difference, not the held parts'
    window fit: the fit cost ~5 us a frame, a third of a step, for a velocity nothing
    reads back; a device missing from a log's frame keeps its last sample, so the base
    holds there (0) and steps the gap's motion in the frame after, as simulated. Samples
    are taken a 60 Hz step apart at most as densely as the release fit takes them
    (``velocity.spacing_ns``: three quarters of ``release_span_s / (release_window - 1)``):
    a log of unaligned devices has a frame every 3 ms, and a difference over one was the
    tracker's noise (an engineer's trial: a bracket held still at 0.07-0.19 m/s); at 60 Hz
    or less, every frame, as before."""
    pose = cast(sp.Pose, f.base_pose)
    t_ns = f.t_ns
    sample = BaseSample(t_ns, pose.apply(base.center_of_mass), pose.rotation)
    if last is None:
        return sample, None
    physics = f.scene.physics
    spacing = max(float(velocity.MIN_INTERVAL_NS), velocity.spacing_ns(
        round(physics.release_span_s * 1e9), physics.release_window))
    if t_ns - last.t_ns < spacing:
        return last, motion
    dt = (t_ns - last.t_ns) * 1e-9
    v = sp.scale(sp.sub(sample.cm, last.cm), 1.0 / dt)
    w = sp.scale(sp.quat_to_rotvec(sp.quat_mul(sample.rotation, sp.quat_conj(last.rotation))),
                 1.0 / dt)
    return sample, BaseVelocity(v, w)


def _was_gripping(grips: tuple[tuple[str, bool], ...], device: str) -> bool:
    """The last frame's grip of ``device`` (``WorldState.grips``; False for one not there):
    ``dict(grips).get(device, False)`` without a dict made three times a frame."""
    for name, grip in grips:
        if name == device:
            return grip
    return False


# --- stages ---------------------------------------------------------------------------

def _read_hands(f: _Frame, state: WorldState) -> None:
    """The hands' and the tools' poses and grips (a device without a sample this frame keeps
    its grip and has no pose)."""
    previous = state.grips
    for hand in _grip_devices(f.scene):
        sample = f.inputs.device(hand)
        if sample is None:
            f.grips[hand] = _was_gripping(previous, hand)
            continue
        f.hands[hand] = sp.Pose(sample.position, sample.rotation_xyzw)
        f.grips[hand] = bool(sample.grip) if sample.grip is not None \
            else _was_gripping(previous, hand)


def _move_base(f: _Frame) -> None:
    # The base part is held in the left hand; without a left-hand tracker, or fixed, it
    # stays put.
    if f.scene.base_in_hand and LEFT in f.hands:
        f.base_pose = f.hands[LEFT].compose(f.scene.hand_from_base)


def _follow_hands(f: _Frame) -> None:
    physics = f.scene.physics
    keep = max(physics.release_window, 2)
    span_ns = round(physics.release_span_s * 1e9)
    for index in f.awake:
        part = f.parts[index]
        if part.mode is not INHAND and part.mode is not ONTOOL:
            continue
        held: Held = part.motion  # type: ignore[assignment]
        grasp: tuple | None = held.grasp
        if held.hand != BOTH_HANDS:
            hand = f.hands.get(held.hand)
        else:
            grasp = _both_hands_grasp(f, held.grasp)
            hand = None if grasp is None else sp.Pose(grasp[0], grasp[4])
        if hand is None or grasp is None:
            # No sample for that hand this frame (or, in both hands, no frame of the two):
            # the part stays where it was.
            continue
        body = f.scene.parts[index]
        pose = hand.compose(held.hand_from_part)
        cm = pose.apply(body.center_of_mass)
        newest = velocity.new_sample(held.history, f.t_ns, cm, pose.rotation)
        history = velocity.kept(held.history + (newest,), keep, span_ns)
        # The point of the part the hand holds it by (the hand's origin, in part axes, from
        # the centre of mass): its path is fitted (``velocity.estimate``).
        grip = sp.sub(held.hand_from_part.inverse().position, body.center_of_mass) \
            if physics.release_point == "grip" else sp.ZERO3
        v, w = velocity.estimate(history, method=physics.release_velocity,
                                 window=physics.release_window, grip=grip,
                                 span_ns=span_ns)
        f.parts[index] = part.moved(pose, v, w, Held(held.hand, held.hand_from_part, history,
                                                     grasp))


def _move_free_parts(f: _Frame) -> None:
    for index in f.awake:
        if f.parts[index].mode is INSPACE:
            _fly(f, index)


def _grip_devices(scene: Scene) -> tuple[str, ...]:
    """The devices with a grip, in the order they act within a frame: the tools (by name),
    then the hands. An order by role, not by name, so that renaming a tool changes nothing:
    a tool and a hand closing on one part in the same frame give it to the tool."""
    tools = scene.tools
    return _HANDS if not tools else (*(t.name for t in tools), *_HANDS)


def _releases(f: _Frame, state: WorldState) -> None:
    previous = state.grips
    for hand in _grip_devices(f.scene):
        if not (_was_gripping(previous, hand) and not f.grips[hand]):
            continue
        for index in f.awake:
            part = f.parts[index]
            if part.mode is INHAND or part.mode is ONTOOL:
                holder = cast(Held, part.motion).hand
                # A part in both hands is too heavy for either alone: one opening lets go.
                if holder == hand or (holder == BOTH_HANDS and (hand == LEFT or hand == RIGHT)):
                    if holder == hand and _taken_over(f, state, hand, index):
                        continue  # the other hand, closing on it now, takes it over
                    _release(f, index, holder)


def _taken_over(f: _Frame, state: WorldState, hand: str, index: int) -> bool:
    """Whether the other hand closes in this frame with the part ``hand`` lets go of as the
    part nearest it: a pass from hand to hand within one frame is a hand-over too (the
    grab stage makes it), not a release and a catch."""
    if hand != LEFT and hand != RIGHT:
        return False
    other = _other(hand)
    if _was_gripping(state.grips, other) or not f.grips.get(other, False) \
            or other not in f.hands \
            or (other == LEFT and f.scene.base_in_hand):
        return False
    nearest = _nearest(f, f.hands[other].position, f.scene.physics.grab_radius, _GRABBABLE,
                       hand)[0]
    return nearest == index


def _grabs(f: _Frame, state: WorldState) -> None:
    previous = state.grips
    closing = [hand for hand in _grip_devices(f.scene)
               if not _was_gripping(previous, hand) and f.grips[hand] and hand in f.hands
               # The left hand holds the base part; it grabs in scenes without one or with
               # a fixed one.
               and not (hand == LEFT and f.scene.base_in_hand)]
    if LEFT in closing and RIGHT in closing:
        # Both hands close in this frame: the one nearer the part nearest it acts first (at
        # equal distances the right), so a part both reach goes to the nearer hand, and a
        # gesture and its mirror image give the same result.
        radius = f.scene.physics.grab_radius
        left_d = _nearest(f, f.hands[LEFT].position, radius, _GRABBABLE, RIGHT)[1]
        right_d = _nearest(f, f.hands[RIGHT].position, radius, _GRABBABLE, LEFT)[1]
        if left_d < right_d:
            closing = [h for h in closing if h != RIGHT] + [RIGHT]
        else:
            closing = [h for h in closing if h != LEFT] + [LEFT]
    for hand in closing:
        # Both hands closed in this frame and took one part together: the second is busy.
        if (hand == LEFT or hand == RIGHT) and _in_both_hands(f) >= 0:
            continue
        _grab(f, hand)


def _in_both_hands(f: _Frame) -> int:
    """The index of the part both hands hold, or -1."""
    for index, part in enumerate(f.parts):
        if part.mode is INHAND and cast(Held, part.motion).hand == BOTH_HANDS:
            return index
    return -1


# --- grabbing and releasing -----------------------------------------------------------

def _distance_to_box(body: Body, pose: sp.Pose, point: sp.Vec3) -> float:
    local = pose.inverse().apply(point)
    gap = 0.0
    for axis in range(3):
        if local[axis] < body.bbox_min[axis]:
            gap += (body.bbox_min[axis] - local[axis]) ** 2
        elif local[axis] > body.bbox_max[axis]:
            gap += (local[axis] - body.bbox_max[axis]) ** 2
    return math.sqrt(gap)


def _nearest(f: _Frame, position: sp.Vec3, radius: float, grabbable: tuple,
             other_hand: str = "") -> tuple[int, float, str, str]:
    """The part a grip closing at ``position`` takes: the index of the grabbable part whose
    bounding box is nearest, within ``radius`` (-1: none), its distance (inf: none), and
    the nearest part in reach that it cannot take with why ("", "": none): on a tool, or in
    a hand that holds it with the other or took it in this frame. A hand (``other_hand``:
    the other one) also takes a part out of the other hand (handed over)."""
    best, best_d = -1, math.inf
    best_name = ""
    held, held_cause = "", ""
    held_d = math.inf
    hx, hy, hz = position
    bodies = f.scene.parts
    tests = 0
    for index, part in enumerate(f.parts):
        mode = part.mode
        takeable = mode in grabbable
        if not takeable and mode is not ONTOOL and not (other_hand and mode is INHAND):
            continue
        # Bounding sphere about the part frame's origin first: most parts are far away.
        # (Products, not ``** 2``: compiled, a float's power is a generic call.)
        reach = bodies[index].reach_from_origin + radius
        p = part.pose.position
        dx, dy, dz = p[0] - hx, p[1] - hy, p[2] - hz
        tests += 1
        if dx * dx + dy * dy + dz * dz > reach * reach:
            continue
        d = _distance_to_box(f.scene.parts[index], part.pose, position)
        if d > radius:
            continue
        cause = "held_by_tool" if mode is ONTOOL else ""
        if not takeable and mode is INHAND:
            # In the other hand since before this frame: handed over; else it stays put.
            if cast(Held, part.motion).hand == other_hand and index not in f.taken:
                takeable = True
            else:
                cause = "held_by_other_hand"
        if takeable:
            if d < best_d or (d == best_d and part.name < best_name):
                best, best_d, best_name = index, d, part.name
        elif d < held_d:
            held, held_cause, held_d = part.name, cause, d
    f.collision.stats["bounding_tests"] += tests
    return best, best_d, held, held_cause


def _grab(f: _Frame, hand: str) -> None:
    """A hand (or a tool: ``hand`` is its device) closed: it takes the part nearest it."""
    physics = f.scene.physics
    tool = f.scene.tool(hand) if f.scene.tools else None
    radius = physics.grab_radius if tool is None else tool.grab_radius
    hand_pose = f.hands[hand]
    frame = f.inputs.frame
    index, _, refused, refused_cause = _nearest(
        f, hand_pose.position, radius, _GRABBABLE if tool is None else _TOOL_GRABBABLE,
        _other(hand) if tool is None else "")
    if index < 0:
        if refused:
            f.events.append(GrabRefused(frame, refused, refused_cause, hand))
        else:
            f.events.append(GrabRefused(frame, "", "nothing_in_reach", hand))
        return
    body = f.scene.parts[index]
    name = body.name
    part = f.parts[index]
    if tool is None and part.mode is INHAND:
        # Out of the other hand: the same mode, a new grip (no release by the other hand);
        # its pose history goes with it, so the release-velocity fit runs on unbroken.
        f.parts[index] = PartState(name, INHAND, part.pose, part.linear_velocity,
                                   part.angular_velocity,
                                   Held(hand, hand_pose.inverse().compose(part.pose),
                                        cast(Held, part.motion).history))
        f.taken.append(index)
        f.events.append(PartGrabbed(frame, name, Cause.HANDED_OVER.value, hand))
        return
    grip = hand  # the grip that takes it: the hand, the tool, or both hands
    hand_from_part = hand_pose.inverse().compose(part.pose)
    grasp: tuple = ()
    if tool is None and body.mass_kg > physics.one_hand_max_mass_kg:
        two_hands = physics.two_hand_max_mass_kg > physics.one_hand_max_mass_kg
        if two_hands and body.mass_kg > physics.two_hand_max_mass_kg:
            f.events.append(GrabRefused(frame, name, "too_heavy_for_two_hands", hand))
            return
        if not (two_hands and _other_hand_on(f, hand, index)):
            f.events.append(GrabRefused(frame, name, "too_heavy_for_one_hand", hand))
            return
        grip = BOTH_HANDS
        left, right = f.hands[LEFT], f.hands[RIGHT]
        line = sp.sub(right.position, left.position)
        middle = sp.scale(sp.add(left.position, right.position), 0.5)
        grasp = (middle, sp.scale(line, 1.0 / sp.norm(line)), left.rotation, right.rotation,
                 sp.IDENTITY_QUAT)
        hand_from_part = sp.Pose(sp.scale(middle, -1.0)).compose(part.pose)
    if tool is not None and body.mass_kg > tool.max_mass_kg:
        f.events.append(GrabRefused(frame, name, "too_heavy_for_tool", hand))
        return
    if tool is not None:
        mode, cause = ONTOOL, Cause.ATTACHED_TO_TOOL
    else:
        mode, cause = INHAND, Cause.CAUGHT if part.mode is INSPACE else Cause.GRABBED
    cm = part.pose.apply(body.center_of_mass)
    held = Held(grip, hand_from_part, ((f.t_ns, cm, part.pose.rotation),), grasp)
    f.change_mode(index, PartState(name, mode, part.pose, _zero3(), _zero3(), held), cause)
    f.taken.append(index)
    f.events.append(PartGrabbed(frame, name, cause.value, grip))


def _other(hand: str) -> str:
    return RIGHT if hand == LEFT else LEFT


def _other_hand_on(f: _Frame, hand: str, index: int) -> bool:
    """Whether the other hand joins ``hand`` on part ``index``: it is a hand that grabs
    (not the left hand carrying the base), it is tracked and closed in this frame (closing
    now or before), it holds nothing, and the part is the one nearest it too (so the same
    gesture mirrored gives the same result). The hands must be apart (a line between them)."""
    if hand != LEFT and hand != RIGHT:
        return False
    other = _other(hand)
    if other == LEFT and f.scene.base_in_hand:
        return False
    if not f.grips.get(other, False) or other not in f.hands:
        return False
    for part in f.parts:
        if (part.mode is INHAND or part.mode is ONTOOL) \
                and cast(Held, part.motion).hand in (other, BOTH_HANDS):
            return False
    if not sp.norm(sp.sub(f.hands[other].position, f.hands[hand].position)) >= _TWO_HAND_MIN:
        return False
    nearest, _, _, _ = _nearest(f, f.hands[other].position, f.scene.physics.grab_radius,
                                _GRABBABLE)
    return nearest == index


# Hands nearer than this (m) have no line between them: a part in both hands then stays
# where it was, and is not taken.
_TWO_HAND_MIN: Final = 1e-6


def _swing(a: sp.Vec3, b: sp.Vec3) -> sp.Quat:
    """The least rotation taking unit vector ``a`` to unit vector ``b`` (for opposite ones,
    a half turn about an axis perpendicular to ``a``)."""
    d = sp.dot(a, b)
    if d < -1.0 + 1e-12:
        axis = sp.normalize(sp.cross(a, (1.0, 0.0, 0.0) if abs(a[0]) < 0.9 else (0.0, 1.0, 0.0)))
        return (axis[0], axis[1], axis[2], 0.0)
    c = sp.cross(a, b)
    return sp.quat_normalize((c[0], c[1], c[2], 1.0 + d))


def _both_hands_grasp(f: _Frame, grasp: tuple) -> tuple | None:
    """The frame of a part in both hands, moved on from the last frame's (``grasp``: its
    origin, the unit line from the left hand to the right, each hand's rotation, and the
    frame's rotation since the hands took the part; all at the grab: origin and line there,
    rotation identity). Its origin is midway between the hands. Its rotation is turned on
    by this frame's increment: the least rotation (the swing) taking last frame's line to
    this frame's, after a turn about last frame's line by the mean of the two hands' own
    turns about it since last frame (their twists, the swing taken out). The increments of
    hands moved together rigidly compose to their motion, exactly but for round-off;
    untracked (fixed) hand rotations give the swing alone, frame by frame (carried round
    about the vertical, the part turns about the vertical). Built frame by frame, it never
    jumps (but where the hands swap sides within one frame). None where either hand has no
    sample this frame, or the hands are together (no line)."""
    left, right = f.hands.get(LEFT), f.hands.get(RIGHT)
    if left is None or right is None:
        return None
    line = sp.sub(right.position, left.position)
    n = sp.norm(line)
    if not n >= _TWO_HAND_MIN:
        return None
    _, u0, left_then, right_then, rotation = grasp
    u = sp.scale(line, 1.0 / n)
    swing = _swing(u0, u)
    unswing = sp.quat_conj(swing)
    s = c = 0.0
    for now, then in ((left.rotation, left_then), (right.rotation, right_then)):
        rest = sp.quat_mul(unswing, sp.quat_mul(now, sp.quat_conj(then)))
        along = rest[0] * u0[0] + rest[1] * u0[1] + rest[2] * u0[2]
        if abs(along) > 1e-12 or abs(rest[3]) > 1e-12:  # else: a half turn across the line
            twist = 2.0 * math.atan2(along, rest[3])
            s += math.sin(twist)
            c += math.cos(twist)
    twist = math.atan2(s, c)  # the mean of the two (0 where they cancel)
    step = sp.quat_mul(swing, sp.quat_unit_axis_angle(u0, twist))
    return (sp.scale(sp.add(left.position, right.position), 0.5), u, left.rotation,
            right.rotation, sp.quat_normalize(sp.quat_mul(step, rotation)))


def _release(f: _Frame, index: int, hand: str) -> None:
    """A hand (or a tool) opened: the part it held goes onto the base, a constraint or its
    final pose, onto the table, or into free flight (from a tool: detached)."""
    part = f.parts[index]
    body = f.scene.parts[index]
    physics = f.scene.physics
    v, w = part.linear_velocity, part.angular_velocity
    frame = f.inputs.frame
    flies = Cause.RELEASED if part.mode is INHAND else Cause.DETACHED_FROM_TOOL
    if body.assembly is not None and f.base_pose is not None \
            and _release_on_base(f, index, hand):
        return
    cm = part.pose.apply(body.center_of_mass)
    if f.base_pose is not None and _base_path(f, cm, body.radius_about_cm) is not None:
        base_from_part = f.base_pose.inverse().compose(part.pose)
        if f.collision.distance_to_base(part.name, base_from_part) <= physics.contact_tolerance:
            normal, _, point = f.collision.base_contact(part.name, base_from_part)
            if normal is None:
                # Let go inside the base (the hand's tracker noise put it there): out of the
                # one flat face it is in, it is let go touching that face (a contact
                # battery's: 0.69 mm into a wall, it rested there, held up by the wall 20 mm
                # above the plate, no face telling which way is out).
                out = _out_of_flat_overlap(f, index, base_from_part)
                if out is not None:
                    base_from_part = out
                    part = replace(part, pose=cast(sp.Pose, f.base_pose).compose(out))
                    f.parts[index] = part
                    cm = part.pose.apply(body.center_of_mass)
                    normal, _, point = f.collision.base_contact(part.name, base_from_part)
            up = _support(f, normal)
            if up is None and normal is not None:
                up = _support_elsewhere(f, part.name, base_from_part, ())
            if up is not None:
                f.events.append(PartReleased(frame, part.name,
                                             Cause.RELEASED_ON_BASE_PART.value, hand, v, w))
                _rest_on_base(f, index, base_from_part, up, Cause.RELEASED_ON_BASE_PART)
                return
            # Touching a face that does not hold it up (underneath, a wall): it flies, not
            # into the base, which it may graze until they separate.
            v, w = _graze(body, cast(sp.Pose, f.base_pose), part.pose, normal, point, v, w,
                          _base_motion(f, point)[0])
            f.events.append(PartReleased(frame, part.name, flies.value, hand, v, w))
            grace, gaps = _grace(f, part.name, base_from_part)
            flight = free.start(t_ns=f.t_ns, cm=cm, velocity=v, omega_world=w,
                                world_from_part=part.pose,
                                part_from_principal=body.part_from_principal,
                                principal_moments=body.principal_moments, base_clear=False,
                                grace=grace, grace_gaps=gaps)
            f.change_mode(index, PartState(part.name, INSPACE, part.pose, v, w, flight), flies)
            return
    near = f.collision.environment_near(cm, body.radius_about_cm + physics.contact_tolerance)
    if near:
        d, which = f.collision.distance_to_environment(part.name, part.pose, near)
        # Let go wholly inside the table (a hand pushed it in: there is no haptic stop) is
        # let go on it, where it is; it flew inside it and fell out of its underside.
        if d <= physics.contact_tolerance or (
                physics.environment_contact == "every_part"
                and f.collision.inside_environment(part.name, part.pose, near) >= 0):
            f.events.append(PartReleased(frame, part.name, Cause.RELEASED_ON_TABLE.value, hand,
                                         v, w))
            f.change_mode(index, PartState(part.name, STATIC, part.pose),
                          Cause.RELEASED_ON_TABLE)
            return
    f.events.append(PartReleased(frame, part.name, flies.value, hand, v, w))
    flight = free.start(t_ns=f.t_ns, cm=cm, velocity=v, omega_world=w, world_from_part=part.pose,
                        part_from_principal=body.part_from_principal,
                        principal_moments=body.principal_moments)
    f.change_mode(index, PartState(part.name, INSPACE, part.pose, v, w, flight), flies)


# How deep in a flat face of the base a part let go inside it may be and be moved out of it
# (``_out_of_flat_overlap``), metres: a tracker's noise of a few tenths of a millimetre,
# whatever the contact tolerance; deeper, nothing says the hand did not mean it.
_OVERLAP_REACH_M: Final = 0.002


def _out_of_flat_overlap(f: _Frame, index: int, base_from_part: sp.Pose) -> sp.Pose | None:
    """A part let go overlapping the base: its pose (base axes) moved out of one flat face
    it is in (``flat_plane``), no deeper than ``_OVERLAP_REACH_M``, along that face's
    normal to about a tenth of the contact tolerance from it, where that takes it out of
    the whole base and clear of the environment; of such faces, the one it is least deep
    in (a block put into a wall just below the wall's top is in the wall's side and its
    top: out through the side, the least move). Only a face its centre of mass is outside
    of: a review put a thin sheet through a thin plate's far side, and one into a plate
    wound inward (an STL whose faces' normals point in). None where no face will do (a
    curved surface, a corner, a part deeper)."""
    tol = f.scene.physics.contact_tolerance
    body = f.scene.parts[index]
    name = body.name
    cm = base_from_part.apply(body.center_of_mass)
    overlapped, _ = f.collision.surface_gaps(name, base_from_part, 0.0)
    best: sp.Pose | None = None
    least = float("inf")
    for surface in overlapped:
        plane = f.collision.flat_plane(surface)
        if plane is None:
            continue
        normal, offset = plane
        if not sp.dot(normal, cm) > offset:
            continue  # its centre of mass inside that face: not the way out
        depth = f.collision.depth_in_flat(name, base_from_part, surface, normal,
                                          _OVERLAP_REACH_M)
        if depth is None or not depth >= 0.0:
            continue
        # ``depth`` is too large where the part reaches past the face's edge (a review: a
        # cube turned 45 degrees across a plate's edge, moved 0.95 mm up for 0.5 mm in, then
        # rested hovering): stepped back toward the face while it is farther than a fifth
        # of the tolerance, by its distance less a tenth (never into it: it moves no more
        # than its distance).
        shift = depth + 0.1 * tol
        moved = sp.Pose(sp.add(base_from_part.position, sp.scale(normal, shift)),
                        base_from_part.rotation)
        for _ in range(8):
            d = f.collision.surface_distance(name, moved, surface)
            if not d > 0.2 * tol:
                break
            shift -= d - 0.1 * tol
            moved = sp.Pose(sp.add(base_from_part.position, sp.scale(normal, shift)),
                            base_from_part.rotation)
        if not shift < least or not f.collision.distance_to_base(name, moved) > 0.0:
            continue
        world = cast(sp.Pose, f.base_pose).compose(moved)
        near = f.collision.environment_near(world.apply(body.center_of_mass),
                                            body.radius_about_cm)
        if near and not f.collision.distance_to_environment(name, world, near)[0] > 0.0:
            continue  # out of the base into the table (a review: squeezed between them)
        best, least = moved, shift
    return best


# --- free flight and contact with the environment -------------------------------------

def _flight_pose(f: _Frame, body: Body, start: free.Flight,
                 t_ns: int) -> tuple[free.Flight, sp.Vec3, sp.Vec3, sp.Pose]:
    physics = f.scene.physics
    stats = f.collision.stats
    stats["closed_form_evals"] += 1  # the CM's parabola
    if t_ns > start.t_ns and physics.free_rotation != "constant_omega":
        if physics.free_rotation == "momentum" and free.symmetry(body.principal_moments):
            stats["closed_form_evals"] += 1  # an axisymmetric body turns in closed form
        else:
            stats["integrator_steps"] += onbase.substeps((t_ns - start.t_ns) * 1e-9,
                                                         physics.free_rotation_max_step_s)
    flight = free.advance(start, t_ns, model=physics.free_rotation, moments=body.principal_moments,
                          order=physics.free_rotation_order,
                          max_step_s=physics.free_rotation_max_step_s)
    cm, v = free.cm_at(start, t_ns, physics.gravity_free)
    pose = free.pose(flight, cm, part_from_principal=body.part_from_principal,
                     center_of_mass=body.center_of_mass)
    return flight, cm, v, pose


# A surface a part leaves at under this (a fraction of the contact tolerance) it touches:
# it passes it (``_grace``), there being no telling touching from overlapping at distance 0.
_TOUCHING: Final = 1e-3


def _grace(f: _Frame, part: str, base_from_part: sp.Pose, before: free.Flight | None = None
           ) -> tuple[tuple[int, ...] | None, tuple[float, ...]]:
    """What of the base a part leaving it at ``base_from_part`` passes until they have
    separated once (``Flight.grace``): the surfaces it touches (within twice the contact
    tolerance; ``CollisionWorld.surface_gaps``), or None for the whole base
    (``physics.flight_grace`` whole_base); and the gap it leaves each at
    (``Flight.grace_gaps``), where it is met at a tenth of that (``_met_at``), so that a part
    moving along a surface passes it and one moving into it meets it (an engineer's trial:
    a pin that slid up out of a bore with 0.1 mm of clearance moved sideways through the
    bore's wall into the boss). A graze (``before``, the flight that met the base) keeps
    the gaps its surfaces were first left at: taken again at each meeting, the gap halved
    each time, and a part pressed onto a face it could not rest on crept through it (a
    review: 10 mm into a plate at 87 degrees)."""
    physics = f.scene.physics
    if physics.flight_grace == "whole_base":
        return None, ()
    grace, gaps = f.collision.surface_gaps(part, base_from_part,
                                           2.0 * physics.contact_tolerance)
    if before is not None and before.grace and not before.base_clear:
        # (Not a flight that had got clear: a surface met again after that is met anew; its
        # old gap, left at 0, passed it whole: a review's plate 7.9 mm into a block.)
        first = dict(zip(before.grace, before.grace_gaps))
        gaps = tuple(first.get(s, d) for s, d in zip(grace, gaps))
    return grace, gaps


def _met_at(f: _Frame, gap: float) -> float:
    """How near a part comes to a surface it left at ``gap`` before it meets it: a tenth of
    that (half, at first, made the bore's wall and rim, one surface in reach on both sides,
    wedge a pin tilted half a degree in a bore of 0.1 mm clearance half way down);
    nothing (0: it passes it) where it left it touching, under a thousandth of the contact
    tolerance, there being no telling touching from overlapping at distance 0 (a nominal
    fit, a face it rested on)."""
    tol = f.scene.physics.contact_tolerance
    # (No farther than the tolerance, where the rest of the base is met: a gap raised by a
    # part that went far from a surface before coming back is met as any other face.)
    return min(0.1 * gap, tol) if gap >= _TOUCHING * tol else 0.0


def _finite(values: tuple[float, ...]) -> bool:
    """``all(map(math.isfinite, values))``; compiled, ``isinf`` and ``isnan`` are C calls
    where ``math.isfinite`` (no mypyc primitive) would be a Python call per number."""
    for v in values:
        if math.isinf(v) or math.isnan(v):
            return False
    return True


# Grazes a flight goes on from within one frame, at most (then the frame's rest waits for
# the next frame, as every graze's did before 2026-12-07).
_GRAZES_A_FRAME: Final = 8


def _fly(f: _Frame, index: int, grazed: int = 0) -> None:
    part = f.parts[index]
    body = f.scene.parts[index]
    physics = f.scene.physics
    start: free.Flight = part.motion  # type: ignore[assignment]
    t_a, t_b = start.t_ns, f.t_ns
    if t_b <= t_a:
        return
    flight, cm_b, v_b, pose_b = _flight_pose(f, body, start, t_b)
    if not (_finite(pose_b.position) and _finite(pose_b.rotation) and _finite(v_b)):
        f.change_mode(index, PartState(part.name, STATIC, part.pose), Cause.NUMERICAL_FAULT)
        return
    w_b = free.omega_world(flight, model=physics.free_rotation, moments=body.principal_moments)
    moved = part.moved(pose_b, v_b, w_b, flight)
    # Broad phase: a sphere around the whole path of the CM over the frame, widened by the
    # parabola's sag off its chord and by the part's own size.
    cm_a, _ = free.cm_at(start, t_a, physics.gravity_free)
    dt = (t_b - t_a) * 1e-9
    sag = sp.norm(physics.gravity_free) * dt * dt / 8.0
    center = sp.scale(sp.add(cm_a, cm_b), 0.5)
    reach = 0.5 * sp.norm(sp.sub(cm_b, cm_a)) + sag + body.radius_about_cm \
        + physics.contact_tolerance
    near = f.collision.environment_near(center, reach)
    base = _base_path(f, center, reach)
    grace = None if flight.base_clear else flight.grace
    gaps = () if flight.base_clear else flight.grace_gaps
    starts: tuple[float, ...] = ()
    if base is not None and not flight.base_clear:
        # Just off the base: what it touched as it left (the whole base, with flight_grace
        # whole_base) is no obstacle until the part has separated from it.
        base_from_part = cast(sp.Pose, f.base_pose).inverse().compose(pose_b)
        if f.collision.distance_to_base(part.name, base_from_part) > 2.0 * physics.contact_tolerance:
            moved = replace(moved, motion=replace(flight, base_clear=True))
        if grace is None:
            base = None
        elif grace:
            # Where it is from each at the frame's start, and the gaps raised to that: a
            # surface left touching (passed whole) is met once the part has been off it (a
            # review: a block let go touching a plate, which went away 0.08 mm and came
            # back, passed 9.9 mm into it).
            starts = tuple(f.collision.surface_distances(
                part.name, base.at_time(t_a).inverse().compose(part.pose), grace))
            raised = tuple(max(g, d) for g, d in zip(gaps, starts))
            if raised != gaps:
                gaps = raised
                m = cast(free.Flight, moved.motion)
                moved = replace(moved, motion=replace(m, grace_gaps=raised))
    elif base is None and not flight.base_clear:
        moved = replace(moved, motion=replace(flight, base_clear=True))
    if not near and base is None:
        f.parts[index] = moved
        return
    contact = _time_of_contact(f, body, start, near, base, t_a, t_b, part.pose, pose_b, grace,
                               gaps, starts)
    if contact is None:
        f.parts[index] = moved
        return
    t_c, pose_c, other, surface = contact
    if other is None:
        # Of what it passes, not the surface it met (``Flight.grace_gaps``).
        if grace is not None and surface >= 0:
            grace = tuple(s for s in grace if s != surface)
        f.events.append(ContactMade(f.inputs.frame, part.name, Cause.HIT_BASE.value,
                                    cast(Body, f.scene.base).name, t_c))
        base_at_contact = base.at_time(t_c)  # type: ignore[union-attr]
        base_from_part = base_at_contact.inverse().compose(pose_c)
        # The flight's state at the contact: what a snap keeps and a graze flies on with.
        flown = None
        if body.assembly is not None and physics.landing == "constraints":
            flown = _flight_pose(f, body, start, t_c)
            if _onto_base(f, index, base_from_part, None, flown[2], free.omega_world(
                    flown[0], model=physics.free_rotation, moments=body.principal_moments)):
                return  # came onto a constraint of its own, or its final pose
        normal, on_face, point = f.collision.base_contact(part.name, base_from_part, grace)
        # Leaving the base, it lands only on a face: the edge of another surface flush
        # with the one it leaves along (a seam) gives directions that would hold it up.
        up = _support(f, normal) if on_face or grace is None else None
        if up is None and normal is not None:
            up = _support_elsewhere(f, part.name, base_from_part, grace or ())
        again = up is None and _met_again(f, body, start, t_a, part.pose, pose_c)
        # (The session's time, not the flight's: met at once, its flight hardly advances.)
        held_ns = (start.held_ns or f.t_prev_ns) if again else 0
        if again:
            up = _wedged(f, start, normal, f.t_ns - held_ns)
        if up is not None:
            _rest_on_base(f, index, base_from_part, up, Cause.LANDED_ON_BASE)
            return
        # It hit a face that cannot hold it (the underside, a wall): it loses its speed into
        # the base and flies on from the contact, grazing the base until they separate.
        contact_flight, cm_c, v_c, _ = flown if flown is not None \
            else _flight_pose(f, body, start, t_c)
        w_c = free.omega_world(contact_flight, model=physics.free_rotation,
                               moments=body.principal_moments)
        if again:
            w_c = _zero3()  # held against the base: it slides, no longer turning
        v_c, w_c = _graze(body, base_at_contact, pose_c, normal, point, v_c, w_c,
                          _base_motion(f, point)[0])
        if surface >= 0:
            # Met where it was passed: back out to the gap it first left that surface at,
            # or it meets it again at once, and again, nearer each time.
            pose_c, cm_c = _back_out(f, part.name, start, surface, base_at_contact, pose_c,
                                     cm_c)
            base_from_part = base_at_contact.inverse().compose(pose_c)
        grace, gaps = _grace(f, part.name, base_from_part, start)
        flight = free.start(t_ns=t_c, cm=cm_c, velocity=v_c, omega_world=w_c,
                            world_from_part=pose_c, part_from_principal=body.part_from_principal,
                            principal_moments=body.principal_moments, base_clear=False,
                            grace=grace, grace_gaps=gaps,
                            after_graze=True,
                            grazed_normal=normal if normal is not None else sp.ZERO3,
                            held_ns=held_ns)
        f.parts[index] = PartState(part.name, INSPACE, pose_c, v_c, w_c, flight)
        if grazed + 1 < _GRAZES_A_FRAME:
            # The rest of the frame flown from the graze: it waited for the next frame, a
            # frame behind, and a base moving on meanwhile met the next frame's flight
            # inside it (a review: a plate driven into a block, 2.4 mm in).
            _fly(f, index, grazed + 1)
        return
    f.events.append(ContactMade(f.inputs.frame, part.name, Cause.HIT_ENVIRONMENT.value,
                                f.collision.environment_name(other), t_c))
    f.change_mode(index, PartState(part.name, STATIC, pose_c), Cause.HIT_ENVIRONMENT)


# Met again and again so for this long (ns), a part rests where it is (``_wedged``).
_WEDGED_AFTER_NS: Final = 100_000_000


def _back_out(f: _Frame, part: str, start: free.Flight, surface: int, base: sp.Pose,
              pose: sp.Pose, cm: sp.Vec3) -> tuple[sp.Pose, sp.Vec3]:
    """The part's pose and CM moved along the normal of ``surface`` (one its flight passed,
    ``Flight.grace``, met at a tenth of the gap it first left it at) back out to that gap."""
    gap = dict(zip(start.grace or (), start.grace_gaps)).get(surface)
    if gap is None:
        return pose, cm
    # (Not beyond twice the tolerance, where a surface stops being passed: a gap raised by a
    # part that went far from the surface would be a jump, not a back-out.)
    gap = min(gap, 2.0 * f.scene.physics.contact_tolerance)
    base_from_part = base.inverse().compose(pose)
    normal, _, _ = f.collision.base_contact(part, base_from_part, None, (surface,))
    if normal is None:
        return pose, cm
    now = f.collision.surface_distance(part, base_from_part, surface)
    depth = gap - now
    if not depth > 0.0:
        return pose, cm
    shift = sp.scale(sp.quat_rotate(base.rotation, normal), depth)
    moved = sp.Pose(sp.add(pose.position, shift), pose.rotation)
    # Not where that brings it nearer the surface elsewhere (a pin spanning its bore,
    # one surface: out from one side is into the other, and back, frame after frame), nor
    # within the tolerance of the rest of the base (a review: unchecked, it could be put
    # inside another face, and rest there).
    moved_from_base = base.inverse().compose(moved)
    if f.collision.surface_distance(part, moved_from_base, surface) <= now:
        return pose, cm
    rest = tuple(sorted(set(start.grace or ()) | {surface}))
    if f.collision.distance_to_base(part, moved_from_base, rest) \
            <= f.scene.physics.contact_tolerance:
        return pose, cm
    return moved, sp.add(cm, shift)


def _met_again(f: _Frame, body: Body, start: free.Flight, t_a: int, pose_a: sp.Pose,
               pose_c: sp.Pose) -> bool:
    """Whether a part has met a base face that cannot hold it again before any point of it
    moved the contact tolerance since it last met one (a graze at ``t_a``): it is held
    against the base, and stops turning (each graze stops only the motion into the face it
    meets, there being no contact force in flight: a pin turned in its bore was stopped by
    one side and the other at ever shorter intervals, turning on between them)."""
    if not start.after_graze or start.base_clear or start.t0_ns != t_a:
        return False
    angle = sp.quat_angle_between(pose_a.rotation, pose_c.rotation)
    moved = sp.norm(sp.sub(pose_c.apply(body.center_of_mass), pose_a.apply(body.center_of_mass)))
    return moved + angle * body.radius_about_cm <= f.scene.physics.contact_tolerance


def _wedged(f: _Frame, start: free.Flight, normal: sp.Vec3 | None,
            held_ns: int) -> sp.Vec3 | None:
    """For a part met again (``_met_again``) at a face of normal ``normal`` (base axes),
    soon after one of normal ``start.grazed_normal``: the way up (base axes) if the two
    faces hold it up together, the way a face that holds a part up does alone (``_support``),
    else None (it slides on between them). They hold it if straight up is a sum of the two
    normals with no negative part, to within 0.1 (6 degrees), whose weights sum to at most
    10 (a V no narrower than a face that holds a part alone): a part in a V-groove is
    wedged; a pin against two facets of its bore, both upright, or against both sides of
    its bore, tilted, falls on. Met again and again so for 0.1 s
    (``held_ns`` so far; a time, not a count of meetings, which is at most one a frame and
    so would depend on the tracker's rate), a part rests where it is whatever the faces:
    no contact force in flight moves it (a pin tilted across its bore, over the tilt its
    clearance allows, touches the one surface of its wall on both sides)."""
    up = _support(f, None)
    if up is None:
        return None  # nothing presses it onto anything
    if held_ns >= _WEDGED_AFTER_NS:
        return up
    if normal is None:
        return None  # overlapping: no face to tell
    n1, n2 = start.grazed_normal, normal
    c, p1, p2 = sp.dot(n1, n2), sp.dot(n1, up), sp.dot(n2, up)
    best = min(sp.norm(sp.sub(up, sp.scale(n1, max(0.0, p1)))),
               sp.norm(sp.sub(up, sp.scale(n2, max(0.0, p2)))))
    det = 1.0 - c * c
    if det > 1e-12:
        a, b = (p1 - c * p2) / det, (p2 - c * p1) / det
        # A V no narrower than a face holds alone (its normal within 84 degrees of up,
        # ``_MIN_SUPPORT_COS``): two walls facing each other, as a bore's on both sides of
        # a pin tilted within the contact tolerance, do not hold it (a pin so wedged half a
        # degree off upright, 7 mm above its bore's bottom).
        if a >= 0.0 and b >= 0.0 and (a + b) * _MIN_SUPPORT_COS <= 1.0:
            best = min(best, sp.norm(sp.sub(up, sp.add(sp.scale(n1, a), sp.scale(n2, b)))))
    return up if best <= 0.1 else None


def _support_elsewhere(f: _Frame, part: str, base_from_part: sp.Pose,
                       grace: tuple[int, ...]) -> sp.Vec3 | None:
    """Where the face nearest a part cannot hold it up (a wall, an overhang), the normal of
    another face it touches too (within the contact tolerance; not one ``grace`` passes)
    that can: a block let go in the corner of a plate and a wall leaning over it touches
    both, and which is nearest is round-off's choice (a physics audit: the wall's, and
    the block flew, passed the plate's top as a surface it touched as it left, and came to
    rest 19.9 mm deep in a 20 mm plate, on its bottom face). None where none can."""
    tol = f.scene.physics.contact_tolerance
    touched = f.collision.surfaces_within(part, base_from_part, tol)
    for surface in touched:
        if surface in grace:
            continue
        others = tuple(sorted(set(grace) | {s for s in touched if s != surface}))
        normal, on_face, _ = f.collision.base_contact(part, base_from_part, others)
        if on_face:
            up = _support(f, normal)
            if up is not None:
                return up
    return None


def _support(f: _Frame, normal: sp.Vec3 | None) -> sp.Vec3 | None:
    """The normal (base axes) of the touched base face if gravity presses the part onto it;
    None for a face that cannot hold it up (underneath, a vertical wall)."""
    g = _to_base(f, f.scene.physics.gravity)
    if sp.norm(g) == 0.0:
        return None  # nothing presses it onto anything
    up = sp.scale(sp.normalize(g), -1.0)
    if normal is None:  # overlapping: no face to tell; take the one gravity presses on
        return up
    # A face steeper than this (84 degrees) is a wall: it does not hold the part up.
    return normal if sp.dot(up, normal) > _MIN_SUPPORT_COS else None


def _graze(body: Body, base: sp.Pose, pose: sp.Pose, normal: sp.Vec3 | None,
           point: sp.Vec3, v: sp.Vec3, w: sp.Vec3,
           v_face: sp.Vec3 = sp.ZERO3) -> tuple[sp.Vec3, sp.Vec3]:
    """The velocity and angular velocity (world) of a part at ``pose`` that meets a base
    face it slides along (normal and the part's touching point in the axes of the base,
    posed at ``base``; ``v_face``, the world velocity of the base there): the velocity
    loses its component into the face, relative to the face (a wall moving into a part
    pushes it: it passed through it), and where the turning still carries the touching
    point into the face, the least turning impulse (about ``r x n``, in the inertia's
    metric, so the energy only falls) takes out what does: a part turned into a wall kept
    turning into it, and a part leaving a face keeps the turning its leaving outruns (a
    review: a block thrown off a face lost all its spin). Not a full impact at the point,
    which would set a part met flat on a face turning about the corner fcl names as
    nearest."""
    if normal is None:
        return v, w
    n = sp.quat_rotate(base.rotation, normal)
    into = sp.dot(sp.sub(v, v_face), n)
    if into < 0.0:
        v = sp.sub(v, sp.scale(n, into))
        into = 0.0
    r = sp.sub(base.apply(point), pose.apply(body.center_of_mass))
    arm = sp.cross(r, n)
    point_into = into + sp.dot(w, arm)
    if not point_into < 0.0:
        return v, w
    # In principal axes the inverse inertia is diagonal.
    q = sp.quat_mul(pose.rotation, body.part_from_principal)
    a = sp.quat_rotate(sp.quat_conj(q), arm)
    moments = body.principal_moments
    turn = (a[0] / moments[0], a[1] / moments[1], a[2] / moments[2])
    reach = sp.dot(a, turn)
    if not reach > 0.0:
        return v, w
    return v, sp.sub(w, sp.quat_rotate(q, sp.scale(turn, point_into / reach)))


def _rest_on_base(f: _Frame, index: int, base_from_part: sp.Pose, up: sp.Vec3,
                  cause: Cause) -> None:
    """Lie on the base on no constraint, on the face with normal ``up`` (base axes): ride
    with it until the base turns so that gravity pulls the part off that face."""
    part = f.parts[index]
    pose = cast(sp.Pose, f.base_pose).compose(base_from_part)
    f.change_mode(index, PartState(part.name, ONBASESTATIC, pose, _zero3(), _zero3(),
                                   Resting(base_from_part, up)), cause)


@dataclass(frozen=True)
class _BasePath:
    """The base part over a frame: its pose at both ends, interpolated in between."""

    start: sp.Pose
    end: sp.Pose
    speed: float      # |velocity of the base origin|
    omega: float      # |angular velocity|
    t0_ns: int = 0    # the frame's start and end (``at_time``)
    t1_ns: int = 0

    def at(self, s: float) -> sp.Pose:
        p0, p1 = self.start.position, self.end.position
        return sp.Pose((p0[0] + s * (p1[0] - p0[0]), p0[1] + s * (p1[1] - p0[1]),
                        p0[2] + s * (p1[2] - p0[2])),
                       sp.slerp(self.start.rotation, self.end.rotation, s))

    def at_time(self, t_ns: int) -> sp.Pose:
        """The base at the instant ``t_ns`` of the frame: a flight that starts within the
        frame (a part leaving the base at a fraction of it) meets the base where it is
        then, not where it was at the frame's start."""
        span = self.t1_ns - self.t0_ns
        # (A flight that met the base within the last frame starts this one before it:
        # the base is taken where it was at this frame's start, as it always was.)
        return self.at(max(0.0, (t_ns - self.t0_ns) / span) if span > 0 else 1.0)


def _base_path(f: _Frame, center: sp.Vec3, reach: float) -> _BasePath | None:
    """The base as an obstacle to a flying part this frame, if their spheres can meet."""
    if f.scene.base is None or f.base_pose is None:
        return None
    start = f.base_prev or f.base_pose
    end = f.base_pose
    travel = sp.norm(sp.sub(end.position, start.position))
    middle = sp.scale(sp.add(start.position, end.position), 0.5)
    f.collision.stats["bounding_tests"] += 1
    if sp.norm(sp.sub(center, middle)) > reach + 0.5 * travel + f.collision.base_radius:
        return None
    dt = f.dt_s
    turn = sp.quat_angle_between(start.rotation, end.rotation)
    return _BasePath(start, end, travel / dt if dt > 0 else 0.0, turn / dt if dt > 0 else 0.0,
                     f.t_prev_ns, f.t_ns)


def _time_of_contact(f: _Frame, body: Body, start: free.Flight, near: tuple[int, ...],
                     base: _BasePath | None, t_a: int, t_b: int, pose_a: sp.Pose,
                     pose_b: sp.Pose, grace: tuple[int, ...] | None = None,
                     gaps: tuple[float, ...] = (), starts: tuple[float, ...] = ()
                     ) -> tuple[int, sp.Pose, int | None, int] | None:
    """First time in [t_a, t_b] at which the part comes within the contact tolerance of an
    environment object or of the (moving) base part: ``(time, pose, index, surface)``, with
    index ``None`` for the base, or ``None`` when there is no contact. With ``grace`` the
    base is taken without those surfaces (a part that has just left it: ``Flight.grace``),
    except that each is met at a tenth of the gap in ``gaps`` it was left at (``_met_at``),
    as the part comes nearer than ``starts`` (each one's distance at ``t_a``); ``surface``
    is the one met so (-1 for any other obstacle).

    Conservative advancement: at distance d no point of the part can close the gap in less
    than d / (bound on its speed relative to the obstacle), so stepping by that never passes
    through an object, however thin or fast. A contact is only ever reported at a distance
    within the tolerance; if the iteration budget runs out (a part skimming a surface), the
    end of the frame decides.
    """
    physics = f.scene.physics
    tol = physics.contact_tolerance
    g = sp.norm(physics.gravity_free)
    if physics.free_rotation == "constant_omega":
        omega_max = sp.norm(start.omega_world)
    else:
        omega_max = free.max_angular_speed(start.momentum_principal, body.principal_moments)
    # Each surface of ``grace`` met short of passing: where it is met, and where the part
    # is from it at the start (``starts``): a surface it is within reach of is met only as
    # the part comes nearer it than that (a pin spanning its bore, within reach of its wall
    # on both sides, falls down it; met at once, it hung where it was).
    met: list[tuple[int, float, float]] = []
    if base is not None:
        for s, gap, d_0 in zip(grace or (), gaps, starts):
            at = _met_at(f, gap)
            if at > 0.0:
                met.append((s, at, d_0))
    met_surfaces = tuple(s for s, _, _ in met)

    def probe(t: int, pose: sp.Pose) -> tuple[float, float, int | None, int]:
        """(room, ahead, index, surface): the least of each obstacle's distance less where
        it is met (<= 0 where one is met) and which that is; and how far the part may
        advance before it could pass half way in from where any is met."""
        d: float
        which: int | None
        d, which = (f.collision.distance_to_environment(body.name, pose, near) if near
                    else (float("inf"), -1))
        base_from_part = pose
        if base is not None:
            base_from_part = base.at_time(t).inverse().compose(pose)
            d_base = f.collision.distance_to_base(body.name, base_from_part, grace)
            if d_base < d:
                d, which = d_base, None
        room, ahead, hit, surface = d - tol, d - 0.5 * tol, which, -1
        if met:
            for (s, d_s, d_0), d_now in zip(met, f.collision.surface_distances(
                    body.name, base_from_part, met_surfaces)):
                gap = d_now - d_s
                if gap <= 0.0 and not d_now < d_0:
                    ahead = min(ahead, 0.0)  # within reach, not nearer: the least step
                    continue
                if gap < room:
                    room, hit, surface = gap, None, s
                ahead = min(ahead, gap + 0.5 * d_s)
        return room, ahead, hit, surface

    base_speed = 0.0
    if base is not None:
        # Every point of the base is within base_radius of its origin, which moves at
        # base.speed while the base turns at base.omega (linear and slerp interpolation).
        base_speed = base.speed + base.omega * f.collision.base_radius
    def first_within(lo: int, hi: int, hit: tuple[int, sp.Pose, int | None, int]
                     ) -> tuple[int, sp.Pose, int | None, int]:
        """Bisect [lo, hi] (clear at lo, ``hit`` at hi) for where the part came within
        reach of what it met, so that it stops at the surface, not inside it."""
        for _ in range(60):
            if hi - lo <= 1:
                break
            mid = (lo + hi) // 2
            pose_mid = _flight_pose(f, body, start, mid)[3]
            room_mid, _, which_mid, surface_mid = probe(mid, pose_mid)
            if room_mid <= 0.0:
                hi, hit = mid, (mid, pose_mid, which_mid, surface_mid)
            else:
                lo = mid
        return hit

    # A step passes at least half the tolerance: a part moving along a surface it left
    # near (``met``) would otherwise take steps of its tiny distance. Where such a step
    # meets something, bisect back to where it did.
    least = 0.5 * tol
    t, pose, t_last, long_step = t_a, pose_a, t_a, False
    for _ in range(_CA_MAX_ITERATIONS):
        room, ahead, which, surface = probe(t, pose)
        if room <= 0.0:
            if long_step:
                return first_within(t_last, t, (t, pose, which, surface))
            return t, pose, which, surface
        _, v = free.cm_at(start, t, physics.gravity_free)
        speed = sp.norm(v) + g * (t_b - t) * 1e-9 + omega_max * body.radius_about_cm \
            + base_speed
        if speed <= 0.0:
            return None
        long_step = ahead < least
        t_next = t + max(1, int((least if long_step else ahead) / speed * 1e9))
        if t_next >= t_b:
            break
        t_last, t = t, t_next
        pose = _flight_pose(f, body, start, t)[3]
    room_b, _, which_b, surface_b = probe(t_b, pose_b)
    if room_b > 0.0:
        return None
    # Out of budget and touching at the frame's end: bisect for where it came within the
    # tolerance, so the part stops at the surface, not inside it.
    return first_within(t, t_b, (t_b, pose_b, which_b, surface_b))


# --- constrained motion on the base (paper 5.2, 5.3, 6) -----------------------------------

_CA_BASE_ITERATIONS: Final = 4096
_INSIDE_ENVELOPE = True  # the shortcut of _sweep for turning in place (off in a test)
_STATIC_HOLD = True  # the shortcut of _slide_and_turn for a held slide (off in a test)
# Allowance (in tolerances) for fcl's distance from the envelope, a cylinder primitive
# (GJK), so that the envelope's clearance is a safe lower bound of the part's distance.
_ENVELOPE_MARGIN: Final = 0.01
_CONTACT_SLACK_M: Final = 1e-9  # round-off allowance for a part moving along an obstacle it touches
# Of the contact tolerance: a part passing what it touches (``_passing``) is stopped this
# near anything (a fit with less radial clearance than this is held by its bore's rim);
# coming this near within _PASS_REACH tolerances of travel, it moves into what it touches.
_PASS_DEPTH: Final = 0.1
_PASS_REACH: Final = 20.0


def _to_base(f: _Frame, world: sp.Vec3) -> sp.Vec3:
    return sp.quat_rotate(sp.quat_conj(cast(sp.Pose, f.base_pose).rotation), world)


def _axis(mate: cn.Mate) -> sp.Vec3 | None:
    return mate.base_dirs[0] if mate.kind == "axis" else None


def _alpha_at_rest(body: Body, mate: cn.Mate, m: OnBase, g: sp.Vec3) -> float:
    """Angular acceleration from gravity about the shaft at the current angle (g base axes)."""
    if not mate.turn:
        return 0.0
    u, r0 = mate.base_dirs[0], m.cm_offset
    k = body.mass_kg / mate.inertia_about_axis
    return k * (math.cos(m.angle) * sp.dot(g, sp.cross(u, r0)) - math.sin(m.angle) * sp.dot(g, r0))


def _drive(f: _Frame, body: Body, mate: cn.Mate, m: OnBase) -> tuple[bool, bool, bool]:
    """At rest on the base now: (gravity lifts it off, it starts sliding, it starts turning)."""
    physics = f.scene.physics
    g = _to_base(f, physics.gravity_slide)
    n_load, lifted = onbase.normal_load(mate.kind, mate.base_dirs, _axis(mate), g)
    slides = False
    if mate.slide_dirs:
        gt = onbase.project_blocked(onbase.tangential(mate.slide_dirs, g), m.blocked_slide)
        slides = onbase.starts_sliding(gt, n_load, mate.static_friction)
    alpha = _alpha_at_rest(body, mate, m, _to_base(f, physics.gravity_rotation))
    # Static friction about the shaft holds it while gravity's torque is within the limit.
    turns = abs(alpha) * mate.inertia_about_axis > mate.holding_torque \
        and alpha * m.blocked_turn <= 0.0
    return lifted, slides, turns


def _release_on_base(f: _Frame, index: int, hand: str) -> bool:
    """Release onto the base: at the final pose, or onto the first recognised constraint."""
    part = f.parts[index]
    base_from_part = cast(sp.Pose, f.base_pose).inverse().compose(part.pose)
    return _onto_base(f, index, base_from_part, hand, part.linear_velocity,
                      part.angular_velocity)


def _onto_base(f: _Frame, index: int, base_from_part: sp.Pose, hand: str | None,
               v: sp.Vec3, w: sp.Vec3) -> bool:
    """The part at ``base_from_part`` goes onto the base: at its final pose it is placed,
    on the first constraint recognised there it goes onto that; else False. Let go by
    ``hand`` (a release: ``PartReleased`` and the ``released_`` causes), or, with ``hand``
    None, come there in flight (physics ``landing: constraints``; ``landed_`` causes).
    ``v`` and ``w`` are its world velocities there (``physics.snap_velocity``)."""
    part = f.parts[index]
    body = f.scene.parts[index]
    assembly: cn.Assembly = body.assembly  # type: ignore[assignment]
    placed = Cause.RELEASED_AT_FINAL_POSE if hand is not None else Cause.LANDED_AT_FINAL_POSE
    onto = Cause.RELEASED_ON_BASE if hand is not None else Cause.LANDED_ON_CONSTRAINT
    if cn.at_final_pose(assembly, base_from_part):
        _place(f, index, placed, hand=hand)
        return True
    for mate_index, mate in enumerate(assembly.mates):
        if mate.kind == "axis" and mate.misfit and f.scene.physics.coaxial_fit == "radial":
            # The part does not fit the shaft or bore (``Mate.misfit``: a pin wider than its
            # bore slid off at once and fell through the boss, graced as what it touched as
            # it left; a sleeve narrower than its shaft passed over it). It is let go as
            # any part is, onto what is under it (vade-record warns of it).
            continue
        snapped = cn.recognise(mate, base_from_part)
        if snapped is None:
            continue
        zeros = tuple(0.0 for _ in mate.slide_dirs)
        if mate.kind == "axis" and mate.slide_dirs:
            # On the shaft's line but not on the shaft: within the recognition distance of
            # its end the snap puts the bore onto the end (as it puts it onto the axis),
            # and the part slides on from there; farther off it is not on this constraint
            # (it slid off at once, and flew through the base it was still touching).
            gap = -_bore_overlap(mate, OnBase(mate_index, snapped, zeros, zeros), zeros)
            if gap > mate.distance_tolerance:
                continue
            if gap > 0.0:
                toward = gap if _bore_overlap(mate, OnBase(mate_index, snapped, zeros, zeros),
                                              (gap,)) > -gap else -gap
                snapped = sp.Pose(sp.add(snapped.position, sp.scale(mate.slide_dirs[0], toward)),
                                  snapped.rotation)
        motion = OnBase(mate_index, snapped, zeros, zeros,
                        cm_offset=cn.cm_offset_base(mate, snapped) if mate.turn else _zero3())
        if hand is None and not _lands_clear(f, body, mate, motion):
            continue  # met the base elsewhere than on this constraint's feature
        if cn.at_final_pose(assembly, snapped):
            _place(f, index, placed, hand=hand)
            return True
        lifted, slides, turns = _drive(f, body, mate, motion)
        if lifted:
            continue  # gravity pulls it off this plane: not a support
        pose = cast(sp.Pose, f.base_pose).compose(snapped)
        v_on, w_on = _zero3(), _zero3()
        if f.scene.physics.snap_velocity == "along_constraint":
            motion = _kept_rates(f, body, mate, motion, v, w, slides, turns)
            if motion.angle_rate != 0.0 or any(r != 0.0 for r in motion.slide_rate):
                slides = True  # it moves on along the constraint from the snap
                v_rel, w_rel = _relative_rates(body, mate, motion, motion.slide_rate, 0.0,
                                               motion.angle_rate)
                q = cast(sp.Pose, f.base_pose).rotation
                v_on, w_on = sp.quat_rotate(q, v_rel), sp.quat_rotate(q, w_rel)
        # (``zero``: the snap is an inelastic contact, the part at rest relative to the base.)
        mode = ONBASESLIDE if (slides or turns) else ONBASESTATIC
        if hand is not None:
            f.events.append(PartReleased(f.inputs.frame, part.name, onto.value, hand, v, w))
        else:
            f.landed = (*f.landed, index)
        f.change_mode(index, PartState(part.name, mode, pose, v_on, w_on, motion), onto)
        return True
    return False


def _kept_rates(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, v: sp.Vec3,
                w: sp.Vec3, slides: bool, turns: bool) -> OnBase:
    """``m`` with the rates that the world velocities ``v`` (of the centre of mass) and
    ``w``, relative to the base, keep on the constraint, as in a plastic contact with a
    frictionless feature: the momentum along each slide direction (the velocity's
    component) and, on an axis, the angular momentum about the shaft, ``u.(I w) +
    m (r x v).u``, over ``J`` (the feature's reactions pass through the shaft, so they have
    no moment about it: a hanging gear let go by a hand moving across the shaft swings).
    The rest (into the base, across the shaft, a spin the constraint does not allow) is
    lost at the snap.

    Where friction holds the part at rest (``slides``, ``turns`` False: ``_drive``), a
    kept motion finer than the simulator resolves is rest: one that would carry the part
    no farther than the contact tolerance in the frame, as Karnopp's band of stiction has
    it, or before friction stops it (a slide within ``v^2 / (2 (f_d N - |g_t|))``, a spin
    within the least of ``|w| J / f_r`` and its swing about where gravity holds it, at the
    part's farthest point from the axis). So a hand let go at rest (its fitted velocity's
    round-off, or a tracker's noise) leaves the part resting, on a slope held only by
    static friction too, not sliding for a frame or off the plate."""
    cm = m.base_from_snap.apply(body.center_of_mass)
    v_base, w_base = _base_motion(f, cm)
    q_inv = sp.quat_conj(cast(sp.Pose, f.base_pose).rotation)
    v_rel = sp.quat_rotate(q_inv, sp.sub(v, v_base))
    w_rel = sp.quat_rotate(q_inv, sp.sub(w, w_base))
    rates = tuple(sp.dot(v_rel, e) for e in mate.slide_dirs)
    spin = 0.0
    u = mate.base_dirs[0]  # the shaft, where it turns
    if mate.turn:
        to_part = sp.quat_conj(m.base_from_snap.rotation)
        u_p = sp.quat_rotate(to_part, u)
        w_p = sp.quat_rotate(to_part, w_rel)
        momentum = sp.dot(u_p, sp.mat_vec(body.inertia_cm, w_p)) \
            + body.mass_kg * sp.dot(sp.cross(m.cm_offset, v_rel), u)
        spin = momentum / mate.inertia_about_axis
    if not (_finite(rates) and math.isfinite(spin)):
        return m
    physics = f.scene.physics
    tol = physics.contact_tolerance
    dt = f.dt_s
    if rates and not slides:
        g = _to_base(f, physics.gravity_slide)
        n_load, _ = onbase.normal_load(mate.kind, mate.base_dirs, _axis(mate), g)
        g_t = math.sqrt(sum(x * x for x in onbase.tangential(mate.slide_dirs, g)))
        stop = mate.dynamic_friction * n_load - g_t
        speed2 = sum(r * r for r in rates)
        if math.sqrt(speed2) * dt <= tol or (stop > 0.0 and speed2 <= 2.0 * stop * tol):
            rates = tuple(0.0 for _ in rates)
    if spin != 0.0 and not turns:
        reach = body.radius_about_cm + sp.norm(m.cm_offset)
        inertia = mate.inertia_about_axis
        angle = math.inf
        if mate.rotational_friction > 0.0:
            angle = abs(spin) * inertia / mate.rotational_friction
        # Gravity across the shaft, as it loads a shaft (``normal_load``).
        g_perp, _ = onbase.normal_load(mate.kind, mate.base_dirs, u,
                                       _to_base(f, physics.gravity_rotation))
        k = body.mass_kg * g_perp * sp.norm(m.cm_offset) / inertia
        if k > 0.0:
            angle = min(angle, abs(spin) / math.sqrt(k))
        if abs(spin) * reach * dt <= tol or angle * reach <= tol:
            spin = 0.0
    return replace(m, slide_rate=rates, angle_rate=spin)


def _lands_clear(f: _Frame, body: Body, mate: cn.Mate, m: OnBase) -> bool:
    """A flying part goes onto a constraint it met only where, snapped onto it, it is on
    the constraint's feature (``_still_on_base``: over the plane's face; on an axis the
    snap puts the bore on the shaft) and clear of the rest of the base (no deeper into it
    than half the tolerance, as a move on the base may be). A review: a block thrown
    against the plate's side was snapped up onto the plane's line beside the plate, and one
    dropped on a low rib was snapped into it. (A release does not ask: the paper recognises
    by the features alone.)"""
    # (On an axis the snap has put the bore on the shaft or onto its end already; at the
    # end a loose fit's walls are farther apart than the tolerance, which would say off.)
    if mate.kind != "axis" and not _still_on_base(
            f, body, mate, m, m.base_from_snap, tuple(0.0 for _ in mate.slide_dirs)):
        return False
    tol = f.scene.physics.contact_tolerance
    if mate.kind == "axis":
        mode, lift = SKIP_COAXIAL, _zero3()
    else:
        mode, lift = SKIP_COPLANAR, _zero3()
        for n in mate.base_dirs:
            lift = sp.add(lift, sp.scale(n, 2.0 * tol))
    return f.collision.base_distance(body.name, m.mate, m.base_from_snap, mode, lift=lift) \
        >= 0.5 * tol - _CONTACT_SLACK_M


def _place(f: _Frame, index: int, cause: Cause, *, hand: str | None = None) -> None:
    part = f.parts[index]
    final = cast(Assembly, f.scene.parts[index].assembly).final_pose
    if hand is not None:
        f.events.append(PartReleased(f.inputs.frame, part.name, cause.value, hand,
                                     part.linear_velocity, part.angular_velocity))
    pose = cast(sp.Pose, f.base_pose).compose(cast(sp.Pose, final))
    f.change_mode(index, PartState(part.name, PLACED, pose), cause)


def _base_motion(f: _Frame, point_base: sp.Vec3) -> tuple[sp.Vec3, sp.Vec3]:
    """World velocity of a base-fixed point and the base's angular velocity, over the frame."""
    dt = f.dt_s
    if f.base_prev is None or dt <= 0.0:
        return _zero3(), _zero3()
    now, before = cast(sp.Pose, f.base_pose), f.base_prev
    v = sp.scale(sp.sub(now.apply(point_base), before.apply(point_base)), 1.0 / dt)
    rel = sp.quat_mul(now.rotation, sp.quat_conj(before.rotation))
    return v, sp.scale(sp.quat_to_rotvec(rel), 1.0 / dt)


def _relative_rates(body: Body, mate: cn.Mate, m: OnBase, slide_rate: tuple[float, ...],
                    angle: float, angle_rate: float) -> tuple[sp.Vec3, sp.Vec3]:
    """CM velocity and angular velocity relative to the base, in base axes."""
    v = _zero3()
    for rate, e in zip(slide_rate, mate.slide_dirs):
        v = sp.add(v, sp.scale(e, rate))
    if not mate.turn or angle_rate == 0.0:
        return v, _zero3()
    u = mate.base_dirs[0]
    r = sp.quat_rotate(sp.quat_unit_axis_angle(mate.unit_axis, angle), m.cm_offset)
    return sp.add(v, sp.scale(sp.cross(u, r), angle_rate)), sp.scale(u, angle_rate)


def _leave(f: _Frame, index: int, cause: Cause, rel: sp.Pose, v_rel: sp.Vec3,
           w_rel: sp.Vec3, *, at: float = 1.0) -> None:
    """Off the base into free flight, with the base's own motion added to the part's; at
    the fraction ``at`` of the frame (the base where the frame's path has it then)."""
    part = f.parts[index]
    body = f.scene.parts[index]
    base = f.base_pose if at >= 1.0 or f.base_prev is None else _BasePath(
        f.base_prev, f.base_pose, 0.0, 0.0).at(at)  # type: ignore[arg-type]
    pose = base.compose(rel)  # type: ignore[union-attr]
    v_base, w_base = _base_motion(f, rel.apply(body.center_of_mass))
    if at < 1.0 and f.base_prev is not None and f.dt_s > 0.0:
        # The base's velocity at that instant of its path (linear in position, slerp in
        # rotation: constant w), not its average over the frame, which differs on a
        # turning base by w x w r dt |at - 1/2| (a review: 6 mm after 0.4 s at 2 rad/s).
        v_origin = sp.scale(sp.sub(cast(sp.Pose, f.base_pose).position, f.base_prev.position),
                            1.0 / f.dt_s)
        v_base = sp.add(v_origin, sp.cross(w_base, sp.quat_rotate(
            base.rotation, rel.apply(body.center_of_mass))))  # type: ignore[union-attr]
    q = base.rotation  # type: ignore[union-attr]
    v = sp.add(sp.quat_rotate(q, v_rel), v_base)
    w = sp.add(sp.quat_rotate(q, w_rel), w_base)
    t_ns = f.t_ns if at >= 1.0 else f.t_prev_ns + int(at * (f.t_ns - f.t_prev_ns))
    grace, gaps = _grace(f, part.name, rel)
    flight = free.start(t_ns=t_ns, cm=pose.apply(body.center_of_mass), velocity=v,
                        omega_world=w, world_from_part=pose,
                        part_from_principal=body.part_from_principal,
                        principal_moments=body.principal_moments, base_clear=False,
                        grace=grace, grace_gaps=gaps)
    f.change_mode(index, PartState(part.name, INSPACE, pose, v, w, flight), cause)


def _check_resting_on_base(f: _Frame) -> None:
    """ONBASESTATIC: does gravity now pull it off, or overcome static friction?"""
    for index in f.awake:
        part = f.parts[index]
        if part.mode is not ONBASESTATIC or f.base_pose is None or index in f.landed:
            continue  # (landed this frame: at rest on it to the frame's end, as let go)
        body = f.scene.parts[index]
        located = f.scene.physics.slide_off == "located" and f.dt_s > 0.0
        if isinstance(part.motion, Resting):
            # No constraint: it stays while gravity presses it onto the base.
            rest = part.motion
            up = rest.up

            def pulls_off(g: sp.Vec3) -> bool:
                return sp.dot(g, up) > 0.0
            if pulls_off(_to_base(f, f.scene.physics.gravity)):
                at = _lift_fraction(f, f.scene.physics.gravity, pulls_off) if located else 1.0
                _leave(f, index, Cause.LIFTED_OFF, rest.base_from_part, _zero3(), _zero3(),
                       at=at)
                if at < 1.0:
                    _fly(f, index)
            continue
        m: OnBase = part.motion  # type: ignore[assignment]
        mate = cast(Assembly, body.assembly).mates[m.mate]
        lifted, slides, turns = _drive(f, body, mate, m)
        if lifted and located and mate.kind != "axis":
            # As gravity turns to pull it off the plane the normal load goes to zero, so
            # static friction gives way just before: it slides, and the slide finds both
            # instants within this frame (_slide_and_turn, which runs next).
            f.change_mode(index, replace(part, mode=ONBASESLIDE), Cause.FRICTION_BROKEN)
        elif lifted:
            rel = cn.relative_pose(mate, m.base_from_snap, m.slide, m.angle)
            _leave(f, index, Cause.LIFTED_OFF, rel, _zero3(), _zero3())
        elif slides or turns:
            f.change_mode(index, replace(part, mode=ONBASESLIDE), Cause.FRICTION_BROKEN)


def _carry_with_base(f: _Frame) -> None:
    """Parts at rest on the base or placed ride with it exactly."""
    if f.base_pose is None:
        return
    for index in f.awake:
        part = f.parts[index]
        if part.mode is ONBASESTATIC:
            m = part.motion
            if isinstance(m, Resting):
                rel = m.base_from_part
            else:
                on = cast(OnBase, m)
                mate = cast(Assembly, f.scene.parts[index].assembly).mates[on.mate]
                rel = cn.relative_pose(mate, on.base_from_snap, on.slide, on.angle)
            f.parts[index] = part.moved(f.base_pose.compose(rel), _zero3(), _zero3(), m)
        elif part.mode is PLACED:
            final = cast(Assembly, f.scene.parts[index].assembly).final_pose
            if final is not None:
                f.parts[index] = part.moved(f.base_pose.compose(final), part.linear_velocity,
                                            part.angular_velocity, part.motion)


def _meet_environment(f: _Frame, before: tuple[PartState, ...]) -> None:
    """Parts on the base part (resting, or moving on a plane) that the base, or their own
    move, takes into the table or another environment object this frame deeper than
    ``_ENV_ALLOWANCE_M``: stopped at the first such instant, STATIC (``hit_environment``),
    moved up out of it by that allowance (``physics.environment_contact``). The base part
    follows the hand and goes on through; the parts on it do not (a physics trial: a block
    on a plate lowered into the table rode 3 cm into it and through it, slid off below it
    and fell for ever: nothing meets a part from inside a mesh).

    The allowance is a tracker's noise: a thin base the hand rests on the table dips into
    it by that much and keeps its parts (a review: a 1.5 mm sheet on the table left parts
    behind, its noise taking them to the table's face). A part on an axis constraint (a pin
    in its bore, a gear on its shaft) is not stopped: the base guides it where it goes (a
    review: a pin sliding down the bore of a plate lying on the table was stopped at the
    table, STATIC, and never placed; a block of its slide by the table is not modelled).

    The frame's path of a part: from its pose at the frame's start to its pose at the end,
    its box's centre linear, its rotation slerp (the arc of a part on a turning base lies
    off that chord by its
    sagitta, r phi^2 / 8: 0.04 mm at 0.3 m from a base turning 2 rad/s at 60 Hz), lifted
    by the allowance (against gravity). Conservative advancement on it, from its box's
    centre: no point moves further than ``reach`` over the frame, so a step of (d - tol/2)
    / reach passes through nothing (at least half the tolerance: met, it is not inside);
    out of its budget, the frame's end decides. One that came onto the base this frame
    (let go or landed) is asked from where it was at the frame's start (the chord standing
    for its flight or hand and the base's carry), and whether it lies wholly inside one at
    the end (let go on a base the hand holds in the table: it stays there, as a part let go
    inside the table does). A part that did not move is not asked; one whose
    sphere stays clear of every object's box is asked nothing more (one test)."""
    physics = f.scene.physics
    if physics.environment_contact != "every_part" or f.base_pose is None \
            or not f.scene.environment:
        return
    tol = physics.contact_tolerance
    g = physics.gravity
    g_norm = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    allowance = _ENV_ALLOWANCE_M if g_norm > 0.0 else 0.0
    lift = sp.scale(g, -allowance / g_norm) if g_norm > 0.0 else sp.ZERO3
    for index in f.awake:
        part = f.parts[index]
        if part.mode is not ONBASESTATIC and part.mode is not ONBASESLIDE:
            continue
        motion = part.motion
        body = f.scene.parts[index]
        if isinstance(motion, OnBase) and cast(Assembly, body.assembly).mates[
                motion.mate].kind == "axis":
            continue  # guided by the base: where it goes, the part goes
        old = before[index]
        # From where it was at the frame's start: on the base, in the hand that let it go
        # onto it, or flying onto it (the chord stands for the flight and the base's carry).
        on_before = old.mode is ONBASESTATIC or old.mode is ONBASESLIDE
        p0 = old.pose
        p1 = part.pose
        if on_before and p0.position == p1.position and p0.rotation == p1.rotation:
            continue  # nothing moved: nothing new to meet
        lo, hi = body.bbox_min, body.bbox_max
        centre = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]))
        ex, ey, ez = hi[0] - centre[0], hi[1] - centre[1], hi[2] - centre[2]
        rho = math.sqrt(ex * ex + ey * ey + ez * ez)  # every point of it within this
        c1 = sp.add(p1.apply(centre), lift)
        reach = sp.norm(sp.sub(c1, sp.add(p0.apply(centre), lift))) \
            + _angle_bound(p0.rotation, p1.rotation) * rho
        # A sphere about its box's centre at the frame's end, widened by that: clear of
        # every object's box, done (a part on a base held above the table: one test).
        if not f.collision.environment_near(c1, rho + reach + tol):
            continue
        box_lo, box_hi = world_box(body, p1)
        widen = reach + tol
        near = f.collision.environment_near_box(
            (box_lo[0] + lift[0] - widen, box_lo[1] + lift[1] - widen,
             box_lo[2] + lift[2] - widen),
            (box_hi[0] + lift[0] + widen, box_hi[1] + lift[1] + widen,
             box_hi[2] + lift[2] + widen))
        if not near:
            continue
        hit = _first_contact(f, part.name, p0, p1, centre, lift, near, reach,
                             not on_before)
        if hit is None:
            continue
        lam, pose, which = hit
        t_c = f.t_prev_ns + int(lam * (f.t_ns - f.t_prev_ns)) if lam < 1.0 else f.t_ns
        f.events.append(ContactMade(f.inputs.frame, part.name, Cause.HIT_ENVIRONMENT.value,
                                    f.collision.environment_name(which), t_c))
        f.change_mode(index, PartState(part.name, STATIC, pose), Cause.HIT_ENVIRONMENT)


# How deep a part on the base may go into the table before the table stops it (m): a
# tracker's noise, as ``_OVERLAP_REACH_M`` is for a part let go in the base.
_ENV_ALLOWANCE_M: Final = 0.002


def _first_contact(f: _Frame, part: str, p0: sp.Pose, p1: sp.Pose, centre: sp.Vec3,
                   lift: sp.Vec3, near: tuple[int, ...], reach: float, arrived: bool
                   ) -> tuple[float, sp.Pose, int] | None:
    """``_meet_environment``'s advancement: the first fraction of the frame at which the
    part, on the chord from ``p0`` to ``p1`` (its box's ``centre`` linear, its rotation
    slerp) lifted by ``lift``, is within the contact tolerance of one of ``near`` (or, one
    that ``arrived`` on the base this frame, lies wholly inside one at the frame's end),
    with that pose and the object; None if it is not."""
    tol = f.scene.physics.contact_tolerance
    c0, c1 = p0.apply(centre), p1.apply(centre)

    def at(lam: float) -> sp.Pose:
        if lam >= 1.0:
            return sp.Pose(sp.add(p1.position, lift), p1.rotation)
        q = sp.slerp(p0.rotation, p1.rotation, lam)
        c = sp.add(c0, sp.scale(sp.sub(c1, c0), lam))
        return sp.Pose(sp.add(sp.sub(c, sp.quat_rotate(q, centre)), lift), q)
    unlifted = sp.scale(lift, -1.0)
    lam = 0.0
    for _ in range(_CA_MAX_ITERATIONS):
        pose = at(lam)
        d, which = f.collision.distance_to_environment(part, pose, near)
        step = d - 0.5 * tol
        if d <= tol:
            # Lifted, it touches one; where it is, it must too (a review: a part 1 mm under
            # a shelf, lifted into it, was stopped for nothing). (Each step leaves it at
            # least half the tolerance from what it meets: met, it is not inside.)
            real = sp.Pose(sp.add(pose.position, unlifted), pose.rotation)
            d_real, _ = f.collision.distance_to_environment(part, real, (which,))
            if d_real <= tol or f.collision.inside_environment(part, real, (which,)) >= 0:
                return lam, pose, which  # (a part thinner than the allowance: wholly in it)
            step = d_real - 0.5 * tol
        if lam >= 1.0:
            if arrived:
                # Come onto the base this frame: wholly inside one (nested meshes are at a
                # distance; let go on a base held in the table) is where it stays.
                inside = f.collision.inside_environment(part, p1, near)  # (where it is)
                if inside >= 0:
                    return lam, pose, inside
            return None
        lam = min(1.0, lam + step / reach) if reach > 0.0 else 1.0
    pose = at(1.0)  # (out of budget: the frame's end decides)
    d, which = f.collision.distance_to_environment(part, pose, near)
    return (1.0, pose, which) if d <= tol else None


def _angle_bound(a: sp.Quat, b: sp.Quat) -> float:
    """At least the angle of the rotation between two unit quaternions, from their chord
    (no inverse trigonometry): |a - b| = 2 sin(angle / 4) on the nearer sign, and
    sin x >= x 2 sqrt(2) / pi on [0, pi / 4], so angle <= |a - b| pi / sqrt(2)."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    d0, d1, d2, d3 = a0 - b0, a1 - b1, a2 - b2, a3 - b3
    e0, e1, e2, e3 = a0 + b0, a1 + b1, a2 + b2, a3 + b3
    near = min(d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3, e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
    return math.sqrt(near) * _PI_OVER_SQRT2


_PI_OVER_SQRT2: Final = 2.2215  # (pi / sqrt(2) = 2.22144..., rounded up)


def world_box(body: Body, pose: sp.Pose) -> tuple[sp.Vec3, sp.Vec3]:
    """A world box around the posed body: its own box's corners, posed (so never smaller)."""
    lo, hi = body.bbox_min, body.bbox_max
    xs, ys, zs = [], [], []
    for x in (lo[0], hi[0]):
        for y in (lo[1], hi[1]):
            for z in (lo[2], hi[2]):
                c = pose.apply((x, y, z))
                xs.append(c[0])
                ys.append(c[1])
                zs.append(c[2])
    return (min(xs), min(ys), min(zs)), (max(xs), max(ys), max(zs))


def _move_on_base(f: _Frame) -> None:
    for index in f.awake:
        if f.parts[index].mode is ONBASESLIDE and f.base_pose is not None \
                and index not in f.landed:
            _slide_and_turn(f, index)


def _clear_blocks(f: _Frame, body: Body, mate: cn.Mate, m: OnBase) -> OnBase:
    """Forget a blocked direction once gravity drives the part away from it."""
    if m.blocked_slide:
        gt = onbase.tangential(mate.slide_dirs, _to_base(f, f.scene.physics.gravity_slide))
        if sum(a * b for a, b in zip(gt, m.blocked_slide)) < 0.0:
            m = replace(m, blocked_slide=())
    if m.blocked_turn:
        alpha = _alpha_at_rest(body, mate, m, _to_base(f, f.scene.physics.gravity_rotation))
        if alpha * m.blocked_turn < 0.0 or m.angle_rate * m.blocked_turn < 0.0:
            m = replace(m, blocked_turn=0)
    return m


def _static_hold(mate: cn.Mate, m: OnBase, physics: Physics,
                 turn_path: onbase.GravityPath | None, q0: sp.Quat, q1: sp.Quat) -> bool:
    """At rest and held by static friction all frame long, whatever the sub-steps sample:
    then sliding would leave the coordinates exactly as they are, and is skipped.

    Within the frame gravity (base axes) turns by at most ``phi``, so it moves by at most
    ``|g| phi`` from its start value; the drive along the slide directions (after the
    blocked projection) and the normal load on an axis or a plane are 1-Lipschitz in g.
    A part that also turns reuses the turning's gravity path, scaled (a test only: when it
    fails, sliding gets its own path).
    """
    for rate in m.slide_rate:  # (compiled, a C loop: ``any`` is a Python call)
        if rate != 0.0:
            return False
    if physics.slide_integrator not in ("analytic", "analytic4", "midpoint") \
            or mate.kind not in ("axis", "plane"):
        return False
    if turn_path is not None and physics.gravity_scale_rotation != 0.0:
        g0 = sp.scale(turn_path.g0,
                      physics.gravity_scale_slide / physics.gravity_scale_rotation)
        phi = turn_path.phi
    else:
        path = onbase.GravityPath(physics.gravity_slide, q0, q1)
        g0, phi = path.g0, path.phi
    gmag = math.sqrt(sp.dot(g0, g0))
    drift = gmag * phi + 1e-12 * gmag
    n_load, _ = onbase.normal_load(mate.kind, mate.base_dirs, _axis(mate), g0)
    gt = onbase.project_blocked(onbase.tangential(mate.slide_dirs, g0), m.blocked_slide)
    drive2 = 0.0
    for c in gt:
        drive2 += c * c
    drive = math.sqrt(drive2)
    return drive + drift <= max(mate.static_friction, mate.dynamic_friction) * (n_load - drift)


def _slide_and_turn(f: _Frame, index: int) -> None:
    """ONBASESLIDE: integrate the coordinates, then the two checks of section 6."""
    part = f.parts[index]
    body = f.scene.parts[index]
    physics = f.scene.physics
    m: OnBase = part.motion  # type: ignore[assignment]
    mate = cast(Assembly, body.assembly).mates[m.mate]
    dt = f.dt_s
    m = _clear_blocks(f, body, mate, m)
    x1, v1, a1, w1 = m.slide, m.slide_rate, m.angle, m.angle_rate
    if dt > 0.0:
        q0 = cast(sp.Pose, f.base_prev or f.base_pose).rotation
        q1 = cast(sp.Pose, f.base_pose).rotation
        turn_path = onbase.GravityPath(physics.gravity_rotation, q0, q1) if mate.turn else None
        if mate.slide_dirs and not (_STATIC_HOLD and _static_hold(mate, m, physics, turn_path,
                                                                 q0, q1)):
            path = onbase.GravityPath(physics.gravity_slide, q0, q1)
            slide_steps = onbase.substeps(dt, physics.slide_step_s)
            # analytic4: two closed-form flows a sub-step.
            f.collision.stats["closed_form_evals" if physics.slide_integrator in (
                "analytic", "analytic4") else "integrator_steps"] += (
                1 if physics.slide_integrator == "paper" else
                2 * slide_steps if physics.slide_integrator == "analytic4" else slide_steps)
            x1, v1 = onbase.slide(mate.kind, mate.base_dirs, _axis(mate), mate.slide_dirs, path,
                                  m.slide, m.slide_rate, dt, slide_steps,
                                  f_static=mate.static_friction, f_dynamic=mate.dynamic_friction,
                                  blocked=m.blocked_slide, integrator=physics.slide_integrator,
                                  located=physics.slide_onset == "located")
        if turn_path is not None:
            force = onbase.TurnForce(turn_path, mate.base_dirs[0], m.cm_offset, body.mass_kg,
                                     mate.inertia_about_axis, mate.rotational_friction)
            held = m.angle_rate == 0.0 and (m.blocked_turn or mate.holding_torque > 0.0 and abs(
                _alpha_at_rest(body, mate, m, _to_base(f, physics.gravity_rotation)))
                * mate.inertia_about_axis <= mate.holding_torque)
            if not held:
                turn_steps = onbase.substeps(dt, physics.turn_step_s)
                f.collision.stats["integrator_steps"] += (
                    1 if physics.turn_integrator == "paper" else turn_steps)
                a1, w1 = onbase.turn(force, m.angle, m.angle_rate, dt, turn_steps,
                                     physics.turn_integrator)
                if mate.holding_torque > 0.0 and m.angle_rate * w1 <= 0.0 and w1 != 0.0 \
                        and m.angle_rate != 0.0:
                    # It came to a stop in this frame: static friction holds it there,
                    # at the turning point of its swing (located in the frame), if
                    # gravity's torque is within the limit.
                    at, a_stop = onbase.turning_point(force, m.angle, m.angle_rate, dt,
                                                      physics.turn_step_s,
                                                      physics.turn_integrator)
                    torque = abs(force.alpha(a_stop, at)) * mate.inertia_about_axis
                    if torque <= mate.holding_torque:
                        a1, w1 = a_stop, 0.0
    if not (_finite(x1) and _finite(v1) and _finite((a1, w1))):
        f.change_mode(index, replace(part, mode=ONBASESTATIC, linear_velocity=_zero3(),
                                     angular_velocity=_zero3(),
                                     motion=replace(m, slide_rate=tuple(0.0 for _ in v1),
                                                    angle_rate=0.0)), Cause.NUMERICAL_FAULT)
        return
    # When gravity turns to pull it off the plane (located), it leaves then, unless the
    # base blocks it or it slides off an edge first in the frame.
    lift = _lift_off_fraction(f, mate) \
        if physics.slide_off == "located" and mate.kind != "axis" and dt > 0.0 else None
    blocked = None
    x_end, a_end = x1, a1  # the frame's path ends here, whatever cuts it short below
    if x1 != m.slide or a1 != m.angle:
        m, blocked = _sweep(f, body, mate, m, x1, a1)
        if blocked is not None:
            lam, blame_slide, blame_turn = blocked
            if lift is not None and lift < lam:
                blocked = None  # lifted off before it reached the obstacle
            else:
                lift = None  # stopped first; a lift is found again next frame, at its start
                # Only what the obstacle stops is cut at the contact: a collar that stops a
                # slide along the shaft leaves the turn about it alone (cut too, it kept
                # the frame's end rate at the contact's angle: energy from nowhere).
                if blame_slide or physics.block_cut == "both":
                    x1 = tuple(x0 + lam * (xe - x0) for x0, xe in zip(m.slide, x1))
                if blame_turn or physics.block_cut == "both":
                    a1 = m.angle + lam * (a1 - m.angle)
    rel = cn.relative_pose(mate, m.base_from_snap, x1, a1)
    assembly = cast(Assembly, body.assembly)
    # The first fraction of the frame at which its path came within the final tolerance:
    # PLACED then, unless it left or lifted off before (a block cuts the path short).
    passed = None
    if assembly.final_pose is not None and physics.final_pose_check == "path" and dt > 0.0:
        passed = _final_fraction(mate, m, x_end, v1, a_end, w1, rel, assembly, dt,
                                 1.0 if blocked is None else blocked[0])
        if passed is None and blocked is not None and not blocked[2] \
                and physics.block_cut == "blamed" and a1 != m.angle:
            # Stopped in its slide only: the turn goes on to the frame's end along the same
            # cubic, at the slide coordinates of the contact (``x1``, cut there).
            still = tuple(0.0 for _ in v1)
            passed = _final_fraction(mate, replace(m, slide=x1, slide_rate=still), x1, still,
                                     a1, w1, rel, assembly, dt, 1.0, since=blocked[0])
    if not _still_on_base(f, body, mate, m, rel, x1):
        lam = _LEAVE_AT_END if blocked is not None or physics.slide_off != "located" \
            else _leaving_fraction(f, body, mate, m, x1, v1, a1, w1)
        if lift is None or lam <= lift:
            if passed is not None and passed <= lam:
                _place(f, index, Cause.REACHED_FINAL_POSE)
                return
            if lam >= 1.0:
                v2, w2 = v1, w1
                if blocked is not None and physics.block_cut == "blamed":
                    # Stopped by the base in the frame it slid off (a turn stopped while
                    # the slide ran off the shaft's end): it leaves without the rate into
                    # the obstacle, as it would have stayed on (``_stop_at_block``).
                    stopped = _stop_at_block(m.moved(x1, v1, a1, w1), m, x1, a1,
                                             blame_slide, blame_turn)  # type: ignore[possibly-undefined]
                    v2, w2 = stopped.slide_rate, stopped.angle_rate
                    _blocked_event(f, part.name, blocked[0])
                v_rel, w_rel = _relative_rates(body, mate, m, v2, a1, w2)
                _leave(f, index, Cause.SLID_OFF, rel, v_rel, w_rel)
                return
            # Off the base part-way through the frame: free flight from that instant on,
            # the rest of the frame flown (contact search included) as any flight is.
            xl, vl, al, wl = _path_at(m, x1, v1, a1, w1, lam, f.dt_s)
            v_rel, w_rel = _relative_rates(body, mate, m, vl, al, wl)
            _leave(f, index, Cause.SLID_OFF, cn.relative_pose(mate, m.base_from_snap, xl, al),
                   v_rel, w_rel, at=lam)
            _fly(f, index)
            return
    if lift is not None:
        if passed is not None and passed <= lift:
            _place(f, index, Cause.REACHED_FINAL_POSE)
            return
        _lift_off(f, index, body, mate, m, lift)
        return
    new = m.moved(x1, v1, a1, w1)
    if blocked is not None:
        new = _stop_at_block(new, m, x1, a1, blame_slide, blame_turn)  # type: ignore[possibly-undefined]
        # Placed before it reached the obstacle (``passed``: no later than the block), the
        # part never met it: no contact (what comes first in the frame wins).
        if passed is None or passed > lam or physics.block_event == "always":  # type: ignore[possibly-undefined]
            _blocked_event(f, part.name, lam)  # type: ignore[possibly-undefined]
    if passed is not None or (assembly.final_pose is not None
                              and cn.at_final_pose(assembly, rel)):
        _place(f, index, Cause.REACHED_FINAL_POSE)
        return
    v_rel, w_rel = _relative_rates(body, mate, new, new.slide_rate, new.angle, new.angle_rate)
    q = cast(sp.Pose, f.base_pose).rotation
    moved = part.moved(cast(sp.Pose, f.base_pose).compose(rel), sp.quat_rotate(q, v_rel),
                       sp.quat_rotate(q, w_rel), new)
    at_rest = new.angle_rate == 0.0 and all(v == 0.0 for v in new.slide_rate)
    if at_rest:
        _, slides, turns = _drive(f, body, mate, new)
        if not (slides or turns):
            cause = Cause.BLOCKED if blocked is not None else Cause.FRICTION_HELD
            f.change_mode(index, replace(moved, mode=ONBASESTATIC, linear_velocity=_zero3(),
                                         angular_velocity=_zero3()), cause)
            return
    f.parts[index] = moved


def _blocked_event(f: _Frame, name: str, lam: float) -> None:
    """The base stopped the part at the fraction ``lam`` of the frame."""
    f.events.append(ContactMade(f.inputs.frame, name, Cause.BLOCKED.value,
                                cast(Body, f.scene.base).name,
                                f.t_prev_ns + int(lam * (f.t_ns - f.t_prev_ns))))


# A few ulps of a speed: what a projection of the speed onto a direction parallel to it
# leaves over (a relative error of a few machine epsilons, 2.2e-16).
_PROJECTION_ROUND_OFF: Final = 16.0 * 2.220446049250313e-16


def _stop_at_block(new: OnBase, old: OnBase, x1, a1, blame_slide: bool,
                   blame_turn: bool) -> OnBase:
    """An inelastic stop: the rate into the obstacle goes to zero, the rest is kept."""
    if blame_slide:
        d = [xe - x0 for x0, xe in zip(old.slide, x1)]
        n = math.sqrt(sum(c * c for c in d))
        if n > 0.0:
            d = [c / n for c in d]
        else:
            d = [c / (math.sqrt(sum(r * r for r in old.slide_rate)) or 1.0)
                 for c in old.slide_rate]
        into = sum(a * b for a, b in zip(new.slide_rate, d))
        rate = tuple(v - max(0.0, into) * c for v, c in zip(new.slide_rate, d))
        # What a motion straight into the obstacle leaves is the projection's round-off
        # (1e-30 m/s of a block let go at 3 m/s into a wall, on a base turned 30 degrees),
        # not a slide along it: kept, the part slid on for a frame and friction's stop was
        # logged after the block (``held_by_friction``), where the block is the stop.
        if math.sqrt(sum(r * r for r in rate)) <= _PROJECTION_ROUND_OFF * math.sqrt(
                sum(v * v for v in new.slide_rate)):
            rate = tuple(0.0 for _ in rate)
        new = replace(new, slide_rate=rate, blocked_slide=tuple(d))
    if blame_turn:
        direction = a1 - old.angle or new.angle_rate
        new = replace(new, angle_rate=0.0, blocked_turn=1 if direction > 0.0 else -1)
    return replace(new, clearance=0.0, clear_at=())


def _sweep_past(f: _Frame, lam0: float, at, speed: float, distance) -> float | None:
    """Conservative advancement along the frame's path from ``lam0`` to within
    ``_PASS_DEPTH`` of the tolerance of the base: where, or None if nowhere. Steps are
    short where it passes within the tolerance of something (~0.05 mm of travel at a 0.05
    mm clearance), but none can pass through anything; out of steps, it stops where it got
    to (a review: a 360 mm pin in a bore 0.012 mm clear ran out and jumped to the frame's
    end, inside the plate)."""
    deep = _PASS_DEPTH * f.scene.physics.contact_tolerance
    lam = lam0
    d = distance(*at(lam))
    for _ in range(_CA_BASE_ITERATIONS):
        if d <= deep:
            return lam
        step_len = (d - 0.5 * deep) / speed
        if lam + step_len >= 1.0:
            return 1.0 if distance(*at(1.0)) <= deep else None
        lam += step_len
        d = distance(*at(lam))
    return lam


def _passing(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, lam: float, at,
             speed: float, distance, lift: sp.Vec3) -> tuple[bool, float | None]:
    """At a point ``lam`` of the frame's path within the contact tolerance of the base:
    whether the part passes what it touches rather than moving into it, and where it is
    blocked if it does.

    Into: closing in on the base from ``lam`` (over the first half tolerance of travel, by
    over a hundredth of it) and within ``_PASS_DEPTH`` of the tolerance of it within
    ``_PASS_REACH`` tolerances: blocked at ``lam``, as any contact. Otherwise it passes (a
    pin passing its bore's rim with less radial clearance than the tolerance stays at that
    clearance), and is blocked, if it comes that near anything in the frame, where what it
    came near is still half the tolerance away (``_back_off``): not at the rim, short of
    the plate (a review: blocked at the rim's contact, up to 2 mm short), nor touching it
    so that it could never turn again."""
    tol = f.scene.physics.contact_tolerance
    d0 = distance(*at(lam))
    if d0 <= _PASS_DEPTH * tol:
        return False, lam  # already that near: along and into cannot be told apart
    deep_at = _sweep_past(f, lam, at, speed, distance)
    if deep_at is None:
        return True, None
    if (deep_at - lam) * speed <= _PASS_REACH * tol:
        probe = lam + 0.5 * tol / speed
        if probe >= deep_at or distance(*at(probe)) < d0 - 0.005 * tol:
            return False, lam
    return True, _back_off(f, body, mate, m, lam, deep_at, at, lift)


def _back_off(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, lam: float, deep_at: float,
              at, lift: sp.Vec3) -> float:
    """Where, between ``lam`` and ``deep_at`` (a tenth of the tolerance from the base), a
    part passing what it touched stops: the last point half the tolerance from the base's
    surfaces it came near at ``deep_at`` (bisected; ``lam`` if it starts nearer)."""
    tol = f.scene.physics.contact_tolerance

    def rel(lam_: float) -> sp.Pose:
        x, a = at(lam_)
        return cn.relative_pose(mate, m.base_from_snap, x, a)
    near = f.collision.rest_surfaces_within(body.name, m.mate, rel(deep_at),
                                            _PASS_DEPTH * tol, lift=lift)
    if not near:
        return deep_at

    def gap(lam_: float) -> float:
        return f.collision.rest_distance(body.name, m.mate, rel(lam_), near, lift=lift)
    lo, hi = lam, deep_at
    if gap(lo) < 0.5 * tol:
        return lo
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if gap(mid) >= 0.5 * tol:
            lo = mid
        else:
            hi = mid
    return lo


def _sweep_from_contact(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, at, speed: float,
                        lift: sp.Vec3) -> float | None:
    """A move that starts within the tolerance of the base (``_sweep``), stepped by
    conservative advancement against the base less the surfaces it touches (whole faces,
    ``collision.rest_surfaces_within``), which it may move along as the end's check lets
    it: the first point of the frame's path where it meets something else, or None.

    A surface met within the tolerance is moved into, and blocks there, if a tolerance of
    travel further along the path (extrapolated past the frame's end) would bring the part
    nearer it than half the tolerance; else the part is moving along it (the edge of the
    wall it slides along as it passes the wall's end, the next box of a wall built of two;
    a review found those blocking for good) and it joins what the part touches. None too on
    a constraint with radial fits (``collision.sweeps_by_surface``), where the end's check
    alone decides, as before."""
    if not f.collision.sweeps_by_surface(body.name, m.mate):
        return None
    tol = f.scene.physics.contact_tolerance
    deep = 0.5 * tol - _CONTACT_SLACK_M

    def posed(lam_: float) -> sp.Pose:
        x, a = at(lam_)
        return cn.relative_pose(mate, m.base_from_snap, x, a)
    touched = f.collision.rest_surfaces_within(body.name, m.mate, posed(0.0), tol, lift=lift)
    lam = 0.0
    for _ in range(_CA_BASE_ITERATIONS):
        d, which = f.collision.rest_nearest_without(body.name, m.mate, posed(lam), touched,
                                                    lift=lift)
        if d <= tol and which >= 0:
            ahead = posed(lam + tol / speed)
            if f.collision.rest_distance(body.name, m.mate, ahead, (which,), lift=lift) < deep:
                return lam  # into it
            touched = (*touched, which)  # along it: it touches that one too from here
            continue
        if lam >= 1.0:
            return None
        lam = min(1.0, lam + (d - 0.5 * tol) / speed)
    return None  # out of steps (skimming something): the end's check decides


def _sweep(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, x1: tuple[float, ...],
           a1: float) -> tuple[OnBase, tuple[float, bool, bool] | None]:
    """SKIP_COPLANAR / SKIP_COAXIAL along the frame's path in coordinates, by conservative
    advancement: at distance d, no point of the part moves more than ``|dx| + rho |da|``
    per unit of the path parameter, so a step of ``(d - tol/2) / that`` never enters the
    base. Returns the motion with an updated clearance cache and ``None`` or
    ``(lambda, blame_slide, blame_turn)`` where the part touched (within the tolerance)."""
    tol = f.scene.physics.contact_tolerance
    x0, a0 = m.slide, m.angle
    dx = _distance(x0, x1)
    da = abs(a1 - a0)
    # The cheap bound: the last measured clearance, minus how far the part can have come.
    if m.clearance > 0.0 and m.clear_at:
        reach = max(_distance(x0, m.clear_at), _distance(x1, m.clear_at))
        if reach < m.clearance - tol:
            return m, None
    if mate.kind == "axis":
        mode, lift = SKIP_COAXIAL, _zero3()
    else:
        mode = SKIP_COPLANAR
        lift = _zero3()
        for n in mate.base_dirs:
            lift = sp.add(lift, sp.scale(n, 2.0 * tol))

    def distance(x, a) -> float:
        rel = cn.relative_pose(mate, m.base_from_snap, x, a)
        return f.collision.base_distance(body.name, m.mate, rel, mode, lift=lift)

    def at(lam):
        return (tuple(p + lam * (q - p) for p, q in zip(x0, x1)), a0 + lam * (a1 - a0))

    speed = dx + mate.sweep_radius * da
    passing = f.scene.physics.passing_contact == "pass"
    depth = tol  # what a hit is within (a tenth of it where it passed something first)
    if speed == 0.0:
        # A move too small to measure (its square underflows): nothing can have come nearer.
        return m, None
    # Only "within the tolerance?" is asked of a start distance <= tol (below, a start in
    # contact uses the end's distance), so a witness pair may answer it.
    d0 = f.collision.base_distance_within(
        body.name, m.mate, cn.relative_pose(mate, m.base_from_snap, x0, a0), mode, tol,
        lift=lift)
    d = d0
    lam = 0.0
    hit = None
    turning_in_place = mate.turn and x1 == x0 == m.clear_at
    if d0 <= tol:
        # Starting in contact (after a block): moving along or away from the obstacle is
        # allowed; going deeper than half the tolerance is not.
        if _INSIDE_ENVELOPE and turning_in_place \
                and m.clearance >= 0.5 * tol + _ENVELOPE_MARGIN * tol:
            # Turning in place: no angle brings any point of the part nearer the base than
            # its envelope (the cylinder about the shaft that the clearance measures), which
            # is more than half the tolerance away, so it cannot go deeper: no query.
            hit = None
        else:
            d_end = distance(x1, a1)
            hit = 0.0 if d_end < 0.5 * tol - _CONTACT_SLACK_M else None
            d = d_end
            if hit is not None and passing:
                passed, past = _passing(f, body, mate, m, 0.0, at, speed, distance, lift)
                if passed:
                    hit, depth = past, _PASS_DEPTH * tol
                    d = distance(*at(1.0 if hit is None else hit))
            elif f.scene.physics.contact_sweep == "path":
                # Along what it touches, into nothing else on the way: checked at the end
                # alone, a block sliding along a wall passed through a rib across its way,
                # and one whose frame ended inside a stop was stopped a frame short.
                met = _sweep_from_contact(f, body, mate, m, at, speed, lift)
                if met is not None:
                    d_met = distance(*at(met))
                    # Else it went deeper into what it touched before it met that: stopped
                    # at the frame's start, as the end's check stops such a move (a review:
                    # where the end's check had let it through, the block was dropped).
                    hit, d = (met, d_met) if d_met >= 0.5 * tol - _CONTACT_SLACK_M \
                        else (0.0, d)
    else:
        for _ in range(_CA_BASE_ITERATIONS):
            step_len = (d - 0.5 * tol) / speed
            if lam + step_len >= 1.0:
                d = distance(x1, a1)
                if d <= tol:
                    hit = 1.0
                break
            lam += step_len
            d = distance(*at(lam))
            if d <= tol:
                hit = lam
                break
        else:
            # Out of budget (skimming along an obstacle): only a real contact blocks.
            d = distance(x1, a1)
            hit = 1.0 if d <= tol else None
        if hit is not None and passing:
            # Come within the tolerance of something it passes (a bore's rim), not into it?
            passed, past = _passing(f, body, mate, m, hit, at, speed, distance, lift)
            if passed:
                hit, depth = past, _PASS_DEPTH * tol
                d = distance(*at(1.0 if hit is None else hit))
    if hit is None:
        if turning_in_place and m.clearance > 0.0:
            return m, None  # the envelope is the same at any angle: its clearance stands
        if mate.turn:
            c, sign = cn.axial_offset(mate, m.base_from_snap)
            u_p = sp.scale(mate.base_dirs[0], sign)
            point = sp.add(m.base_from_snap.apply(mate.part_points[0]),
                           sp.scale(mate.base_dirs[0], x1[0] if x1 else 0.0))
            clearance = f.collision.sweep_clearance(body.name, m.mate, point,
                                                    cn._rotation_between((0.0, 0.0, 1.0), u_p))
        else:
            clearance = d
        return replace(m, clear_at=x1, clearance=clearance if clearance >= 0.5 * tol else 0.0), None
    # Which coordinate ran into the base: try each alone from the contact point.
    blame_slide, blame_turn = bool(x0) and dx > 0.0, mate.turn and da > 0.0
    if blame_slide and blame_turn:
        xc, ac = at(hit)
        blame_slide = distance(x1, ac) < 0.5 * depth
        blame_turn = distance(xc, a1) < 0.5 * depth
        if not (blame_slide or blame_turn):
            blame_slide = blame_turn = True
    return replace(m, clearance=0.0, clear_at=()), (hit, blame_slide, blame_turn)


def _distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Euclidean distance between two points in slide coordinates (summed in order, as
    written: not ``math.dist``, whose other rounding would move a decision). The loop is
    ``sum((q - p) ** 2 for p, q in zip(a, b))`` written out: no list or zip when compiled."""
    total = 0.0
    for i in range(min(len(a), len(b))):
        total += (b[i] - a[i]) ** 2
    return math.sqrt(total)


_LEAVE_AT_END: Final = 1.0
_LEAVING_ITERATIONS: Final = 40  # at most; it stops at 0.1 ns


def _path_at(m: OnBase, x1: tuple[float, ...], v1: tuple[float, ...], a1: float, w1: float,
             lam: float, dt: float) -> tuple[tuple[float, ...], tuple[float, ...], float, float]:
    """The coordinates and rates at the fraction ``lam`` of the frame: the cubic Hermite
    between the frame's ends and its derivative (exact while the acceleration changes
    linearly, as it does to first order while the base turns)."""
    l2, l3 = lam * lam, lam * lam * lam
    h00, h10, h01, h11 = 2.0 * l3 - 3.0 * l2 + 1.0, l3 - 2.0 * l2 + lam, -2.0 * l3 + 3.0 * l2, \
        l3 - l2
    d00, d10, d11 = 6.0 * l2 - 6.0 * lam, 3.0 * l2 - 4.0 * lam + 1.0, 3.0 * l2 - 2.0 * lam
    x = tuple(h00 * p + h10 * dt * u + h01 * q + h11 * dt * w
              for p, u, q, w in zip(m.slide, m.slide_rate, x1, v1))
    v = tuple((d00 * (p - q)) / dt + d10 * u + d11 * w
              for p, u, q, w in zip(m.slide, m.slide_rate, x1, v1))
    a = h00 * m.angle + h10 * dt * m.angle_rate + h01 * a1 + h11 * dt * w1
    w_lam = d00 * (m.angle - a1) / dt + d10 * m.angle_rate + d11 * w1
    return x, v, a, w_lam


def _final_fraction(mate: cn.Mate, m: OnBase, x1: tuple[float, ...], v1: tuple[float, ...],
                    a1: float, w1: float, end: sp.Pose, assembly: Assembly, dt: float,
                    until: float, since: float = 0.0) -> float | None:
    """The first fraction of the frame, from ``since`` up to ``until`` (where a block
    stopped the part; ``end`` is its pose there), at which the frame's path (``_path_at`` to
    ``x1``, ``a1``) is within the final tolerance, or None. Asked only at the frame's end, a part that
    slid or turned through its final pose by more than the tolerance's width in a frame
    (4 mm at the default 2 mm: 0.24 m/s at 60 Hz) passed it unplaced, and whether it was
    placed depended on the frame rate.

    Bisection in time order: a stretch of the path is dropped when its middle is further
    from the final pose, in distance or in angle, than the path can move in half the
    stretch plus the tolerance. The bounds are of the cubic's derivative (its basis
    derivatives are at most 1.5, 1 and 1 in size): the coordinates move at most
    ``1.5 |x1 - x0| + dt (|v0| + |v1|)`` a frame, and the origin at most that plus the
    turn's rate times its distance from the axis. A pass is found to a frame's 2**-30,
    however narrow the tolerance. (The cubic is the path between the frame's ends, as for
    the leaving instant; where the part stopped inside the frame it can overshoot the stop
    by ~a dt^2 / 10, 0.05 mm at 2 m/s^2 and 60 Hz.) A path that runs just outside the
    tolerance's edge for long can exhaust ``_FINAL_EVALUATIONS``; the frame's end decides
    then."""
    final = cast(sp.Pose, assembly.final_pose)
    d_tol, a_tol = assembly.final_distance, assembly.final_angle
    dx = math.sqrt(sum((q - p) * (q - p) for p, q in zip(m.slide, x1)))
    speed = 1.5 * dx + dt * (math.sqrt(sum(u * u for u in m.slide_rate))
                             + math.sqrt(sum(w * w for w in v1)))
    turn_rate = 1.5 * abs(a1 - m.angle) + dt * (abs(m.angle_rate) + abs(w1))
    if turn_rate > 0.0:
        # The origin's distance from the shaft (the same all frame: sliding is along it).
        start = cn.relative_pose(mate, m.base_from_snap, m.slide, m.angle)
        r = sp.sub(start.position, mate.base_points[0])
        u = mate.unit_axis
        speed += turn_rate * sp.norm(sp.sub(r, sp.scale(u, sp.dot(r, u))))
    # Stretches [lo, hi] still to look at, the earliest on top. The budget only matters
    # for a path that runs along the tolerance's edge, just outside, for a long stretch.
    stack = [(since, until, 0)]
    budget = _FINAL_EVALUATIONS
    while stack and budget > 0:
        budget -= 1
        lo, hi, depth = stack.pop()
        mid = 0.5 * (lo + hi)
        x, _, a, _ = _path_at(m, x1, v1, a1, w1, mid, dt)
        pose = cn.relative_pose(mate, m.base_from_snap, x, a)
        half = 0.5 * (hi - lo)
        d = sp.norm(sp.sub(pose.position, final.position))
        angle = sp.quat_angle_between(pose.rotation, final.rotation)
        if d > d_tol + speed * half or angle > a_tol + turn_rate * half:
            continue  # no instant of the stretch is within the tolerance
        if depth >= _FINAL_DEPTH:
            if d <= d_tol and angle <= a_tol:
                return mid
            continue
        # The later half goes under the earlier; the middle is between them in time.
        stack.append((mid, hi, depth + 1))
        if d <= d_tol and angle <= a_tol:
            stack.append((mid, mid, _FINAL_DEPTH))
        stack.append((lo, mid, depth + 1))
    return until if cn.at_final_pose(assembly, end) else None


_FINAL_DEPTH: Final = 30
_FINAL_EVALUATIONS: Final = 4096


def _leaving_fraction(f: _Frame, body: Body, mate: cn.Mate, m: OnBase,
                      x1: tuple[float, ...], v1: tuple[float, ...], a1: float,
                      w1: float) -> float:
    """The fraction of the frame at which the part left the base (off at the frame's end,
    on at its start), along the frame's path (``_path_at``): regula falsi (Illinois) on
    ``_off_margin``, which is continuous enough that a few evaluations do where bisection
    took ~24, each maybe an fcl query. Deciding it at the frame's end kept the part on the
    base up to a frame too long: it started to fall up to 16 ms late, which the rest of its
    flight carried on (0.3 mm at once, and g t dt more after a fall of t)."""
    dt = f.dt_s

    def margin(lam: float) -> float:
        x, _, a, _ = _path_at(m, x1, v1, a1, w1, lam, dt)
        return _off_margin(f, body, mate, m, cn.relative_pose(mate, m.base_from_snap, x, a), x)
    lo, hi = 0.0, 1.0
    f_lo, f_hi = margin(lo), margin(hi)
    if not f_lo <= 0.0 < f_hi:
        return 1.0  # not a clean crossing along the path: leave at the frame's end
    side, flat = 0, False
    for _ in range(_LEAVING_ITERATIONS):
        if (hi - lo) * dt < 1e-10:
            break  # finer than the nanoseconds a time is kept in
        lam = 0.5 * (lo + hi) if flat else (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < lam < hi:
            lam = 0.5 * (lo + hi)
        value = margin(lam)
        if abs(value) < 1e-12:
            return lam  # the crossing itself, to 1e-12 m
        # A margin that does not change (a centre of mass well over the face: 0 from fcl)
        # says nothing about where the crossing is: bisect until it does.
        flat = value == (f_hi if value > 0.0 else f_lo)
        if value > 0.0:
            hi, f_hi = lam, value
            if side == 1:
                f_lo *= 0.5  # Illinois: the end that stays put counts for less
            side = 1
        else:
            lo, f_lo = lam, value
            if side == -1:
                f_hi *= 0.5
            side = -1
    return hi


def _lift_off(f: _Frame, index: int, body: Body, mate: cn.Mate, m: OnBase,
              lift: float) -> None:
    """Gravity turned to pull a sliding part off the plane: it separates at the fraction
    ``lift`` of the frame. Its state then is the slide's own up to that instant (the base's
    turn up to it is a slerp too), not an interpolation of the frame's ends, which misses a
    slip that started within the frame (as one always does just before a lift: the normal
    load goes to zero). Plane mates do not turn."""
    physics = f.scene.physics
    xl, vl = m.slide, m.slide_rate
    if lift > 0.0:
        q0 = cast(sp.Pose, f.base_prev or f.base_pose).rotation
        q_lift = sp.slerp(q0, cast(sp.Pose, f.base_pose).rotation, lift)
        steps = onbase.substeps(lift * f.dt_s, physics.slide_step_s)
        f.collision.stats["closed_form_evals" if physics.slide_integrator in (
            "analytic", "analytic4") else "integrator_steps"] += steps
        xl, vl = onbase.slide(
            mate.kind, mate.base_dirs, _axis(mate), mate.slide_dirs,
            onbase.GravityPath(physics.gravity_slide, q0, q_lift), m.slide, m.slide_rate,
            lift * f.dt_s, steps, f_static=mate.static_friction,
            f_dynamic=mate.dynamic_friction, blocked=m.blocked_slide,
            integrator=physics.slide_integrator, located=physics.slide_onset == "located")
    v_rel, w_rel = _relative_rates(body, mate, m, vl, m.angle, m.angle_rate)
    _leave(f, index, Cause.LIFTED_OFF, cn.relative_pose(mate, m.base_from_snap, xl, m.angle),
           v_rel, w_rel, at=lift)
    _fly(f, index)


def _lift_off_fraction(f: _Frame, mate: cn.Mate) -> float | None:
    """When, within the frame, gravity (base axes, along the frame's turn of the base) first
    pulls a part off the plane(s) of its mate, or None if it does not by the frame's end."""
    axis = _axis(mate)
    gravity = f.scene.physics.gravity_slide

    def lifted(g: sp.Vec3) -> bool:
        return onbase.normal_load(mate.kind, mate.base_dirs, axis, g)[1]
    if not lifted(_to_base(f, gravity)):
        return None  # pressed onto the plane at the frame's end: the common case, no path
    return _lift_fraction(f, gravity, lifted)


def _lift_fraction(f: _Frame, gravity: sp.Vec3, lifted) -> float:
    """The first fraction of the frame at which ``lifted(gravity in base axes)`` holds, given
    that it holds at the frame's end: bisected on the frame's gravity path (no geometry)."""
    q0 = cast(sp.Pose, f.base_prev or f.base_pose).rotation
    path = onbase.GravityPath(gravity, q0, cast(sp.Pose, f.base_pose).rotation)
    lo, hi = 0.0, 1.0
    if lifted(path.at(0.0)):
        return 0.0
    for _ in range(_LEAVING_ITERATIONS):
        if (hi - lo) * f.dt_s < 1e-10:
            break
        mid = 0.5 * (lo + hi)
        if lifted(path.at(mid)):
            hi = mid
        else:
            lo = mid
    return hi


def beyond_end(mate: cn.Mate, mate_index: int, snapped: sp.Pose) -> float:
    """How far beyond the end of the base's feature (the shaft, or the bore) a part snapped
    onto an axis constraint's line lies along it: > 0 off it, <= 0 on it (the overlap)."""
    zeros = tuple(0.0 for _ in mate.slide_dirs)
    return -_bore_overlap(mate, OnBase(mate_index, snapped, zeros, zeros), zeros)


def _bore_overlap(mate: cn.Mate, m: OnBase, x: tuple[float, ...]) -> float:
    """How far the bore's span overlaps the shaft's, along the shaft (base axes)."""
    c, sign = cn.axial_offset(mate, m.base_from_snap)
    lo, hi = (c + sign * mate.part_feature_span[0] + x[0],
              c + sign * mate.part_feature_span[1] + x[0])
    lo, hi = min(lo, hi), max(lo, hi)
    return min(hi, mate.base_feature_span[1]) - max(lo, mate.base_feature_span[0])


def _feet(mate: cn.Mate, rel: sp.Pose, body: Body) -> list[sp.Vec3]:
    """The centre of mass dropped onto each base face of a plane mate."""
    cm = rel.apply(body.center_of_mass)
    return [sp.sub(cm, sp.scale(normal, sp.dot(sp.sub(cm, point), normal)))
            for point, normal in zip(mate.base_points, mate.base_dirs)]


def _off_margin(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, rel: sp.Pose,
                x: tuple[float, ...]) -> float:
    """``_still_on_base`` as a number: positive exactly when the part is off the base, and
    continuous where the decision is made (metres past the tolerance)."""
    tol = f.scene.physics.contact_tolerance
    if mate.kind == "axis":
        if not mate.slide_dirs:
            return -1.0
        overlap = _bore_overlap(mate, m, x)
        # Outside the band the 1-D bound decides, shaped as fcl's distance is in it (0 while
        # the bore is on the shaft, the gap past its end after): no jump at the band's edges.
        if overlap > 2.0 * tol:
            return tol - overlap
        if overlap < -2.0 * tol:
            return -overlap - tol
        return f.collision.base_distance(body.name, m.mate, rel, KEEP_COPLANAR) - tol
    if mate.leave_when == "no_contact":
        return f.collision.base_distance(body.name, m.mate, rel, KEEP_COPLANAR) - tol
    return max(_unsupported(f, body, m.mate, rel, plane, foot) - tol
               for plane, foot in enumerate(_feet(mate, rel, body)))


def _unsupported(f: _Frame, body: Body, mate: int, rel: sp.Pose, plane: int,
                 foot: sp.Vec3) -> float:
    """How far the centre of mass's ``foot`` on a plane mate's ``plane`` is from what holds
    the part up: its distance to the plane's faces, or, where that is past the tolerance
    (over the plate's edge, or over a hole or slot in it), its distance outside the hull of
    where the part meets the faces (``CollisionWorld.support_gap``: a part spanning a slot
    is held; a CAD user's trial saw a block "slide off" into one, 9 mm into the plate).
    The lesser of the two (continuous, for ``_leaving_fraction``'s root: a review found the
    first version's jump of the tolerance put a leaving there). Past a convex face's edge
    the plane's outline is as far as the faces are, and the faces' distance stands to the
    bit (``support_gap`` is not asked further where the outline is within a nanometre of
    that distance: the goldens' frames are the same). A centre of mass past the part's
    footprint is asked at the footprint's point nearest it, and one its own faces do not
    cover (a U's notch) by the hull alone (``CollisionWorld.stand_in``; nineteenth session:
    an L slid off into a groove under its arm, and a review found an L held by the plate
    under its arm, its foot wholly over a groove, and a U by a rib under its notch)."""
    tol = f.scene.physics.contact_tolerance
    stand, covered = f.collision.stand_in(body.name, mate, plane, tol)
    if stand is not None:
        # Its centre of mass past its footprint: the footprint's point nearest it stands
        # for it, dropped onto the plane as the centre of mass is (``_feet``).
        m = cast(Assembly, body.assembly).mates[mate]
        point, normal = m.base_points[plane], m.base_dirs[plane]
        at = rel.apply(stand)
        foot = sp.sub(at, sp.scale(normal, sp.dot(sp.sub(at, point), normal)))
    if not covered:
        # Not on its own faces (a notch): the faces under it may touch nothing of the
        # part; the hull of contact alone holds it.
        return f.collision.support_gap(body.name, mate, plane, foot, rel, tol, math.inf)
    d = f.collision.support_distance(body.name, mate, foot)
    if d <= tol:
        return d
    return min(d, f.collision.support_gap(body.name, mate, plane, foot, rel, tol,
                                          d - _OUTLINE_SLACK_M))


# How much nearer than the faces' distance the plane's outline may be and still settle a
# foot past it (``_unsupported``): round-off between fcl's distance and the outline's.
_OUTLINE_SLACK_M: Final = 1e-9


def _still_on_base(f: _Frame, body: Body, mate: cn.Mate, m: OnBase, rel: sp.Pose,
                   x: tuple[float, ...]) -> bool:
    """KEEP_COPLANAR: is the part still on the base (on the shaft, on the plane)?"""
    tol = f.scene.physics.contact_tolerance
    if mate.kind == "axis":
        if not mate.slide_dirs:
            return True
        # The bore's span on the shaft, in base axes: a 1-D bound decides all but the edge.
        overlap = _bore_overlap(mate, m, x)
        if overlap > 2.0 * tol:
            return True
        if overlap < -2.0 * tol:
            return False
        return f.collision.base_distance(body.name, m.mate, rel, KEEP_COPLANAR) <= tol
    if mate.leave_when == "no_contact":
        return f.collision.base_distance(body.name, m.mate, rel, KEEP_COPLANAR) <= tol
    # The part tips over the edge once its centre of mass is no longer above where it
    # touches the face (over a hole or slot it spans, it is still held: ``_unsupported``).
    for plane, foot in enumerate(_feet(mate, rel, body)):
        if _unsupported(f, body, m.mate, rel, plane, foot) > tol:
            return False
    return True


# --- snapshots ------------------------------------------------------------------------

def snapshot(part: PartState) -> PartSnapshot:
    # ``_value_``, not ``.value``: the enum's ``value`` is a descriptor written in Python,
    # two interpreted calls a snapshot even in the compiled build; ``_value_`` is the same
    # string, read from the member's own attributes.
    return PartSnapshot(part.name, part.mode._value_, part.pose.position, part.pose.rotation,
                        part.linear_velocity, part.angular_velocity)


_INHAND_TEXT: Final[str] = Mode.INHAND.value
_STATIC_TEXT: Final[str] = Mode.STATIC.value


def frame_record(scene: Scene, state: WorldState, inputs: TrackerFrame,
                 events: tuple[Event, ...], *,
                 previous: tuple[WorldState, FrameRecord] | None = None,
                 scratch: list[PartSnapshot] | None = None) -> FrameRecord:
    """What a frame derived, in the shape the recording and the review consume.

    With ``previous`` (the state and record of the frame before), a part that no stage
    looked at keeps last frame's snapshot object, so a scene of many resting parts costs
    little here and in the encoder (``codec.FrameEncoder`` reuses an unchanged snapshot's
    text). Only the parts awake before or after the step can have changed. ``scratch``
    (``Stepper``'s, with ``previous``): a list holding the objects of the previous record's
    parts, worked in instead of a copy and left holding this record's.
    """
    base = None
    # The base's velocity (its centre of mass's) and angular velocity, for world velocities
    # (physics ``velocities``; ``_base_sample``): None for ``relative``, or before its
    # second sample; and where its centre of mass is (with a velocity).
    moving: BaseVelocity | None = None
    cm_base = _zero3()
    if scene.base is not None and state.base_pose is not None:
        moving = state.base_velocity
        if moving is not None:
            cm_base = state.base_pose.apply(scene.base.center_of_mass)
        if previous is not None and previous[0].base_pose is state.base_pose \
                and previous[0].base_velocity is moving and previous[1].base is not None:
            base = previous[1].base  # a base that did not move (fixed, or no left hand)
        else:
            base = PartSnapshot(scene.base.name,
                                _STATIC_TEXT if scene.base_fixed else _INHAND_TEXT,
                                state.base_pose.position, state.base_pose.rotation,
                                _zero3() if moving is None else moving.velocity,
                                _zero3() if moving is None else moving.omega)
    prev_awake = previous[0].awake_parts() if previous is not None else None
    awake = state.awake_parts()
    if previous is None or prev_awake is None or awake is None:
        every = tuple(_snapshot_in(scene, i, p, moving, cm_base)
                      for i, p in enumerate(state.parts))
        if scratch is not None:
            scratch[:] = every
        return FrameRecord(inputs, base, every, events)
    prev_state, prev_record = previous
    snaps = list(prev_record.parts) if scratch is None else scratch
    parts, prev_parts = state.parts, prev_state.parts
    looked_at = set(awake)  # (added to, not set.union: compiled, that is a Python call)
    for index in prev_awake:
        looked_at.add(index)
    for index in looked_at:
        if parts[index] is not prev_parts[index]:
            snaps[index] = _snapshot_in(scene, index, parts[index], moving, cm_base)
    return FrameRecord(inputs, base, tuple(snaps), events)


def _snapshot_in(scene: Scene, index: int, part: PartState, moving: BaseVelocity | None,
                 cm_base: sp.Vec3) -> PartSnapshot:
    """``snapshot(part)``, with world velocities for a part on the base (``moving``: the
    base's velocity at its centre of mass and its angular velocity; ``cm_base``: where its
    centre of mass is): the base's motion at the part's centre of mass added to its motion
    relative to the base (zero at rest on it, or placed), as the schema's "world velocity"
    says; before ``velocities: world`` those were recorded as relative velocities, in world
    axes."""
    mode = part.mode
    if moving is None or not (mode is ONBASESLIDE or mode is ONBASESTATIC or mode is PLACED):
        return snapshot(part)
    v_base, w = moving.velocity, moving.omega
    cm = part.pose.apply(scene.parts[index].center_of_mass)
    v = sp.add(v_base, sp.cross(w, sp.sub(cm, cm_base)))
    return PartSnapshot(part.name, mode._value_, part.pose.position, part.pose.rotation,
                        sp.add(part.linear_velocity, v), sp.add(part.angular_velocity, w))


_REUSE_SNAPSHOTS = True  # frame_record's reuse of unchanged snapshots (off in a test)


class Stepper:
    """The fold of ``step`` over a run's tracker frames, one frame a call: what each frame
    derived (``replay.simulate``, ``replay.replay_frames``). A class of this compiled
    module, so that the fold costs no interpreted call a frame."""

    def __init__(self, scene: Scene, collision: CollisionWorld) -> None:
        self.scene = scene
        self.collision = collision
        self.state: WorldState | None = None
        self.previous: tuple[WorldState, FrameRecord] | None = None
        # Lists holding the objects of ``state.parts`` and of the last record's parts,
        # reused frame to frame (``step``, ``frame_record``); None until there is a state,
        # and while a frame is being worked (a step that raised leaves them half written).
        self._parts: list[PartState] | None = None
        self._snaps: list[PartSnapshot] | None = None

    def __call__(self, inputs: TrackerFrame) -> FrameRecord:
        state = self.state
        if state is None:
            state = initial_state(self.scene, time_ns=inputs.time_ns)
        parts, snaps = self._parts, self._snaps
        self._parts = self._snaps = None
        state, events = step(self.scene, self.collision, state, inputs, scratch=parts)
        previous = self.previous if _REUSE_SNAPSHOTS else None
        record = frame_record(self.scene, state, inputs, events, previous=previous,
                              scratch=snaps if previous is not None else None)
        self.state = state
        self.previous = (state, record)
        self._parts = parts if parts is not None else list(state.parts)
        self._snaps = snaps if snaps is not None and previous is not None \
            else list(record.parts)
        return record
