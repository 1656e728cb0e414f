"""One pure step: ``step(scene, collision, state, inputs) -> (state, events)``.

The body of ``step`` is the list of stages, one call per line. Its result depends on its
arguments only: no clock, no globals, no unseeded randomness, dicts walked in sorted order.
The collision world is a cache of geometry built once from the scene; its counters are
instrumentation and never change a result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from . import spatial as sp
from .collision import CollisionWorld
from .dynamics import free, velocity
from .events import ContactMade, Event, GrabRefused, ModeChanged, PartGrabbed, PartReleased
from .frames import FrameRecord, PartSnapshot, TrackerFrame
from .modes import Cause, Mode, check_transition
from .scene import Body, Scene
from .state import Held, PartState, WorldState

RIGHT, LEFT = "right_hand", "left_hand"
_GRABBABLE = (Mode.STATIC, Mode.INSPACE, Mode.ONBASESLIDE, Mode.ONBASESTATIC, Mode.PLACED)
_CA_MAX_ITERATIONS = 200


@dataclass
class _Frame:
    """Scratch space of one step: the parts being rebuilt and the events so far."""

    scene: Scene
    collision: CollisionWorld
    inputs: TrackerFrame
    t_prev_ns: int
    parts: list[PartState]
    hands: dict[str, sp.Pose] = field(default_factory=dict)
    grips: dict[str, bool] = field(default_factory=dict)
    base_pose: sp.Pose | None = None
    events: list[Event] = field(default_factory=list)

    @property
    def t_ns(self) -> int:
        return self.inputs.time_ns

    def change_mode(self, index: int, new: PartState, cause: Cause) -> None:
        old = self.parts[index]
        check_transition(old.mode, new.mode, cause, part=old.name, frame=self.inputs.frame)
        self.parts[index] = new
        self.events.append(ModeChanged(self.inputs.frame, old.name, cause.value, old.mode.value,
                                       new.mode.value))


def initial_state(scene: Scene, *, time_ns: int = 0) -> WorldState:
    """Every part at rest at its initial pose, before the first frame."""
    parts = tuple(PartState(body.name, body.initial_mode, body.initial_pose)
                  for body in scene.parts)
    base_pose = scene.base.initial_pose if scene.base else None
    return WorldState(-1, time_ns, parts, base_pose, ((LEFT, False), (RIGHT, False)))


def step(scene: Scene, collision: CollisionWorld, state: WorldState,
         inputs: TrackerFrame) -> tuple[WorldState, tuple[Event, ...]]:
    """Advance the world by one frame of tracker inputs."""
    f = _Frame(scene, collision, inputs, state.time_ns, list(state.parts),
               base_pose=state.base_pose)
    _read_hands(f, state)
    _move_base(f)
    _follow_hands(f)
    _move_free_parts(f)
    _releases(f, state)
    _grabs(f, state)
    new_state = WorldState(inputs.frame, inputs.time_ns, tuple(f.parts), f.base_pose,
                           tuple(sorted(f.grips.items())))
    return new_state, tuple(f.events)


# --- stages ---------------------------------------------------------------------------

def _read_hands(f: _Frame, state: WorldState) -> None:
    previous = dict(state.grips)
    for hand in (LEFT, RIGHT):
        sample = f.inputs.device(hand)
        if sample is None:
            f.grips[hand] = previous.get(hand, False)
            continue
        f.hands[hand] = sp.Pose(sample.position, sample.rotation_xyzw)
        f.grips[hand] = bool(sample.grip) if sample.grip is not None else previous.get(hand, False)


def _move_base(f: _Frame) -> None:
    # The base part is held in the left hand; without a left-hand tracker it stays put.
    if f.scene.base is not None and LEFT in f.hands:
        f.base_pose = f.hands[LEFT].compose(f.scene.hand_from_base)


def _follow_hands(f: _Frame) -> None:
    physics = f.scene.physics
    keep = max(physics.release_window, 2)
    for index, part in enumerate(f.parts):
        if part.mode is not Mode.INHAND:
            continue
        held: Held = part.motion  # type: ignore[assignment]
        hand = f.hands.get(held.hand)
        if hand is None:
            continue  # no sample for that hand this frame: the part stays where it was
        body = f.scene.parts[index]
        pose = hand.compose(held.hand_from_part)
        cm = pose.apply(body.center_of_mass)
        history = (held.history + ((f.t_ns, cm, pose.rotation),))[-keep:]
        v, w = velocity.estimate(history, method=physics.release_velocity,
                                 window=physics.release_window)
        f.parts[index] = replace(part, pose=pose, linear_velocity=v, angular_velocity=w,
                                 motion=Held(held.hand, held.hand_from_part, history))


def _move_free_parts(f: _Frame) -> None:
    for index, part in enumerate(f.parts):
        if part.mode is Mode.INSPACE:
            _fly(f, index)


def _releases(f: _Frame, state: WorldState) -> None:
    previous = dict(state.grips)
    for hand in sorted(f.grips):
        if not (previous.get(hand, False) and not f.grips[hand]):
            continue
        for index, part in enumerate(f.parts):
            if part.mode is Mode.INHAND and part.motion.hand == hand:  # type: ignore[union-attr]
                _release(f, index, hand)


def _grabs(f: _Frame, state: WorldState) -> None:
    previous = dict(state.grips)
    for hand in sorted(f.grips):
        if previous.get(hand, False) or not f.grips[hand] or hand not in f.hands:
            continue
        # The left hand holds the base part; it grabs only in scenes without one.
        if hand == LEFT and f.scene.base is not None:
            continue
        _grab(f, hand)


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


def _grab(f: _Frame, hand: str) -> None:
    physics = f.scene.physics
    hand_pose = f.hands[hand]
    frame = f.inputs.frame
    candidates = []
    for index, part in enumerate(f.parts):
        if part.mode not in _GRABBABLE:
            continue
        d = _distance_to_box(f.scene.parts[index], part.pose, hand_pose.position)
        if d <= physics.grab_radius:
            candidates.append((d, part.name, index))
    if not candidates:
        f.events.append(GrabRefused(frame, "", "nothing_in_reach", hand))
        return
    _, name, index = min(candidates)
    body = f.scene.parts[index]
    if body.mass_kg > physics.one_hand_max_mass_kg:
        f.events.append(GrabRefused(frame, name, "too_heavy_for_one_hand", hand))
        return
    part = f.parts[index]
    cause = Cause.CAUGHT if part.mode is Mode.INSPACE else Cause.GRABBED
    cm = part.pose.apply(body.center_of_mass)
    held = Held(hand, hand_pose.inverse().compose(part.pose), ((f.t_ns, cm, part.pose.rotation),))
    f.change_mode(index, PartState(name, Mode.INHAND, part.pose, sp.ZERO3, sp.ZERO3, held), cause)
    f.events.append(PartGrabbed(frame, name, cause.value, hand))


def _release(f: _Frame, index: int, hand: str) -> None:
    part = f.parts[index]
    body = f.scene.parts[index]
    physics = f.scene.physics
    v, w = part.linear_velocity, part.angular_velocity
    frame = f.inputs.frame
    cm = part.pose.apply(body.center_of_mass)
    near = f.collision.environment_near(cm, body.radius_about_cm + physics.contact_tolerance)
    if near:
        d, which = f.collision.distance_to_environment(part.name, part.pose, near)
        if d <= physics.contact_tolerance:
            f.events.append(PartReleased(frame, part.name, Cause.RELEASED_ON_TABLE.value, hand,
                                         v, w))
            f.change_mode(index, PartState(part.name, Mode.STATIC, part.pose),
                          Cause.RELEASED_ON_TABLE)
            return
    f.events.append(PartReleased(frame, part.name, Cause.RELEASED.value, hand, v, w))
    flight = free.start(t_ns=f.t_ns, cm=cm, velocity=v, omega_world=w, world_from_part=part.pose,
                        part_from_principal=body.part_from_principal,
                        principal_moments=body.principal_moments)
    f.change_mode(index, PartState(part.name, Mode.INSPACE, part.pose, v, w, flight),
                  Cause.RELEASED)


# --- free flight and contact with the environment -------------------------------------

def _flight_pose(f: _Frame, body: Body, start: free.Flight, t_ns: int):
    physics = f.scene.physics
    flight = free.advance(start, t_ns, model=physics.free_rotation, moments=body.principal_moments,
                          order=physics.free_rotation_order,
                          max_step_s=physics.free_rotation_max_step_s)
    cm, v = free.cm_at(start, t_ns, physics.gravity_free)
    pose = free.pose(flight, cm, part_from_principal=body.part_from_principal,
                     center_of_mass=body.center_of_mass)
    return flight, cm, v, pose


def _fly(f: _Frame, index: int) -> None:
    part = f.parts[index]
    body = f.scene.parts[index]
    physics = f.scene.physics
    start: free.Flight = part.motion  # type: ignore[assignment]
    t_a, t_b = start.t_ns, f.t_ns
    if t_b <= t_a:
        return
    flight, cm_b, v_b, pose_b = _flight_pose(f, body, start, t_b)
    if not all(math.isfinite(x) for x in (*pose_b.position, *pose_b.rotation, *v_b)):
        f.change_mode(index, PartState(part.name, Mode.STATIC, part.pose), Cause.NUMERICAL_FAULT)
        return
    w_b = free.omega_world(flight, model=physics.free_rotation, moments=body.principal_moments)
    moved = replace(part, pose=pose_b, linear_velocity=v_b, angular_velocity=w_b, motion=flight)
    # Broad phase: a sphere around the whole path of the CM over the frame, widened by the
    # parabola's sag off its chord and by the part's own size.
    cm_a, _ = free.cm_at(start, t_a, physics.gravity_free)
    dt = (t_b - t_a) * 1e-9
    sag = sp.norm(physics.gravity_free) * dt * dt / 8.0
    center = sp.scale(sp.add(cm_a, cm_b), 0.5)
    reach = 0.5 * sp.norm(sp.sub(cm_b, cm_a)) + sag + body.radius_about_cm \
        + physics.contact_tolerance
    near = f.collision.environment_near(center, reach)
    if not near:
        f.parts[index] = moved
        return
    contact = _time_of_contact(f, body, start, near, t_a, t_b, part.pose, pose_b)
    if contact is None:
        f.parts[index] = moved
        return
    t_c, pose_c, other = contact
    f.events.append(ContactMade(f.inputs.frame, part.name, Cause.HIT_ENVIRONMENT.value,
                                f.collision.environment_name(other), t_c))
    f.change_mode(index, PartState(part.name, Mode.STATIC, pose_c), Cause.HIT_ENVIRONMENT)


def _time_of_contact(f: _Frame, body: Body, start: free.Flight, near: tuple[int, ...], t_a: int,
                     t_b: int, pose_a: sp.Pose, pose_b: sp.Pose):
    """First time in (t_a, t_b] at which the part comes within the contact tolerance.

    Conservative advancement: at distance d no point of the part can close the gap in less
    than d / (bound on any point's speed), so stepping by that never passes through an
    object, however thin or fast.
    """
    physics = f.scene.physics
    tol = physics.contact_tolerance
    g = sp.norm(physics.gravity_free)
    if physics.free_rotation == "constant_omega":
        omega_max = sp.norm(start.omega_world)
    else:
        omega_max = sp.norm(start.momentum_principal) / body.principal_moments[0]
    t, pose = t_a, pose_a
    for _ in range(_CA_MAX_ITERATIONS):
        d, which = f.collision.distance_to_environment(body.name, pose, near)
        if d <= tol:
            return t, pose, which
        _, v = free.cm_at(start, t, physics.gravity_free)
        speed = sp.norm(v) + g * (t_b - t) * 1e-9 + omega_max * body.radius_about_cm
        if speed <= 0.0:
            return None
        t_next = t + max(1, int((d - 0.5 * tol) / speed * 1e9))
        if t_next >= t_b:
            d_b, which_b = f.collision.distance_to_environment(body.name, pose_b, near)
            return (t_b, pose_b, which_b) if d_b <= tol else None
        t = t_next
        pose = _flight_pose(f, body, start, t)[3]
    return t, pose, which


# --- snapshots ------------------------------------------------------------------------

def snapshot(part: PartState) -> PartSnapshot:
    return PartSnapshot(part.name, part.mode.value, part.pose.position, part.pose.rotation,
                        part.linear_velocity, part.angular_velocity)


def frame_record(scene: Scene, state: WorldState, inputs: TrackerFrame,
                 events: tuple[Event, ...]) -> FrameRecord:
    """What a frame derived, in the shape the recording and the review consume."""
    base = None
    if scene.base is not None and state.base_pose is not None:
        base = PartSnapshot(scene.base.name, Mode.INHAND.value, state.base_pose.position,
                            state.base_pose.rotation, sp.ZERO3, sp.ZERO3)
    return FrameRecord(inputs, base, tuple(snapshot(p) for p in state.parts), events)
