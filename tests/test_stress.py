"""Stress suite (issue 5, part 5): the simulator stays sane where naive schemes break.

Short by default (CI); ``VADE_STRESS=full python -m pytest -q -m stress`` runs the long
version: 1e6 steps instead of 1e4, a one-hour session instead of one minute, and hundreds of
hypothesis examples per property (exploring) instead of a few (derandomized).
"""

from __future__ import annotations

import bisect
import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

import strategies as S
from conftest import make_session, run_records, session_doc, table
from vade_replay import spatial as sp
from vade_replay.collision import CollisionWorld
from vade_replay.dynamics import free
from vade_replay.modes import Mode
from vade_replay.replay import record, replay
from vade_replay.recording import Recording
from vade_replay.state import OnBase, PartState, WorldState
from vade_replay.step import LEFT, RIGHT, step

FULL = S.FULL
STEPS = 10**6 if FULL else 10**4
SESSION_S = 3600 if FULL else 60
G = S.G

pytestmark = pytest.mark.stress


# --- shared checks ----------------------------------------------------------------------

def assert_sane_snapshot(snap) -> None:
    """Every number finite, the rotation a unit quaternion (|q| - 1 within 1e-12)."""
    values = (*snap.position, *snap.rotation_xyzw, *snap.linear_velocity,
              *snap.angular_velocity)
    assert all(math.isfinite(v) for v in values), snap
    assert abs(math.sqrt(sum(c * c for c in snap.rotation_xyzw)) - 1.0) <= 1e-12, snap


def assert_sane_records(records) -> None:
    for r in records:
        for snap in (*r.parts, *((r.base,) if r.base else ())):
            assert_sane_snapshot(snap)
        for e in r.events:
            # A NaN caught inside the step becomes this transition: it must never happen.
            assert getattr(e, "cause", None) != "numerical_fault", (r.frame, e)


def orthonormality_error(q) -> float:
    """max |R R^T - I| and |det R - 1| of the rotation matrix of ``q`` (numpy, independent)."""
    r = np.array(sp.quat_to_matrix(q))
    return max(float(np.max(np.abs(r @ r.T - np.eye(3)))), abs(float(np.linalg.det(r)) - 1.0))


def record_and_replay(doc: dict, files: dict | None, tmp_path, name="s"):
    """Record the session, replay the recording: it must match bit for bit."""
    session = make_session(doc, files)
    out = tmp_path / f"{name}.mcap"
    recorded = record(session, out)
    replayed = replay(Recording(out))
    assert replayed.match, replayed.first_divergence
    assert replayed.frames == recorded.frames > 0
    assert replayed.messages_checked >= 2 * replayed.frames
    return recorded, replayed


def on_shaft(scene, base_pose, *, angle_rate=0.0, slide_rate=0.0, mode=Mode.ONBASESLIDE,
             axis=(1.0, 0.0, 0.0)) -> WorldState:
    """A world at t = 0 with the disc of ``S.shaft_scene`` on its shaft."""
    from vade_replay import constraints as cn
    body = scene.parts[0]
    mate = body.assembly.mates[0]
    snapped = cn.recognise(mate, S.disc_on_shaft_pose(axis))
    assert snapped is not None
    motion = OnBase(0, snapped, (0.0,), (slide_rate,), angle_rate=angle_rate,
                    cm_offset=cn.cm_offset_base(mate, snapped))
    part = PartState(body.name, mode, base_pose.compose(snapped), motion=motion)
    return WorldState(0, 0, (part,), base_pose, ((LEFT, True), (RIGHT, False)))


def with_rates(scene, state: WorldState) -> WorldState:
    """The world with the part's CM and angular velocity set from its slide and turn rates
    (the helpers that place a part on the base leave them zero)."""
    from dataclasses import replace

    from vade_replay.step import _relative_rates
    part = state.parts[0]
    m = part.motion
    mate = scene.parts[0].assembly.mates[m.mate]
    v, w = _relative_rates(scene.parts[0], mate, m, m.slide_rate, m.angle, m.angle_rate)
    q = state.base_pose.rotation
    part = replace(part, linear_velocity=sp.quat_rotate(q, v), angular_velocity=sp.quat_rotate(q, w))
    return replace(state, parts=(part,))


def run_times(scene, state, times, left=None):
    """Step through frames at the given integer-ns times; ``left(t_ns)`` is the base pose."""
    world = CollisionWorld(scene)
    fixed = state.base_pose
    out = []
    for n, t in enumerate(times[1:], start=1):
        state, events = step(scene, world, state, S.tracker_frame(n, t, left(t) if left else fixed))
        out.append((t, state, events))
    return out


def energy(body, part: PartState, gravity) -> float:
    """Kinetic (CM translation + rotation about the CM) plus potential energy, from the
    world pose and velocities a frame derives (J)."""
    m = body.mass_kg
    cm = part.pose.apply(body.center_of_mass)
    q = sp.quat_mul(part.pose.rotation, body.part_from_principal)
    w_body = sp.quat_rotate(sp.quat_conj(q), part.angular_velocity)
    rot = 0.5 * sum(i * w * w for i, w in zip(body.principal_moments, w_body))
    return 0.5 * m * sp.dot(part.linear_velocity, part.linear_velocity) + rot \
        - m * sp.dot(gravity, cm)


def tilt(axis, deg, position=(0.0, 0.0, 1.0)) -> sp.Pose:
    return sp.Pose(position, sp.quat_axis_angle(axis, math.radians(deg)))


# --- 1. random scenes and tracker streams never produce NaN or infinity ------------------

@S.examples(ci=6, full=300)
@given(S.sessions())
def test_random_sessions_stay_finite(doc):
    records = run_records(doc)
    assert len(records) >= 2
    assert_sane_records(records)


@S.examples(ci=4, full=150)
@given(st.data())
def test_random_csv_streams_with_gaps_and_duplicates_stay_finite_and_replay(data):
    doc = data.draw(S.sessions())
    text = data.draw(S.csv_streams(doc))
    doc, files = S.csv_session(doc, text)
    records = run_records(doc, files)
    assert_sane_records(records)
    times = [r.time_ns for r in records]
    assert times == sorted(times)
    # And the stream, gaps and duplicates included, records and replays bit for bit.
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as folder:
        recorded, _ = record_and_replay(doc, files, Path(folder))
    assert recorded.frames == len(records)


@S.examples(ci=6, full=300)
@given(kind=st.sampled_from(["plane", "shaft"]), seconds=st.floats(0.5, 3.0),
       times=st.data(), rates=st.tuples(st.floats(-3.0, 3.0), st.floats(-20.0, 20.0)),
       friction=st.tuples(st.floats(0.0, 1.2), st.floats(0.0, 1.0)),
       damping=st.sampled_from([0.0, 1e-6, 2e-5, 1e-3]),
       base_turns=st.lists(S.unit_quats(), min_size=1, max_size=4),
       integrator=st.sampled_from(["yoshida6", "yoshida4", "verlet", "rk4", "paper"]))
def test_random_base_motion_on_constraints_stays_finite(kind, seconds, times, rates, friction,
                                                        damping, base_turns, integrator):
    """Parts on a plane or a shaft while the base is turned about at random, with gaps of
    up to 0.5 s and repeated timestamps in the stream: finite, unit rotations, no faults."""
    from _onbase import on_base, plate_scene
    fs, fd = max(friction), min(friction)
    if kind == "plane":
        scene = plate_scene({"turn_integrator": integrator}, friction=(fs, fd))
        state = on_base(scene, tilt((1, 0, 0), 0.0), sp.Pose((0.0, 0.0, 0.04)),
                        mode=Mode.ONBASESLIDE, slide_rate=(rates[0], 0.5 * rates[0]))
    else:
        scene = S.shaft_scene({"turn_integrator": integrator}, friction=(fs, fd),
                              damping=damping)
        state = on_shaft(scene, tilt((1, 0, 0), 0.0), angle_rate=rates[1],
                         slide_rate=rates[0])
    frame_ts = times.draw(S.frame_times(seconds))
    keys = [sp.IDENTITY_QUAT, *base_turns]
    span = frame_ts[-1] / len(base_turns)

    def left(t):
        k = min(int(t / span), len(keys) - 2)
        a = min(1.0, t / span - k)
        return sp.Pose((0.0, 0.0, 1.0), sp.slerp(keys[k], keys[k + 1], a))

    for t, s, events in run_times(scene, state, frame_ts, left):
        part = s.parts[0]
        assert_sane_snapshot(_snap(part))
        assert all(getattr(e, "cause", None) != "numerical_fault" for e in events)
        if isinstance(part.motion, OnBase):
            assert all(math.isfinite(c) for c in (*part.motion.slide, *part.motion.slide_rate,
                                                  part.motion.angle, part.motion.angle_rate))


def _snap(part: PartState):
    from vade_replay.step import snapshot
    return snapshot(part)


def test_angular_speed_bound_with_moments_one_ulp_apart():
    """Principal moments of a near-symmetric part (computed from a mesh) can differ in the
    last bit; 1/I_a == 1/I_b then, and the bound must still be a finite upper bound."""
    moments = (1e-7, 0.00045004157372394946, 0.0004500415737239495)
    assert moments[1] != moments[2] and 1.0 / moments[1] == 1.0 / moments[2]
    momentum = (1e-6, 2e-6, 3e-6)
    bound = free.max_angular_speed(momentum, moments)
    speed = sp.norm(tuple(m / i for m, i in zip(momentum, moments)))
    assert math.isfinite(bound) and speed <= bound <= 1.01 * speed


def test_tiny_slide_rate_on_a_plane():
    """A block sliding at 1e-82 m/s on a horizontal plane: its slide this frame is not zero
    but its square underflows; it must stop (friction) or creep, finite, never crash."""
    from _onbase import on_base, plate_scene
    scene = plate_scene()
    state = on_base(scene, tilt((1, 0, 0), 0.0), sp.Pose((0.0, 0.0, 0.04)),
                    mode=Mode.ONBASESLIDE, slide_rate=(-1e-82, 0.0))
    (_, s, _), = run_times(scene, state, [0, 10**9 // 60])
    assert_sane_snapshot(_snap(s.parts[0]))


# --- 2. rotation matrices stay orthonormal after a million steps -------------------------

BOX_MOMENTS = (0.3 * (0.05**2 + 0.02**2) / 12, 0.3 * (0.10**2 + 0.02**2) / 12,
               0.3 * (0.10**2 + 0.05**2) / 12)
ROD_MOMENTS = (2.2842021559081e-10, 1.3744522250879228e-05, 1.374452225087923e-05)


@pytest.mark.parametrize("model, order, moments, w0", [
    ("momentum", 6, BOX_MOMENTS, (0.1, 5.0, 0.1)),     # near the intermediate axis: tumbles
    ("momentum", 2, BOX_MOMENTS, (0.1, 5.0, 0.1)),
    ("momentum", 6, ROD_MOMENTS, (0.3, 6.0, 2.0)),     # thin rod, inertia ratio 6e4
    ("constant_omega", 6, BOX_MOMENTS, (0.1, 5.0, 0.1)),
], ids=["box-order6", "box-order2", "thin-rod", "constant-omega"])
def test_free_flight_rotation_stays_orthonormal(model, order, moments, w0):
    """``free.advance`` frame after frame at 60 Hz (as ``step`` does), STEPS frames: the
    rotation matrix of the part pose is orthonormal to 1e-12; the world angular momentum
    (momentum model) is conserved to 1e-9 relative and the energy stays within 1e-6."""
    flight = free.start(t_ns=0, cm=sp.ZERO3, velocity=sp.ZERO3, omega_world=w0,
                        world_from_part=sp.IDENTITY, part_from_principal=sp.IDENTITY_QUAT,
                        principal_moments=moments)
    l0 = sp.quat_rotate(flight.world_from_principal, flight.momentum_principal)
    e0 = sum(m * m / (2 * i) for m, i in zip(flight.momentum_principal, moments))
    part_from_principal = sp.quat_normalize((0.1, -0.2, 0.3, 0.9))
    worst = 0.0
    for n in range(1, STEPS + 1):
        flight = free.advance(flight, n * 10**9 // 60, model=model, moments=moments, order=6
                              if order == 6 else order, max_step_s=1 / 60)
        if n % 997 == 0 or n == STEPS:
            pose = free.pose(flight, sp.ZERO3, part_from_principal=part_from_principal,
                             center_of_mass=(0.01, 0.0, 0.0))
            worst = max(worst, orthonormality_error(pose.rotation),
                        orthonormality_error(flight.world_from_principal))
    assert worst <= 1e-12, worst
    if model == "momentum":
        m = flight.momentum_principal
        l1 = sp.quat_rotate(flight.world_from_principal, m)
        assert sp.norm(sp.sub(l1, l0)) <= 1e-9 * sp.norm(l0)
        e1 = sum(x * x / (2 * i) for x, i in zip(m, moments))
        assert abs(e1 - e0) <= 1e-6 * e0
        assert all(math.isfinite(c) for c in (*l1, *flight.world_from_principal))


def test_turning_on_a_shaft_stays_orthonormal_and_keeps_its_energy():
    """A disc whirling over the top of a horizontal shaft (undamped) for STEPS frames through
    ``step``: the part pose stays orthonormal to 1e-12, it keeps turning the same way, and
    the energy stays within 1e-8 of its range (the 6th-order splitting's bounded error) plus
    the round-off of the ever-growing angle."""
    scene = S.shaft_scene()
    body = scene.parts[0]
    base = sp.Pose((0.0, 0.0, 1.0), sp.IDENTITY_QUAT)
    state = on_shaft(scene, base, angle_rate=30.0)
    world = CollisionWorld(scene)
    gravity = scene.physics.gravity_rotation
    e0 = None
    scale = body.mass_kg * G * 0.02
    energy_range = 0.5 * body.assembly.mates[0].inertia_about_axis * 30.0**2 + 2.0 * scale
    worst_e = worst_r = 0.0
    last_angle = 0.0
    for n in range(1, STEPS + 1):
        state, events = step(scene, world, state, S.tracker_frame(n, n * 10**9 // 60, base))
        assert not events
        if n % 97 == 0 or n == STEPS:
            part = state.parts[0]
            worst_r = max(worst_r, orthonormality_error(part.pose.rotation))
            e = energy(body, part, gravity)
            e0 = e if e0 is None else e0
            worst_e = max(worst_e, abs(e - e0))
            assert part.motion.angle > last_angle
            last_angle = part.motion.angle
    assert worst_r <= 1e-12, worst_r
    # Round-off allowance: the angle is not wrapped, so each of the 28 additions per frame
    # (7 stages x 4 sub-steps) rounds it by up to half an ulp of |angle|; as a random walk
    # that moves the potential energy by m g r ulp(angle) sqrt(28 n) (6e-7 m g r after 1e6
    # frames at 5e5 rad, 4e-11 after 1e4). Allowed: 1e-8 of the energy range of the motion
    # (0.5 J w0^2 + 2 m g r) for the integrator's bounded error, plus 4x that round-off.
    roundoff = 4.0 * math.ulp(last_angle) * math.sqrt(28.0 * STEPS) * scale
    assert worst_e <= 1e-8 * energy_range + roundoff, (worst_e / energy_range, roundoff)
    assert state.parts[0].mode is Mode.ONBASESLIDE


# --- 3. energy never rises in passive phases with friction ---------------------------------
# Passive: the base is still, so nothing does work on the part but gravity and friction.
# Allowance: sliding is exact (closed form) so 1e-12 J per kg covers round-off; turning
# adds the 6th-order splitting's bounded energy error, 1e-8 of the swing's scale m g |r|.

@S.examples(ci=8, full=300)
@given(theta=st.floats(0.0, 45.0), direction=st.floats(0.0, 2 * math.pi),
       speed=st.floats(0.0, 3.0), friction=st.tuples(st.floats(0.01, 1.0), st.floats(0.01, 1.0)))
def test_sliding_on_a_still_plane_never_gains_energy(theta, direction, speed, friction):
    from _onbase import on_base, plate_scene
    fs, fd = max(friction), min(friction)
    scene = plate_scene(size=(8.0, 8.0, 0.04), friction=(fs, fd))
    base = tilt((1.0, 0.0, 0.0), -theta)
    state = on_base(scene, base, sp.Pose((0.0, 0.0, 0.04)), mode=Mode.ONBASESLIDE,
                    slide_rate=(speed * math.cos(direction), speed * math.sin(direction)))
    body = scene.parts[0]
    gravity = scene.physics.gravity_slide
    e_min = energy(body, with_rates(scene, state).parts[0], gravity)
    for t, s, _ in run_times(scene, state, [n * 10**9 // 60 for n in range(91)]):
        part = s.parts[0]
        if part.mode not in (Mode.ONBASESLIDE, Mode.ONBASESTATIC):
            break  # off the plate: no longer passive on the base
        e = energy(body, part, gravity)
        assert e <= e_min + 1e-12 * body.mass_kg, (t, e - e_min)
        e_min = min(e_min, e)


@S.examples(ci=8, full=300)
@given(tilt_deg=st.floats(0.0, 60.0), start=st.floats(-math.pi, math.pi),
       rate=st.floats(-15.0, 15.0), slide=st.floats(-0.5, 0.5),
       damping=st.floats(1e-6, 1e-3), offset=st.floats(0.0, 0.035),
       friction=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)))
# Found by the full run (2026-11-22): the collar stopped the slide while the disc swung at
# 16.6 rad/s; the turn was cut at the contact too but kept its end-of-frame rate, +2.5 % of
# m g r. Now a block cuts only what it stops (physics.block_cut).
@example(tilt_deg=0.0, start=2.5, rate=0.0, slide=-0.1875, damping=0.001, offset=0.03125,
         friction=(0.0, 0.0))
def test_turning_and_sliding_on_a_still_shaft_never_gains_energy(tilt_deg, start, rate, slide,
                                                                 damping, offset, friction):
    """A disc on a tilted shaft turns (viscous friction) and slides (Coulomb friction) at
    once; a collar on the shaft blocks it (inelastic)."""
    fs, fd = max(friction), min(friction)
    scene = S.shaft_scene(friction=(fs, fd), damping=damping,
                          offset=(offset * math.cos(start), offset * math.sin(start)), stop=-0.1)
    base = tilt((0.0, 1.0, 0.0), tilt_deg)  # base x (the shaft) points down-hill to -x
    state = on_shaft(scene, base, angle_rate=rate, slide_rate=slide)
    body = scene.parts[0]
    gravity = scene.physics.gravity_rotation
    scale = body.mass_kg * G * max(offset, 1e-3)
    e_min = energy(body, with_rates(scene, state).parts[0], gravity)
    for t, s, _ in run_times(scene, state, [n * 10**9 // 60 for n in range(121)]):
        part = s.parts[0]
        if part.mode not in (Mode.ONBASESLIDE, Mode.ONBASESTATIC):
            break
        e = energy(body, part, gravity)
        assert e <= e_min + 1e-8 * scale + 1e-12 * body.mass_kg, (t, (e - e_min) / scale)
        e_min = min(e_min, e)


def _arm_on_a_shaft_over_a_rail(physics=None):
    """An arm (its CM 3 cm off the shaft) on a horizontal frictionless shaft along base x,
    0.4 m long, and a rail beside the shaft and along it, which stops the arm's swing and
    not its slide. Returns the scene and a world maker: (slide, angle, their rates)."""
    from vade_replay import constraints as cn
    from vade_replay.scene import build_scene
    q = sp.quat_axis_angle((0.0, 1.0, 0.0), math.pi / 2)  # a cylinder's z onto base x
    base = {"name": "shaft", "shape": {"type": "compound", "children": [
        {"type": "cylinder", "radius": 0.006, "height": 0.4, "pose": {"xyzw": list(q)}},
        {"type": "box", "size": [0.6, 0.02, 0.02], "pose": {"position": [0.0, 0.04, -0.04]}}]}}
    arm = {"name": "arm", "shape": {"type": "compound", "children": [
        {"type": "box", "size": [0.08, 0.01, 0.01], "pose": {"position": [0.03, 0.0, 0.0]}}]},
        "mass_properties": {"mass": 0.1, "center_of_mass": [0.03, 0.0, 0.0],
                            "inertia": [[1e-5, 0, 0], [0, 6e-5, 0], [0, 0, 6e-5]]},
        "assembly": {"constraints": [
            {"type": "axis", "radius": 0.006,
             "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
             "base": {"point": [0, 0, 0], "direction": [1, 0, 0]},
             "friction": {"static": 0.0, "dynamic": 0.0, "rotational": 0.0}}]}}
    scene = build_scene(S.base_session([arm], base, physics), {})
    body = scene.parts[0]
    mate = body.assembly.mates[0]
    snapped = cn.recognise(mate, S.disc_on_shaft_pose((1.0, 0.0, 0.0)))
    base_pose = sp.Pose((0.0, 0.0, 1.0))

    def world(x, angle, slide_rate, angle_rate) -> WorldState:
        m = OnBase(0, snapped, (x,), (slide_rate,), angle=angle, angle_rate=angle_rate,
                   cm_offset=cn.cm_offset_base(mate, snapped))
        part = PartState(body.name, Mode.ONBASESLIDE,
                         base_pose.compose(cn.relative_pose(mate, snapped, (x,), angle)),
                         motion=m)
        return WorldState(0, 0, (part,), base_pose, ((LEFT, True), (RIGHT, False)))
    return scene, world


@pytest.mark.parametrize("block_cut", ["blamed", "both"])
def test_a_turn_stopped_in_the_frame_the_part_slides_off_does_not_leave_with_its_rate(block_cut):
    """The arm swings down into the rail (-6 rad/s, the contact ~0.08 rad away) while it
    slides off the shaft's end at 1 m/s, in the same frame. The base stops the turn, so the
    part leaves (at the frame's end) without a rate into the rail: a still base and a
    frictionless horizontal shaft leave it exactly its slide, (1, 0, 0) m/s, and no spin
    (before, it left at -8.97 rad/s and flew on through the rail). The contact is an event.
    With ``block_cut: both`` (older recordings, the paper model) the slide is cut at the
    contact too, and the part is still on the shaft after the frame."""
    scene, world = _arm_on_a_shaft_over_a_rail({"block_cut": block_cut})
    for x0, stays in ((0.0, True), (0.19, False)):
        state = world(x0, 1.2, 1.0, -6.0)
        after, events = step(scene, CollisionWorld(scene), state,
                             S.tracker_frame(1, 10**9 // 60, state.base_pose))
        part = after.parts[0]
        kinds = [(e.kind, e.cause) for e in events]
        if stays:  # the same swing on the shaft's middle: blocked, sliding on
            assert part.mode is Mode.ONBASESLIDE and part.motion.angle_rate == 0.0
            assert kinds == [("ContactMade", "blocked_by_base")]
            assert 1.1 < part.motion.angle < 1.2
        elif block_cut == "blamed":
            assert part.mode is Mode.INSPACE
            assert kinds == [("ContactMade", "blocked_by_base"),
                             ("ModeChanged", "slid_off_base")]
            assert part.linear_velocity == (1.0, 0.0, 0.0)
            assert part.angular_velocity == (0.0, 0.0, 0.0)
        else:  # both motions cut at the contact: still on the shaft this frame
            assert part.mode is Mode.ONBASESLIDE and part.motion.angle_rate == 0.0
            assert x0 < part.motion.slide[0] < x0 + 1.0 / 60.0


# --- 4. friction never reverses motion -------------------------------------------------------

@S.examples(ci=8, full=300)
@given(direction=st.floats(0.0, 2 * math.pi), speed=st.floats(1e-6, 3.0),
       fd=st.floats(0.05, 1.0))  # stops within 9.2 m: on the 40 m plate
def test_friction_on_a_horizontal_plane_stops_a_part_in_a_straight_line(direction, speed, fd):
    """Horizontal plane: the part decelerates at f_d g along a straight line, never turns
    back, stops at v0^2 / (2 f_d g) (closed form, 1e-12 m + 1e-12 relative) within the
    frame the closed form stops in, and stays there bit for bit."""
    from _onbase import on_base, plate_scene
    # Half a side beyond the longest slide: s0^2 / (2 g (f_d cos - sin)) <= 20.5 m here
    # (2 m/s, f_d 0.05, ratio 0.8); 40 m was too small for that corner (found in a full run).
    scene = plate_scene(size=(60.0, 60.0, 0.04), friction=(fd, fd))
    v0 = (speed * math.cos(direction), speed * math.sin(direction))
    state = on_base(scene, tilt((1, 0, 0), 0.0), sp.Pose((0.0, 0.0, 0.04)),
                    mode=Mode.ONBASESLIDE, slide_rate=v0)
    decel = fd * G
    t_stop = speed / decel
    frames = int(t_stop * 60) + 3
    prev_v, stopped = v0, None
    for t, s, events in run_times(scene, state, [n * 10**9 // 60 for n in range(frames + 1)]):
        m = s.parts[0].motion
        v = m.slide_rate
        assert v[0] * prev_v[0] + v[1] * prev_v[1] >= 0.0            # never back
        assert math.hypot(*v) <= math.hypot(*prev_v)                  # never faster
        assert abs(v[0] * v0[1] - v[1] * v0[0]) <= 1e-12 * speed * speed  # same line
        along = (m.slide[0] * v0[0] + m.slide[1] * v0[1]) / speed
        tau = min(t * 1e-9, t_stop)
        assert along == pytest.approx(speed * tau - 0.5 * decel * tau * tau,
                                      abs=1e-12, rel=1e-12)
        if stopped is not None:
            assert s.parts[0].pose == stopped and not events
        elif s.parts[0].mode is Mode.ONBASESTATIC:
            assert 0.0 <= t * 1e-9 - t_stop < 1.0 / 60.0 + 1e-12
            stopped = s.parts[0].pose
        prev_v = v
    assert stopped is not None


@S.examples(ci=8, full=300)
@given(ratio=st.floats(0.0, 0.8), direction=st.floats(0.0, 2 * math.pi),
       speed=st.floats(0.01, 2.0), fd=st.floats(0.05, 1.0))
# Pushed all but straight downhill (found in a full run, and by a review): the sub-step for
# a velocity along g_t to within 1e-12 rad updated its components on their own, scaling the
# across-slope round-off by 1 - c h / |v|, below -1 near a stop (6.9e-14 m/s became
# -1.5e-14): now it accelerates along the velocity itself.
@example(ratio=0.7984047390879633, direction=8.572545777594152e-07, speed=0.75, fd=1.0)
@example(ratio=0.7, direction=2e-11, speed=0.02, fd=0.1)
@example(ratio=0.8, direction=2e-11, speed=0.02, fd=0.3)
def test_friction_below_the_friction_angle_slows_and_stops_never_reverses(ratio, direction,
                                                                          speed, fd):
    """An incline shallower than the friction angle (tan theta = ratio f_d, f_s = f_d), pushed
    in any direction: the speed never rises, the velocity only ever turns towards downhill
    (its angle from downhill never grows: friction does not turn it back), it stops no later
    than s0 / (g (f_d cos - sin)) and then stays bit for bit. (Turning downhill is gravity's
    doing: near the friction angle a part pushed uphill curves round and creeps downhill
    before it stops, in the closed form too.)"""
    from _onbase import on_base, plate_scene
    theta = math.atan(ratio * fd)
    # Half a side beyond the longest slide: s0^2 / (2 g (f_d cos - sin)) <= 20.5 m here
    # (2 m/s, f_d 0.05, ratio 0.8); 40 m was too small for that corner (found in a full run).
    scene = plate_scene(size=(60.0, 60.0, 0.04), friction=(fd, fd))
    v0 = (speed * math.cos(direction), speed * math.sin(direction))
    state = on_base(scene, tilt((1, 0, 0), -math.degrees(theta)), sp.Pose((0.0, 0.0, 0.04)),
                    mode=Mode.ONBASESLIDE, slide_rate=v0)
    t_bound = speed / (G * (fd * math.cos(theta) - math.sin(theta)))
    frames = int(t_bound * 60) + 3

    def from_downhill(v):  # slide coordinate 0 is downhill (base +y), 1 is across
        return math.atan2(abs(v[1]), v[0])
    prev_v, stopped = v0, None
    for t, s, events in run_times(scene, state, [n * 10**9 // 60 for n in range(frames + 1)]):
        v = s.parts[0].motion.slide_rate
        assert math.hypot(*v) <= math.hypot(*prev_v) * (1.0 + 1e-12)
        if v != (0.0, 0.0):
            assert from_downhill(v) <= from_downhill(prev_v) + 1e-12
        if stopped is not None:
            assert s.parts[0].pose == stopped and v == (0.0, 0.0)
        elif s.parts[0].mode is Mode.ONBASESTATIC:
            stopped = s.parts[0].pose
            assert t * 1e-9 <= t_bound + 1.0 / 60.0
        prev_v = v
    assert stopped is not None


@S.examples(ci=8, full=300)
@given(rate=st.floats(-50.0, 50.0).filter(lambda w: abs(w) > 1e-3),
       damping=st.floats(1e-6, 1e-2), axis=st.sampled_from([(1, 0, 0), (0, 1, 0), (1, 1, 0)]))
def test_viscous_friction_decays_a_spin_without_reversing_it(rate, damping, axis):
    """CM on the shaft axis (no gravity torque), horizontal shafts (no slope): w(t) = w0 e^{-f_r t/J}
    within 1e-12 relative and theta(t) = w0 J/f_r (1 - e^{-f_r t/J}) within 1e-9; w never
    changes sign."""
    scene = S.shaft_scene(offset=(0.0, 0.0), damping=damping, axis=axis, friction=(10.0, 10.0))
    mate = scene.parts[0].assembly.mates[0]
    j = mate.inertia_about_axis
    state = on_shaft(scene, sp.Pose((0.0, 0.0, 1.0)), angle_rate=rate, axis=axis)
    for t, s, _ in run_times(scene, state, [n * 10**9 // 60 for n in range(121)]):
        m = s.parts[0].motion
        tau = t * 1e-9
        decay = math.exp(-damping * tau / j)
        assert m.angle_rate * rate > 0.0
        assert m.angle_rate == pytest.approx(rate * decay, rel=1e-12)
        # The angle is the 6th-order quadrature of that exponential: (f_r h / J)^7 error, up
        # to 1e-10 relative at the strongest damping drawn (f_r h / J = 0.14).
        assert m.angle == pytest.approx(rate * j / damping * -math.expm1(-damping * tau / j),
                                        rel=1e-9)
        assert m.slide == (0.0,)


# --- 5. edge cases behave -------------------------------------------------------------------

def _with_gap(times_s=2.0, gap=(0.6, 1.1)):
    """60 Hz frame times with no samples strictly inside ``gap`` (0.5 s)."""
    out = [n * 10**9 // 60 for n in range(int(times_s * 60) + 1)]
    return [t for t in out if not gap[0] * 1e9 < t < gap[1] * 1e9 - 1]


def test_gap_while_sliding_keeps_the_closed_form():
    """A 0.5 s gap in the samples while a block slides down a still 20 degree incline: the
    position after the gap is still the closed form 0.5 a t^2 (1e-9 m), 120 sub-steps in one
    frame."""
    from _onbase import on_base, plate_scene
    scene = plate_scene()
    base = tilt((1, 0, 0), -20.0)
    state = on_base(scene, base, sp.Pose((0.0, -0.8, 0.04)))
    start = state.parts[0].pose.position
    down = sp.quat_rotate(base.rotation, (0.0, 1.0, 0.0))
    th = math.radians(20.0)
    a = G * (math.sin(th) - 0.2 * math.cos(th))
    times = _with_gap(1.2)
    assert max(b - a_ for a_, b in zip(times, times[1:])) >= 5 * 10**8
    for t, s, _ in run_times(scene, state, times):
        tau = t * 1e-9
        expected = sp.add(start, sp.scale(down, 0.5 * a * tau * tau))
        assert sp.norm(sp.sub(s.parts[0].pose.position, expected)) < 1e-9


def test_gap_while_turning_matches_the_reference():
    """A 0.5 s gap while the damped gear swings: after it the angle agrees with a DOP853
    reference to 1e-7 rad, as without the gap."""
    from scipy.integrate import solve_ivp
    damping = 2e-5
    scene = S.shaft_scene(damping=damping, offset=(0.0, 0.02))  # CM level with the shaft
    body = scene.parts[0]
    j = body.assembly.mates[0].inertia_about_axis
    state = on_shaft(scene, sp.Pose((0.0, 0.0, 1.0)))
    times = _with_gap(3.0, gap=(1.0, 1.5))
    out = run_times(scene, state, times)
    r = 0.02
    theta0 = math.atan2(state.parts[0].motion.cm_offset[2], state.parts[0].motion.cm_offset[1])

    def rhs(_, y):
        # CM offset at angle theta about +x from (0, r cos, r sin): torque m g r cos(theta0+theta)
        return [y[1], (-body.mass_kg * G * r * math.cos(theta0 + y[0]) - damping * y[1]) / j]
    ts = [t * 1e-9 for t, _, _ in out]
    ref = solve_ivp(rhs, (0.0, ts[-1]), [0.0, 0.0], method="DOP853", t_eval=ts, rtol=1e-13,
                    atol=1e-13).y[0]
    err = max(abs(s.parts[0].motion.angle - x) for (_, s, _), x in zip(out, ref))
    assert err < 1e-7, err
    assert max(abs(x) for x in ref) > 1.0  # it really swung


def _throw_doc(csv_rows=None, **physics):
    """A box thrown by a hand moving at constant velocity and spin (known release rates),
    released at t = 0.7 s, 0.43 m above the table; it lands at about 1.0 s."""
    box = {"name": "box", "shape": {"type": "box", "size": [0.10, 0.05, 0.02]}, "density": 3000,
           "pose": {"position": [0.0, 0.0, 0.75]}}
    q1 = sp.quat_axis_angle((0.0, 0.0, 1.0), 1.2)
    return session_doc(parts=[box], physics=physics or None, duration_s=2.0, right_hand=[
        {"t": 0.0, "position": [0.0, 0.0, 0.75], "grip": False},
        {"t": 0.1, "grip": True},
        {"t": 0.4, "position": [0.0, 0.0, 0.80]},
        {"t": 0.7, "position": [0.3, 0.1, 1.25], "xyzw": list(q1), "grip": False},
        {"t": 1.0, "position": [0.5, 0.5, 1.25]}])


def _rows(doc, edit):
    """The session's 60 Hz stream as CSV rows [(t_ns, device, sample)], edited by ``edit``."""
    frames = list(make_session(doc).tracker_frames())
    rows = [(f.time_ns, name, s) for f in frames for name, s in f.devices]
    rows = edit(rows)
    text = "time,device,x,y,z,q0,q1,q2,q3,grip\n" + "".join(
        S._csv_row(t, d, s) + "\n" for t, d, s in rows)
    return S.csv_session(doc, text)


def _release(records):
    r = next(r for r in records if any(e.kind == "PartReleased" for e in r.events))
    return r, next(e for e in r.events if e.kind == "PartReleased")


def test_gap_in_flight_keeps_the_closed_form_and_still_stops_at_the_table(tmp_path):
    """No samples from 0.75 s to 1.25 s: the box is released at 0.7 s (full gravity) and
    reaches the table inside the gap. The flight before the gap is the closed form (1e-12 m), the contact
    is found inside the gap (the part stops on top of the table: 0 <= gap <= tolerance, never
    below), and the session records and replays bit for bit."""
    doc = _throw_doc(gravity_scale_free=1.0)  # lands at 1.21 s, inside the gap
    doc["environment"] = [table(size=(3.0, 3.0, 0.04))]
    doc, files = _rows(doc, lambda rows: [r for r in rows if not 0.75e9 < r[0] < 1.25e9])
    records = run_records(doc, files)
    assert_sane_records(records)
    assert max(b.time_ns - a.time_ns for a, b in zip(records, records[1:])) >= 5 * 10**8 - 10**7
    release, event = _release(records)
    assert np.allclose(event.linear_velocity, (1.0, 1.0 / 3.0, 1.5), atol=1e-9)
    p0 = np.array(release.parts[0].position)
    g = np.array([0.0, 0.0, -G])
    for r in records:
        if r.frame > release.frame and r.parts[0].mode == "INSPACE":
            tau = (r.time_ns - release.time_ns) * 1e-9
            assert np.allclose(r.parts[0].position, p0 + np.array(event.linear_velocity) * tau
                               + 0.5 * g * tau * tau, rtol=0, atol=1e-12)
    contact = [(r, e) for r in records for e in r.events if e.kind == "ContactMade"]
    assert len(contact) == 1 and contact[0][1].other == "table"
    assert 0.75e9 < contact[0][1].time_ns < 1.25e9   # found inside the gap
    final = records[-1].parts[0]
    assert final.mode == "STATIC"
    scene = make_session(doc, files).build_scene()
    d, _ = CollisionWorld(scene).distance_to_environment(
        "box", sp.Pose(final.position, final.rotation_xyzw), (0,))
    assert 0.0 <= d <= scene.physics.contact_tolerance
    record_and_replay(doc, files, tmp_path)


def test_gap_while_held_gives_the_exact_release_velocity():
    """No samples for 0.5 s just before the throw: the hand moves at constant velocity, so
    the fit over the (unevenly spaced) held poses still gives it exactly (1e-9)."""
    doc = _throw_doc()
    doc, files = _rows(doc, lambda rows: [r for r in rows if not 0.1e9 < r[0] < 0.6e9])
    records = run_records(doc, files)
    assert_sane_records(records)
    _, event = _release(records)
    assert np.allclose(event.linear_velocity, (1.0, 1.0 / 3.0, 1.5), atol=1e-9)
    assert np.allclose(event.angular_velocity, (0.0, 0.0, 4.0), atol=1e-9)


def _duplicate(at_s: float, other_pose: bool):
    def edit(rows):
        out = []
        for t, d, s in rows:
            out.append((t, d, s))
            if d == RIGHT and abs(t - at_s * 1e9) < 1e7:
                if other_pose:
                    s = type(s)(sp.add(s.position, (0.002, -0.001, 0.003)),
                                sp.quat_normalize(sp.quat_mul(sp.quat_axis_angle((1, 0, 0),
                                                                                 0.02),
                                                              s.rotation_xyzw)), s.grip)
                out.append((t, d, s))
        return out
    return edit


@pytest.mark.parametrize("other_pose", [False, True], ids=["same-pose", "other-pose"])
def test_duplicated_timestamp(tmp_path, other_pose):
    """A right-hand sample repeated at the same time (0.5 s, while held): a frame of its own
    with dt = 0. Finite; the duplicate frame's part follows the hand; from seven frames on
    (the fit window) every derived value equals the run whose stream holds only the second of
    the two samples; the release velocity is exact (1e-9); record and replay match bit for bit."""
    base_doc = _throw_doc()
    doc, files = _rows(base_doc, _duplicate(0.5, other_pose))
    # The reference stream: the duplicate's second sample only.
    def second_only(rows):
        rows = _duplicate(0.5, other_pose)(rows)
        drop = next(i for i, (t, d, _) in enumerate(rows)
                    if d == RIGHT and abs(t - 0.5e9) < 1e7)
        return rows[:drop] + rows[drop + 1:]
    ref_doc, ref_files = _rows(base_doc, second_only)
    records = run_records(doc, files)
    reference = run_records(ref_doc, ref_files)
    assert_sane_records(records)
    assert len(records) == len(reference) + 1
    k = next(i for i, (a, b) in enumerate(zip(records, records[1:])) if a.time_ns == b.time_ns)
    assert records[k + 1].parts[0].mode == "INHAND"
    for ours, theirs in zip(records[k + 1 + 7:], reference[k + 7:]):
        assert ours.parts == theirs.parts
        assert [(e.kind, getattr(e, "cause", None)) for e in ours.events] == \
            [(e.kind, getattr(e, "cause", None)) for e in theirs.events]
    _, event = _release(records)
    assert np.allclose(event.linear_velocity, (1.0, 1.0 / 3.0, 1.5), atol=1e-9)
    record_and_replay(doc, files, tmp_path)


def test_repeated_pose_at_a_new_time_gives_the_least_squares_release_velocity():
    """A stale sample (the previous pose again, at the next time) two frames before the
    release: the release velocity is the slope at the newest pose of the least-squares
    quadratic through the last seven held CM positions (numpy.polyfit, 1e-9 m/s): finite,
    no special case gone wrong."""
    doc = _throw_doc()

    def stale(rows):
        out, last = [], None
        for t, d, s in rows:
            if d == RIGHT and abs(t - (0.7e9 - 2e9 / 60)) < 1e7:
                s = type(s)(last.position, last.rotation_xyzw, s.grip)
            if d == RIGHT:
                last = s
            out.append((t, d, s))
        return out
    doc, files = _rows(doc, stale)
    records = run_records(doc, files)
    assert_sane_records(records)
    release, event = _release(records)
    held = [r for r in records if r.frame < release.frame][-6:] + [release]
    body = make_session(doc, files).build_scene().parts[0]
    ts = np.array([(r.time_ns - release.time_ns) * 1e-9 for r in held])
    cms = np.array([sp.Pose(r.parts[0].position, r.parts[0].rotation_xyzw).apply(
        body.center_of_mass) for r in held])
    slope = [np.polyfit(ts, cms[:, i], 2)[1] for i in range(3)]
    assert np.allclose(event.linear_velocity, slope, atol=1e-9)
    assert np.linalg.norm(np.array(event.linear_velocity) - (1.0, 1 / 3, 1.5)) > 0.01


def test_thin_rod_flight_conserves_momentum_and_lands_on_the_table(tmp_path):
    """A rod 1 mm thick and 0.3 m long (inertia ratio 6e4) thrown end over end: finite, world
    angular momentum conserved to 1e-9, it stops on top of the table (not through it: within
    the contact tolerance) and the session records and replays bit for bit."""
    rod = {"name": "rod", "shape": {"type": "cylinder", "radius": 0.0005, "height": 0.3},
           "density": 7800, "pose": {"position": [0.0, 0.0, 0.9], "euler_deg": [0, 90, 0]}}
    doc = session_doc(parts=[rod], duration_s=2.5, right_hand=[
        {"t": 0.0, "position": [0.0, 0.0, 0.9], "grip": False},
        {"t": 0.1, "grip": True},
        {"t": 0.3, "position": [0.0, 0.0, 0.9]},
        {"t": 0.6, "position": [0.1, 0.0, 1.2], "euler_deg": [0, 0, 120], "grip": False},
        {"t": 0.8, "position": [0.3, 0.0, 1.2]}])
    records = run_records(doc)
    assert_sane_records(records)
    body = make_session(doc).build_scene().parts[0]
    flying = [r.parts[0] for r in records if r.parts[0].mode == "INSPACE"]
    assert len(flying) > 10

    def momentum(p):
        q = sp.quat_mul(p.rotation_xyzw, body.part_from_principal)
        w = sp.quat_rotate(sp.quat_conj(q), p.angular_velocity)
        return np.array(sp.quat_rotate(q, tuple(i * x for i, x in zip(body.principal_moments,
                                                                      w))))
    l0 = momentum(flying[0])
    assert np.linalg.norm(l0) > 0.0
    for p in flying:
        assert np.linalg.norm(momentum(p) - l0) <= 1e-9 * np.linalg.norm(l0)
    final = records[-1].parts[0]
    assert final.mode == "STATIC"
    scene = make_session(doc).build_scene()
    d, _ = CollisionWorld(scene).distance_to_environment(
        "rod", sp.Pose(final.position, final.rotation_xyzw), (0,))
    assert 0.0 <= d <= scene.physics.contact_tolerance
    record_and_replay(doc, None, tmp_path)


def _symmetric_top(q0, m0, t, i_axis, i_perp):
    """Closed-form torque-free motion of a symmetric top (I_1 = I_2 = i_perp, axis 0 here):
    q(t) = exp(t L_world / I_perp) q0 exp(t (1/I_axis - 1/I_perp) L_axis e_axis)."""
    lw = sp.quat_rotate(q0, m0)
    c = (1.0 / i_axis - 1.0 / i_perp) * m0[0]
    return sp.quat_mul(sp.quat_mul(sp.quat_from_rotvec(sp.scale(lw, t / i_perp)), q0),
                       sp.quat_from_rotvec((c * t, 0.0, 0.0)))


def test_thin_rod_follows_the_symmetric_top_closed_form():
    """The rod tumbling end over end (no spin about its long axis), as the simulator moves
    it (free.advance: two equal moments, so the closed form rather than the splitting, whose
    error the stiff long axis (I = 2.3e-10) blows up to 7.8e-3 rad after 1 s): within 1e-6
    rad of this independent form of the closed solution over 10 s of 60 Hz frames."""
    moments = ROD_MOMENTS
    w0 = (0.0, 5.0, 3.5)
    m0 = tuple(i * w for i, w in zip(moments, w0))
    # What the simulator runs (free.advance): the rod is axisymmetric, so a closed form.
    flight = free.start(t_ns=0, cm=sp.ZERO3, velocity=sp.ZERO3, omega_world=w0,
                        world_from_part=sp.IDENTITY, part_from_principal=sp.IDENTITY_QUAT,
                        principal_moments=moments)
    worst = 0.0
    for n in range(1, 601):
        flight = free.advance(flight, n * 10**9 // 60, model="momentum", moments=moments,
                              order=6, max_step_s=1 / 60)
        expected = _symmetric_top(sp.IDENTITY_QUAT, m0, (n * 10**9 // 60) * 1e-9, moments[0],
                                  moments[1])
        worst = max(worst, sp.quat_angle_between(flight.world_from_principal, expected))
    assert worst <= 1e-6, worst


def test_symmetric_top_closed_form_is_right():
    """The reference of the test above, checked: the splitting converges to it (1e-9 rad at
    1/6000 s over 1 s), and a less extreme top matches it at the defaults (1e-8 rad)."""
    moments = ROD_MOMENTS
    m0 = tuple(i * w for i, w in zip(moments, (0.0, 5.0, 3.5)))
    q, _ = free.rotate_momentum(sp.IDENTITY_QUAT, m0, 1.0, moments, order=6, max_step_s=1 / 6000)
    assert sp.quat_angle_between(q, _symmetric_top(sp.IDENTITY_QUAT, m0, 1.0, *moments[:2])) < 1e-9
    top = (1e-5, moments[1], moments[2])
    m0 = tuple(i * w for i, w in zip(top, (2.0, 5.0, 3.5)))
    q, _ = free.rotate_momentum(sp.IDENTITY_QUAT, m0, 1.0, top, order=6, max_step_s=1 / 60)
    assert sp.quat_angle_between(q, _symmetric_top(sp.IDENTITY_QUAT, m0, 1.0, *top[:2])) < 1e-8


def test_cm_on_a_horizontal_shaft_axis_never_moves():
    """CM on the axis of a horizontal shaft: no gravity torque, no slope. Released at rest it
    is ONBASESTATIC and its pose does not change by a bit in STEPS frames."""
    scene = S.shaft_scene(offset=(0.0, 0.0))
    base = sp.Pose((0.1, -0.2, 1.0), sp.quat_axis_angle((0, 0, 1), 0.3))
    state = on_shaft(scene, base, mode=Mode.ONBASESTATIC)
    pose0 = state.parts[0].pose
    world = CollisionWorld(scene)
    for n in range(1, STEPS // 10 + 1):
        state, events = step(scene, world, state, S.tracker_frame(n, n * 10**9 // 60, base))
        assert not events
    assert state.parts[0].mode is Mode.ONBASESTATIC
    assert state.parts[0].pose == pose0
    assert state.parts[0].motion.angle == 0.0 and state.parts[0].motion.slide == (0.0,)


def test_cm_on_a_tilted_shaft_axis_slides_by_the_closed_form_without_turning():
    """CM on the axis, shaft tilted 30 degrees: it slides at g (sin - f_d cos) (1e-12 m),
    the angle stays exactly 0."""
    scene = S.shaft_scene(offset=(0.0, 0.0), length=4.0)
    base = tilt((0.0, 1.0, 0.0), 30.0)
    state = on_shaft(scene, base)
    th = math.radians(30.0)
    a = G * (math.sin(th) - 0.2 * math.cos(th))
    for t, s, _ in run_times(scene, state, [n * 10**9 // 60 for n in range(61)]):
        tau = t * 1e-9
        m = s.parts[0].motion
        # The tilted base's x axis (the shaft) points downhill: the slide is positive.
        assert m.slide[0] == pytest.approx(0.5 * a * tau * tau, abs=1e-12, rel=1e-12)
        assert m.angle == 0.0 and m.angle_rate == 0.0
        assert s.parts[0].angular_velocity == (0.0, 0.0, 0.0)


def test_horizontal_plane_at_rest_never_moves():
    """A block on a horizontal plane, at rest: not a bit of motion and no event in STEPS
    frames (however long, nothing creeps)."""
    from _onbase import on_base, plate_scene
    scene = plate_scene()
    base = sp.Pose((0.2, 0.1, 0.9), sp.quat_axis_angle((0, 0, 1), 0.7))
    state = on_base(scene, base, sp.Pose((0.1, -0.3, 0.04)))
    pose0 = state.parts[0].pose
    world = CollisionWorld(scene)
    for n in range(1, STEPS + 1):
        state, events = step(scene, world, state, S.tracker_frame(n, n * 10**9 // 60, base))
        assert not events
    assert state.parts[0].pose == pose0 and state.parts[0].mode is Mode.ONBASESTATIC


@pytest.mark.parametrize("offset", [(0.0, 0.0), (0.02, 0.01)], ids=["cm-on-axis", "cm-off-axis"])
def test_vertical_shaft_free_fall_without_friction_then_blocked(offset):
    """A vertical shaft: gravity is along it, so the normal load and friction are zero and
    no torque turns the disc, whatever its CM: it falls along the shaft at g exactly
    (x = -g t^2 / 2, 1e-12 m), the angle stays exactly 0, and a collar stops it between
    half the contact tolerance and the tolerance from it (ONBASESTATIC, blocked)."""
    scene = S.shaft_scene(offset=offset, axis=(0.0, 0.0, 1.0), stop=-0.1, friction=(0.5, 0.4))
    base = sp.Pose((0.0, 0.0, 1.0))
    state = on_shaft(scene, base, axis=(0.0, 0.0, 1.0))
    tol = scene.physics.contact_tolerance
    # Collar top at -0.09, disc bottom at slide - 0.005: contact at slide = -0.085.
    x_contact = -0.085
    blocked = None
    for t, s, events in run_times(scene, state, [n * 10**9 // 60 for n in range(61)]):
        part = s.parts[0]
        m = part.motion
        assert m.angle == 0.0 and m.angle_rate == 0.0
        if part.mode is Mode.ONBASESLIDE:
            tau = t * 1e-9
            assert m.slide[0] == pytest.approx(-0.5 * G * tau * tau, abs=1e-12)
            assert m.slide[0] > x_contact
        elif blocked is None:
            assert [e.cause for e in events if e.kind == "ModeChanged"] == ["blocked_by_base"]
            blocked = m.slide[0]
            assert x_contact + 0.5 * tol - 1e-9 <= blocked <= x_contact + tol + 1e-9
        else:
            assert m.slide[0] == blocked and not events
    assert blocked is not None


def _edge_sessions():
    """Session files for the edge cases, to record and replay."""
    import json
    from conftest import RECORDINGS
    out = {}
    shaft = json.loads((RECORDINGS / "shaft_slide_blocked.json").read_text())
    out["vertical_shaft_cm_on_axis"] = shaft  # a sleeve on a vertical shaft
    gear = json.loads((RECORDINGS / "gear_pendulum.json").read_text())
    gear["tracker"]["duration_s"] = 3.0
    gear["tracker"]["devices"]["left_hand"].append({"t": 1.5, "euler_deg": [0, 0, 0]})
    gear["tracker"]["devices"]["left_hand"].append({"t": 2.0, "euler_deg": [0, -90, 0]})
    out["gear_shaft_turned_vertical"] = gear
    plane = json.loads((RECORDINGS / "plane_block_wall.json").read_text())
    plane["tracker"]["devices"]["left_hand"] = plane["tracker"]["devices"]["left_hand"][:1]
    plane["tracker"]["duration_s"] = 3.0
    out["horizontal_plane"] = plane
    return out


@pytest.mark.parametrize("name", sorted(_edge_sessions()))
def test_edge_case_sessions_record_and_replay_exactly(name, tmp_path):
    """Each edge-case session (vertical shaft, a shaft turned vertical mid-swing, a block left
    on a horizontal plane) is finite, ends where it should, and replays bit for bit."""
    doc = _edge_sessions()[name]
    records = run_records(doc)
    assert_sane_records(records)
    final = records[-1].parts[0]
    if name == "horizontal_plane":
        rest = [r.parts[0] for r in records if r.parts[0].mode == "ONBASESTATIC"]
        assert len(rest) > 60
        assert all(p.position == rest[0].position for p in rest)
    elif name == "vertical_shaft_cm_on_axis":
        assert final.mode == "ONBASESTATIC"
        assert any(e.cause == "blocked_by_base" for r in records for e in r.events
                   if e.kind == "ModeChanged")
    else:
        # The shaft is turned up to vertical by 2.0 s: the gear slides down it onto the stand
        # (blocked) and, with no gravity torque about a vertical shaft, its spin decays by
        # viscous friction alone: |w| falls by exp(-f_r dt / J) a frame (1e-9 relative).
        assert any(e.cause == "blocked_by_base" for r in records for e in r.events
                   if e.kind == "ContactMade")
        mate = make_session(doc).build_scene().parts[0].assembly.mates[0]
        f_r, j = mate.rotational_friction, mate.inertia_about_axis
        # (From the frame after the turn's last: until then the recorded angular velocity,
        # a world one, has the base's turn in it too.)
        after = [r for r in records if r.time_ns > 2 * 10**9]
        assert all(r.parts[0].mode == "ONBASESLIDE" for r in after)
        for a, b in zip(after, after[1:]):
            dt = (b.time_ns - a.time_ns) * 1e-9
            wa, wb = sp.norm(a.parts[0].angular_velocity), sp.norm(b.parts[0].angular_velocity)
            assert wb == pytest.approx(wa * math.exp(-f_r * dt / j), rel=1e-9)
            assert b.parts[0].position == a.parts[0].position  # on the stand: no sliding
        assert sp.norm(after[-1].parts[0].angular_velocity) > 1.0
    record_and_replay(doc, None, tmp_path, name)


# --- 6. a long session records and replays exactly ----------------------------------------

def _long_session(seconds: int) -> tuple[dict, dict]:
    """A session of ``seconds`` at 60 Hz with three parts, as a tracker log: the gear of
    ``gear_pendulum`` is put on the shaft of the base held in the left hand, which is then
    rocked about the shaft (+-40 deg, 7 s period) so the gear keeps swinging; every 6 s the
    right hand picks a peg up from the table, lifts and twists it and lets it drop back;
    a third part lies on the table untouched."""
    import json
    from conftest import RECORDINGS
    gear_doc = json.loads((RECORDINGS / "gear_pendulum.json").read_text())
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
           "density": 2700, "pose": {"position": [-0.3, -0.2, 0.78]}}
    block = {"name": "block", "shape": {"type": "box", "size": [0.05, 0.05, 0.05]},
             "density": 2700, "pose": {"position": [-0.3, 0.25, 0.765]}}
    doc = {"format": "vade-session/1", "name": f"long_{seconds}s", "units": "m",
           "base": gear_doc["base"], "parts": [gear_doc["parts"][0], peg, block],
           "environment": gear_doc["environment"]}
    ident = sp.IDENTITY_QUAT
    gear_q = sp.quat_from_euler_deg(90, 0, 90)
    # Right-hand keyframes (t, position, rotation, grip): the gear, then the peg cycles.
    keys = [(0.0, (0.3, -0.1, 0.745), ident, False), (0.2, (0.3, -0.1, 0.745), ident, True),
            (0.8, (0.12, 0.2, 1.0), gear_q, True), (1.0, (0.12, 0.2, 1.0), gear_q, False),
            (1.2, (0.3, 0.0, 1.1), ident, False)]
    t0 = 2.0
    twist = sp.quat_axis_angle((0, 0, 1), 0.5)
    while t0 + 6.0 <= seconds:
        keys += [(t0, (-0.3, -0.2, 1.0), ident, False), (t0 + 1.0, (-0.3, -0.2, 0.79), ident, False),
                 (t0 + 1.3, (-0.3, -0.2, 0.79), ident, True),
                 (t0 + 2.3, (-0.3, -0.2, 0.95), twist, True),
                 (t0 + 2.6, (-0.3, -0.2, 0.95), twist, False),
                 (t0 + 3.5, (-0.3, -0.2, 1.0), ident, False)]
        t0 += 6.0
    times = [k[0] for k in keys]
    rows = ["time,device,x,y,z,q0,q1,q2,q3,grip", "0,head,-0.6,0.1,1.5,0,0,0,1,"]
    for n in range(seconds * 60 + 1):
        t_ns = n * 10**9 // 60
        t = t_ns * 1e-9
        i = bisect.bisect_right(times, t) - 1
        k0 = keys[i]
        if i + 1 < len(keys):
            k1 = keys[i + 1]
            a = (t - k0[0]) / (k1[0] - k0[0])
            p = tuple(x + a * (y - x) for x, y in zip(k0[1], k1[1]))
            q = sp.slerp(k0[2], k1[2], a)
        else:
            p, q = k0[1], k0[2]
        grip = k0[3]
        rock = 0.0 if t < 1.5 else math.radians(40.0) * min(1.0, (t - 1.5) / 5.0) * \
            math.sin(2.0 * math.pi * (t - 1.5) / 7.0)
        ql = sp.quat_axis_angle((1.0, 0.0, 0.0), rock)
        rows.append(f"{t_ns},left_hand,0,0.2,1.0,{ql[0]!r},{ql[1]!r},{ql[2]!r},{ql[3]!r},1")
        rows.append(f"{t_ns},right_hand,{p[0]:.9f},{p[1]:.9f},{p[2]:.9f},"
                    f"{q[0]:.12f},{q[1]:.12f},{q[2]:.12f},{q[3]:.12f},{int(grip)}")
    return S.csv_session(doc, "\n".join(rows) + "\n")


def test_long_session_records_and_replays_exactly(tmp_path):
    """SESSION_S seconds (60 s in CI, an hour in full) at 60 Hz, three parts: every frame
    is finite, the recording replays bit for bit, and the activity really happened all along
    (a grab, a release and a landing of the peg every 6 s; the gear swinging to the end)."""
    doc, files = _long_session(SESSION_S)
    session = make_session(doc, files)
    out = tmp_path / "long.mcap"
    last = {}

    def check(rec):
        for snap in rec.parts:
            assert_sane_snapshot(snap)
        last["rec"] = rec
    recorded = record(session, out, on_frame=check)
    assert recorded.frames == SESSION_S * 60 + 1
    cycles = (SESSION_S - 2) // 6
    edges = recorded.transitions_by_edge
    assert edges.get("STATIC->INHAND", 0) >= cycles + 1      # the gear once, the peg each cycle
    assert edges.get("INHAND->INSPACE", 0) >= cycles
    assert edges.get("INSPACE->STATIC", 0) >= cycles
    final = {p.name: p for p in last["rec"].parts}
    assert final["gear"].mode == "ONBASESLIDE" and sp.norm(final["gear"].angular_velocity) > 0.0
    assert final["block"].position == (-0.3, 0.25, 0.765)
    assert "numerical_fault" not in str(edges)

    replayed = replay(Recording(out), on_frame=lambda item: None)
    assert replayed.match, replayed.first_divergence
    assert replayed.frames == recorded.frames
    assert replayed.transitions_by_edge == edges
