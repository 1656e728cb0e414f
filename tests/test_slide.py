"""Sliding on the base against closed forms (paper 5.2, NOTES.md)."""

from __future__ import annotations

import math

import pytest

from _onbase import G, on_base, plate_scene, run, tilt_x
from vade_replay import spatial as sp
from vade_replay.collision import CollisionWorld
from vade_replay.dynamics import onbase
from vade_replay.modes import Mode

FS, FD = 0.3, 0.2


def _downhill(theta_deg: float) -> sp.Vec3:
    # Base tilted by theta about world x: its +y axis points downhill.
    return sp.quat_rotate(tilt_x(theta_deg).rotation, (0.0, 1.0, 0.0))


def test_block_on_fixed_incline_matches_closed_form():
    theta = -20.0  # tan 20 deg = 0.364 > f_s = 0.3: it slides
    scene = plate_scene()
    base = tilt_x(theta)
    state = on_base(scene, base, sp.Pose((0.0, -0.8, 0.04)))
    start = state.parts[0].pose.position
    th = math.radians(abs(theta))
    a = G * (math.sin(th) - FD * math.cos(th))
    down = _downhill(theta)
    worst = 0.0
    for n, state, _ in run(scene, state, 60):
        t = state.time_ns * 1e-9
        expected = sp.add(start, sp.scale(down, 0.5 * a * t * t))
        worst = max(worst, sp.norm(sp.sub(state.parts[0].pose.position, expected)))
        assert state.parts[0].mode is Mode.ONBASESLIDE
    assert worst < 1e-9, worst
    assert 0.5 * a * 1.0 > 0.7  # it really went somewhere (0.755 m in 1 s)


def test_below_friction_angle_never_creeps():
    scene = plate_scene()
    base = tilt_x(-15.0)  # tan 15 deg = 0.268 < f_s
    state = on_base(scene, base, sp.Pose((0.0, 0.0, 0.04)))
    pose0 = state.parts[0].pose
    for n, state, events in run(scene, state, 60 * 60):
        assert not events
    part = state.parts[0]
    assert part.mode is Mode.ONBASESTATIC
    assert part.motion.slide == (0.0, 0.0)
    assert part.pose == pose0


def test_friction_stops_a_sliding_block_and_it_stays_stopped():
    scene = plate_scene()
    v0 = 0.5
    state = on_base(scene, sp.Pose((0.0, 0.0, 1.0)), sp.Pose((0.0, -0.5, 0.04)),
                    mode=Mode.ONBASESLIDE, slide_rate=(v0, 0.0))
    decel = FD * G
    t_stop = v0 / decel
    stopped_at = None
    for n, state, events in run(scene, state, 120):
        t = state.time_ns * 1e-9
        x = state.parts[0].motion.slide[0]
        if t < t_stop:
            assert x == pytest.approx(v0 * t - 0.5 * decel * t * t, abs=1e-12)
        else:
            assert x == pytest.approx(v0 * v0 / (2.0 * decel), abs=1e-12)
        if any(e.kind == "ModeChanged" for e in events):
            assert stopped_at is None
            assert [e.cause for e in events] == ["held_by_friction"]
            stopped_at = t
    assert stopped_at is not None and 0.0 <= stopped_at - t_stop < 1.0 / 60.0
    assert state.parts[0].mode is Mode.ONBASESTATIC


def test_friction_never_reverses_motion_uphill():
    """Pushed uphill below the friction angle: it slows by g (sin + f_d cos), stops, stays."""
    scene = plate_scene()
    base = tilt_x(-10.0)
    v0 = -0.6  # uphill (downhill is +y)
    state = on_base(scene, base, sp.Pose((0.0, 0.3, 0.04)), mode=Mode.ONBASESLIDE,
                    slide_rate=(v0, 0.0))
    th = math.radians(10.0)
    decel = G * (math.sin(th) + FD * math.cos(th))
    x_stop = -v0 * v0 / (2.0 * decel)
    # The plane's slide basis for normal +z is (base y, -base x).
    lowest = 0.0
    for n, state, _ in run(scene, state, 90):
        lowest = min(lowest, state.parts[0].motion.slide[0])
    assert lowest == pytest.approx(x_stop, abs=1e-12)
    assert state.parts[0].motion.slide == (pytest.approx(x_stop, abs=1e-12), 0.0)
    assert state.parts[0].mode is Mode.ONBASESTATIC


def test_base_turned_upside_down_drops_the_part():
    """Turned over in one frame: as the plane passes vertical the normal load vanishes, so
    static friction gives way just before gravity pulls the part off, both within the
    frame (``slide_off: frame_end``, before 2026-11-22: lifted from rest at the frame's end)."""
    for physics, expected in (
            ({}, [("ONBASESTATIC", "ONBASESLIDE", "static_friction_exceeded"),
                  ("ONBASESLIDE", "INSPACE", "gravity_lifts_off")]),
            ({"slide_off": "frame_end"}, [("ONBASESTATIC", "INSPACE", "gravity_lifts_off")])):
        scene = plate_scene(physics)
        state = on_base(scene, tilt_x(0.0), sp.Pose((0.0, 0.0, 0.04)))
        record = list(run(scene, state, 3, left=lambda n: tilt_x(180.0)))
        first_events = record[0][2]
        assert [(e.from_mode, e.to_mode, e.cause) for e in first_events] == expected
        assert record[-1][1].parts[0].mode is Mode.INSPACE


def test_paper_slide_model_is_selectable():
    scene = plate_scene({"model": "paper"})
    assert scene.physics.slide_integrator == "paper"
    base = tilt_x(-20.0)
    state = on_base(scene, base, sp.Pose((0.0, -0.8, 0.04)))
    *_, (n, state, _) = run(scene, state, 30)
    # Eq. 4 is exact for a constant acceleration too.
    th = math.radians(20.0)
    a = G * (math.sin(th) - FD * math.cos(th))
    t = state.time_ns * 1e-9
    assert math.hypot(*state.parts[0].motion.slide) == pytest.approx(0.5 * a * t * t, rel=1e-6)


# --- a plane with the velocity across the slope: the friction direction turns -------------

def _coulomb_reference(gt_of_t, n_of_t, fd, v0, t_end, t_eval):
    """DOP853 (rtol 1e-12) on x' = v, v' = g_t(t) - f_d N(t) v/|v|, stopped at zero speed.

    ``|v|`` touches zero without changing sign, so the terminal event is at 1e-9 m/s: the
    part still moves ``|v|^2 / (2 (f_d N - |g_t|))`` < 1e-17 m after it."""
    from scipy.integrate import solve_ivp

    def rhs(t, y):
        s = math.hypot(y[2], y[3])
        gt, c = gt_of_t(t), fd * n_of_t(t)
        return [y[2], y[3], gt[0] - c * y[2] / s, gt[1] - c * y[3] / s]

    def stop(t, y):
        return math.hypot(y[2], y[3]) - 1e-9
    stop.terminal = True
    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0, *v0], method="DOP853", rtol=1e-12,
                    atol=1e-15, events=stop, dense_output=True)
    t_stop = sol.t_events[0][0] if sol.t_events[0].size else None

    def x_at(t):
        y = sol.sol(min(t, sol.t[-1]))
        return float(y[0]), float(y[1])
    return [x_at(t) for t in t_eval], t_stop


def _still_incline(theta_deg, size=(8.0, 8.0, 0.04)):
    scene = plate_scene(size=size)
    base = tilt_x(theta_deg)
    mate = scene.parts[0].assembly.mates[0]
    g = sp.quat_rotate(sp.quat_conj(base.rotation), scene.physics.gravity_slide)
    gt = onbase.tangential(mate.slide_dirs, g)
    n_load, _ = onbase.normal_load(mate.kind, mate.base_dirs, None, g)
    return scene, base, gt, n_load


def test_across_a_still_incline_matches_a_dop853_reference():
    """30 degrees, f_d 0.2, 1 m/s across the slope, 60 Hz, 1/240 s sub-steps: the friction
    direction turns as the part turns downhill. The ``midpoint`` scheme was 2.7e-3 m off."""
    scene, base, gt, n_load = _still_incline(-30.0)
    v0 = (0.0, 1.0)  # the slide basis is (base y = downhill, -base x = across)
    assert abs(gt[1]) < 1e-12 and gt[0] > 4.0
    state = on_base(scene, base, sp.Pose((0.0, -2.0, 0.04)), mode=Mode.ONBASESLIDE,
                    slide_rate=v0)
    record = list(run(scene, state, 60))
    times = [s.time_ns * 1e-9 for _, s, _ in record]
    ref, t_stop = _coulomb_reference(lambda t: gt, lambda t: n_load, FD, v0, 1.0, times)
    assert t_stop is None
    worst = max(math.dist(s.parts[0].motion.slide, r) for (_, s, _), r in zip(record, ref))
    assert worst < 1e-7, worst
    assert record[-1][1].parts[0].mode is Mode.ONBASESLIDE
    assert math.dist(record[-1][1].parts[0].motion.slide, (0.0, 0.0)) > 1.5  # it went far


def test_across_a_shallow_incline_stops_where_the_reference_stops_and_stays():
    """10 degrees (tan 10 < f_d): the part turns downhill, slows, stops at t = 0.698 s on the
    reference's stop point, and static friction holds it. It never moves backwards."""
    scene, base, gt, n_load = _still_incline(-10.0)
    v0 = (0.0, 0.3)
    state = on_base(scene, base, sp.Pose((0.0, 0.0, 0.04)), mode=Mode.ONBASESLIDE,
                    slide_rate=v0)
    record = list(run(scene, state, 90))
    times = [s.time_ns * 1e-9 for _, s, _ in record]
    ref, t_stop = _coulomb_reference(lambda t: gt, lambda t: n_load, FD, v0, 1.5, times)
    assert t_stop == pytest.approx(0.6978, abs=1e-4)
    worst = max(math.dist(s.parts[0].motion.slide, r) for (_, s, _), r in zip(record, ref))
    assert worst < 1e-7, worst
    stopped_at, prev_v, prev_speed = None, v0, math.hypot(*v0)
    for (n, s, events), t in zip(record, times):
        v = s.parts[0].motion.slide_rate
        speed = math.hypot(*v)
        assert speed <= prev_speed and v[0] * prev_v[0] + v[1] * prev_v[1] >= 0.0
        prev_v, prev_speed = v, speed
        if events:
            assert stopped_at is None and [e.cause for e in events] == ["held_by_friction"]
            stopped_at = t
    assert 0.0 <= stopped_at - t_stop < 1.0 / 60.0
    at_stop = [s.parts[0].pose for _, s, _ in record if s.time_ns * 1e-9 >= stopped_at]
    assert all(p == at_stop[0] for p in at_stop)
    assert record[-1][1].parts[0].mode is Mode.ONBASESTATIC
    assert record[-1][1].parts[0].motion.slide_rate == (0.0, 0.0)


def _plane_dirs():
    """The plate's slide basis in base axes (normal +z): (base y, -base x)."""
    return plate_scene().parts[0].assembly.mates[0].slide_dirs


def _slide_frames(path_of_frame, v0, steps, integrator, frames=60, fd=FD):
    """``onbase.slide`` over ``frames`` 60 Hz frames on the plate's plane."""
    dirs = _plane_dirs()
    x, v = (0.0, 0.0), v0
    for k in range(frames):
        x, v = onbase.slide("plane", ((0.0, 0.0, 1.0),), None, dirs, path_of_frame(k), x, v,
                            1.0 / 60.0, steps, f_static=FS, f_dynamic=fd, blocked=(),
                            integrator=integrator)
    return x, v


def _turning_base(rate):
    """Tilted 30 degrees about x and turning about its own normal at ``rate`` rad/s."""
    def q(t):
        return sp.quat_mul(sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(30.0)),
                           sp.quat_axis_angle((0.0, 0.0, 1.0), rate * t))

    def g(t):
        return sp.quat_rotate(sp.quat_conj(q(t)), (0.0, 0.0, -G))

    def path(k):
        return onbase.GravityPath((0.0, 0.0, -G), q(k / 60.0), q((k + 1) / 60.0))
    dirs = _plane_dirs()
    return path, (lambda t: onbase.tangential(dirs, g(t))), (lambda t: -g(t)[2])


def _turning_errors(rate, v0, integrator, steps):
    """Distances from DOP853 after 1 s on the plane turning at ``rate``, at each sub-step
    count, and that of ``analytic`` at one sub-step a frame."""
    turning, gt_turn, n_turn = _turning_base(rate)
    ref = _coulomb_reference(gt_turn, n_turn, FD, v0, 1.0, [1.0])[0][0]
    errors = [math.dist(_slide_frames(turning, v0, s, integrator)[0], ref) for s in steps]
    return errors, math.dist(_slide_frames(turning, v0, 1, "analytic")[0], ref)


def _assert_each_halving_divides_by(errors, factor, tolerance):
    for coarse, fine in zip(errors, errors[1:]):
        assert abs(coarse / fine / factor - 1.0) < tolerance, errors


def test_plane_sliding_order_exact_on_a_still_base_second_order_while_it_turns():
    """Halving the sub-step: under a still base the error is round-off at any sub-step;
    while the base turns (1 rad/s about its normal) it falls 4x (gravity is held at the
    sub-step's mid time); the frozen friction direction of ``midpoint`` falls only 2x."""
    v0 = (0.0, 1.0)
    still, gt_still, n_still = _turning_base(0.0)
    ref_still = _coulomb_reference(gt_still, n_still, FD, v0, 1.0, [1.0])[0][0]
    for steps in (1, 4):
        assert math.dist(_slide_frames(still, v0, steps, "analytic")[0], ref_still) < 1e-11
    e_mid = [math.dist(_slide_frames(still, v0, s, "midpoint")[0], ref_still) for s in (4, 8)]
    assert e_mid[0] == pytest.approx(2.7e-3, rel=0.05)
    assert 1.9 < e_mid[0] / e_mid[1] < 2.1
    errors, _ = _turning_errors(1.0, v0, "analytic", (4, 8, 16))
    assert errors[0] < 1e-5
    _assert_each_halving_divides_by(errors, 4.0, 0.05)


@pytest.mark.parametrize("rate", [1.0, 5.0])
def test_analytic4_is_fourth_order_while_the_base_turns_and_exact_on_a_still_one(rate):
    """The commutator-free scheme (two exact flows a sub-step under gravity combined from
    the Gauss nodes): round-off on a still base, and while the base turns at 1 or 5 rad/s
    the error against DOP853 falls 16x a halving, ~1e-8 m at one sub-step a frame (60 Hz),
    where ``analytic`` (gravity held at mid sub-step) is ~1e-4 m."""
    v0 = (0.0, 1.0)
    still, gt_still, n_still = _turning_base(0.0)
    ref_still = _coulomb_reference(gt_still, n_still, FD, v0, 1.0, [1.0])[0][0]
    for steps in (1, 3):
        assert math.dist(_slide_frames(still, v0, steps, "analytic4")[0], ref_still) < 1e-11
    errors, coarse_analytic = _turning_errors(rate, v0, "analytic4", (1, 2, 4))
    assert errors[0] < 3e-8
    _assert_each_halving_divides_by(errors, 16.0, 0.125)
    assert coarse_analytic > 1e3 * errors[0]


def _tilting_through_the_friction_angle(th0_deg=10.0, omega=0.5):
    """A plane tilted about base x at ``omega`` rad/s from ``th0_deg``: a part at rest on it
    slips at tan(theta*) = f_s and slides down its +y, ``s'' = g (sin - f_d cos)``, in closed
    form from the onset."""
    th0, th_on = math.radians(th0_deg), math.atan(FS)
    t_on = (th_on - th0) / omega

    def q(t):
        return sp.quat_axis_angle((1.0, 0.0, 0.0), -(th0 + omega * t))

    def path(k):
        return onbase.GravityPath((0.0, 0.0, -G), q(k / 60.0), q((k + 1) / 60.0))

    def exact(t):
        th = th0 + omega * max(t, t_on)
        f_on = -math.cos(th_on) - FD * math.sin(th_on)
        return G / omega ** 2 * ((-math.sin(th) + FD * math.cos(th))
                                 - (-math.sin(th_on) + FD * math.cos(th_on))
                                 - f_on * (th - th_on))
    return path, exact, t_on


def test_the_onset_of_slipping_is_found_within_the_sub_step():
    """Static friction gives way at an instant between sub-steps (here 0.234 s); the slide
    starts there, not at a sub-step's edge, so each scheme keeps its order: analytic4 ~1e-10 m
    after 1 s at one sub-step a frame and 16x less a halving, analytic 4x. An onset rounded to
    the sub-step would leave both first order, ~1e-3 m at 1/60 s."""
    path, exact, t_on = _tilting_through_the_friction_angle()
    assert 0.2 < t_on < 0.25
    ref = exact(1.0)
    errors = {i: [abs(_slide_frames(path, (0.0, 0.0), s, i)[0][0] - ref) for s in (1, 2, 4)]
              for i in ("analytic4", "analytic")}
    assert errors["analytic4"][0] < 1e-9
    for name, order in (("analytic4", 4), ("analytic", 2)):
        for coarse, fine in zip(errors[name], errors[name][1:]):
            assert 0.85 * 2 ** order < coarse / fine < 1.15 * 2 ** order, (name, errors)
    # At rest before the onset, exactly.
    x, v = _slide_frames(path, (0.0, 0.0), 1, "analytic4", frames=14)
    assert x == (0.0, 0.0) and v == (0.0, 0.0)
    x, v = _slide_frames(path, (0.0, 0.0), 1, "analytic4", frames=15)
    assert abs(x[0] - exact(0.25)) < 1e-11 and x[1] == 0.0 and v[0] > 0.0


def test_a_stop_while_the_base_turns_keeps_analytic4_fourth_order():
    """Friction stops the part (5 degree plane, 0.3 m/s across it, the base turning at
    2 rad/s about its normal) at 0.203 s, inside a sub-step: the instant is bisected on the
    whole scheme, not taken from one half-flow (whose combined gravity is only right with
    the other's), so the error still falls 16x a halving (a review measured 8x before)."""
    def q(t):
        return sp.quat_mul(sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(5.0)),
                           sp.quat_axis_angle((0.0, 0.0, 1.0), 2.0 * t))

    def g(t):
        return sp.quat_rotate(sp.quat_conj(q(t)), (0.0, 0.0, -G))

    def path(k):
        return onbase.GravityPath((0.0, 0.0, -G), q(k / 60.0), q((k + 1) / 60.0))
    dirs = _plane_dirs()
    v0 = (0.0, 0.3)
    (ref,), t_stop = _coulomb_reference(lambda t: onbase.tangential(dirs, g(t)),
                                        lambda t: -g(t)[2], FD, v0, 1.0, [1.0])
    assert 0.19 < t_stop < 0.21
    results = [_slide_frames(path, v0, s, "analytic4") for s in (1, 2, 4, 8)]
    assert all(v == (0.0, 0.0) for _, v in results)  # it stays where it stopped
    errors = [math.dist(x, ref) for x, _ in results]
    assert errors[0] < 1e-9
    for coarse, fine in zip(errors, errors[1:]):
        assert 13.0 < coarse / fine < 19.0, errors


def test_along_the_slope_and_on_an_axis_the_schemes_agree_bit_for_bit():
    """Velocity along g_t (from rest, base tilting about a horizontal axis) and any axis:
    ``analytic`` is the constant-acceleration update of ``midpoint``, to the last bit."""
    def q(t):
        return sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(25.0) + 0.5 * t)

    def path(k):
        return onbase.GravityPath((0.0, 0.0, -G), q(k / 60.0), q((k + 1) / 60.0))
    for v0 in ((0.0, 0.0), (-0.4, 0.0), (0.7, 0.0)):
        assert _slide_frames(path, v0, 4, "analytic") == _slide_frames(path, v0, 4, "midpoint")
    axis = ((0.0, 1.0, 0.0),)
    for v0 in ((0.0,), (-0.5,), (0.8,)):
        out = [onbase.slide("axis", axis, axis[0], axis, path(3), v0, v0, 1.0 / 60.0, 4,
                            f_static=FS, f_dynamic=FD, blocked=(), integrator=i)
               for i in ("analytic", "midpoint")]
        assert out[0] == out[1]


def test_a_part_slides_off_the_edge_at_the_instant_it_crosses_it():
    """A cube sliding at 1 m/s (f_d 0.2) towards the edge of a still plate leaves it when
    its centre of mass passes the edge by the contact tolerance, at 0.1125 s, mid-frame:
    from that instant it flies (gravity x 0.25) in closed form. The instant is found within
    the frame; decided at the frame's end, the part started to fall up to a frame late
    (5 mm off here)."""
    scene = plate_scene()
    tol = scene.physics.contact_tolerance
    a, gf = FD * G, 0.25 * G
    t_off = (1.0 - math.sqrt(1.0 - 2.0 * a * (0.1 + tol))) / a
    v_off = 1.0 - a * t_off
    assert 6 < t_off * 60 < 7

    def worst_error(scene):
        base = sp.Pose((0.0, 0.0, 1.0), sp.IDENTITY_QUAT)
        state = on_base(scene, base, sp.Pose((0.0, 0.9, 0.04), sp.IDENTITY_QUAT),
                        mode=Mode.ONBASESLIDE, slide_rate=(1.0, 0.0))
        z0 = state.parts[0].pose.apply(scene.parts[0].center_of_mass)[2]
        worst, flying = 0.0, 0
        for n, s, events in run(scene, state, 30):
            part = s.parts[0]
            if part.mode is not Mode.INSPACE:
                assert n / 60 < t_off
                continue
            flying += 1
            t = n / 60 - t_off
            cm = part.pose.apply(scene.parts[0].center_of_mass)
            expected = (0.0, 1.0 + tol + v_off * t, z0 - 0.5 * gf * t * t)
            worst = max(worst, math.dist(cm, expected))
        assert flying == 24
        return worst
    assert worst_error(scene) < 1e-8
    assert worst_error(plate_scene({"slide_off": "frame_end"})) > 1e-3


def test_off_a_turning_moving_base_with_the_bases_velocity_at_that_instant():
    """The plate turns at 2 rad/s about its normal and moves at 0.1 m/s while the cube
    slides off: after 0.5 s the cube is where a run of the same motion tracked at 3840 Hz
    (sub-steps 1/1920 s) has it. Leaving with the base's average velocity over the frame
    instead of its velocity at the instant was 6.7 mm off (a review); leaving at the
    frame's end is 7 mm off."""

    def base(t):
        return sp.Pose((0.1 * t, 0.0, 1.0), sp.quat_axis_angle((0.0, 0.0, 1.0), 2.0 * t))

    def final_cm(rate, physics):
        scene = plate_scene(physics)
        for _, state, _ in _tracked(scene, base, sp.Pose((0.0, 0.9, 0.04), sp.IDENTITY_QUAT),
                                    (1.0, 0.0), rate, 0.5):
            pass
        assert state.parts[0].mode is Mode.INSPACE
        return state.parts[0].pose.apply(scene.parts[0].center_of_mass)
    reference = final_cm(3840, {"slide_max_step_s": 1 / 1920})
    assert math.dist(final_cm(60, {}), reference) < 1e-8
    assert math.dist(final_cm(60, {"slide_off": "frame_end"}), reference) > 3e-3


def test_a_sliding_part_lifts_off_when_the_plane_turns_past_vertical():
    """The plate turns about its long axis at 2.2 degrees a frame (132 deg/s) while the
    cube slides on it: when the plane passes vertical (mid-frame 41) gravity pulls the cube
    off, and it flies from that instant. After 1 s it is within 1e-8 m of the same motion
    tracked at 3840 Hz. Before, a sliding part (unlike a resting one) was never lifted off: it
    hung under the plate until it slid off an edge (``slide_off: frame_end`` keeps that)."""
    part, lifted_at, cm = _turned_over(60, {}, (0.3, 0.2), (0.2, 0.0))
    assert lifted_at == 41 and part.mode is Mode.INSPACE
    _, _, reference = _turned_over(3840, {"slide_max_step_s": 1 / 1920}, (0.3, 0.2), (0.2, 0.0))
    assert math.dist(cm, reference) < 1e-8
    _, never, glued = _turned_over(60, {"slide_off": "frame_end"}, (0.3, 0.2), (0.2, 0.0))
    assert never is None and math.dist(glued, cm) > 0.1


def test_a_resting_part_lifts_off_at_the_instant_too():
    """The same plate turned past vertical with the cube at rest on it (f_s 1000: held until
    the normal load all but vanishes): static friction gives way at 89.94 degrees and the
    cube slips for 0.45 ms before gravity pulls it off at 90, both within frame 41, and the
    slide up to the lift is integrated, not interpolated: after 1 s it is within 1e-8 m of
    the motion tracked at 3840 Hz. Lifted from rest at the frame's end, it missed the slip
    (4.5 mm/s) and started late: 2.6 mm off."""
    _, lifted_at, cm = _turned_over(60, {}, (1000.0, 0.2), (0.0, 0.0))
    assert lifted_at == 41
    _, _, reference = _turned_over(3840, {"slide_max_step_s": 1 / 1920}, (1000.0, 0.2),
                                   (0.0, 0.0))
    assert math.dist(cm, reference) < 1e-8
    _, late_at, late = _turned_over(60, {"slide_off": "frame_end"}, (1000.0, 0.2), (0.0, 0.0))
    assert late_at == 41 and math.dist(late, reference) > 1e-3


def test_an_edge_or_a_wall_before_the_lift_comes_first():
    """Found by a review: the lift was decided before the frame's other events. A cube
    sliding fast (no friction) on a plate turning about base y crosses the edge mid-frame
    41, before the plane passes vertical in that frame: it slides off (and lands where the
    motion tracked at 3840 Hz has it, within 1e-6 m), not lifts off. And a cube that hits
    the plate's wall in the frame the plate turns over is stopped there, not carried
    through the wall to where it would lift."""
    def base(t):
        return sp.Pose((0.0, 0.0, 1.0),
                       sp.quat_axis_angle((0.0, 1.0, 0.0), math.radians(132.0 * t)))

    def run_edge(rate):
        scene = plate_scene({}, size=(8.0, 2.0, 0.04), friction=(0.0, 0.0))
        causes = []
        for n, state, events in _tracked(scene, base, sp.Pose((0.0, 0.0, 0.04)),
                                         (1.0 / 0.6775, 0.0), rate, 1.0):
            causes += [(n, e.cause) for e in events]
        return state.parts[0].pose.apply(scene.parts[0].center_of_mass), causes
    cm, causes = run_edge(60)
    assert causes == [(41, "slid_off_base")]
    reference, _ = run_edge(3840)
    assert math.dist(cm, reference) < 1e-6

    def over(t):
        return sp.Pose((0.0, 0.0, 1.0), sp.quat_axis_angle((0.0, 1.0, 0.0),
                                                           math.radians(120.0 if t > 0 else 0.0)))
    scene = plate_scene({}, wall=True)
    world = CollisionWorld(scene)
    frames = list(_tracked(scene, over, sp.Pose((0.0, 0.93, 0.04)), (3.0, 0.0), 60, 3 / 60))
    first = [e.cause for e in frames[0][2]]
    assert first == ["blocked_by_base"], first
    for _, state, _ in frames:
        rel = state.base_pose.inverse().compose(state.parts[0].pose)
        assert world.distance_to_base("cube", rel) >= -1e-12  # never inside the wall
    assert frames[-1][1].parts[0].mode is Mode.INSPACE  # then it lifts off


def _turned_over(rate, physics, friction, slide_rate):
    """The cube on an 8 m plate turned about its long axis at 132 deg/s, tracked at ``rate``
    Hz for 1 s: its final state, the frame gravity lifted it off in, its final CM."""
    def base(t):
        return sp.Pose((0.0, 0.0, 1.0),
                       sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(132.0 * t)))
    scene = plate_scene(physics, size=(0.6, 8.0, 0.04), friction=friction)
    lifted_at = None
    for n, state, events in _tracked(scene, base, sp.Pose((0.0, 0.0, 0.04), sp.IDENTITY_QUAT),
                                     slide_rate, rate, 1.0):
        if any(e.cause == "gravity_lifts_off" for e in events):
            lifted_at = n
    part = state.parts[0]
    return part, lifted_at, part.pose.apply(scene.parts[0].center_of_mass)


def _tracked(scene, base, rel, slide_rate, rate, seconds):
    """The cube sliding from ``rel`` on the plate held at ``base(t)``, tracked at ``rate`` Hz:
    (frame, state, events) each frame."""
    from vade_replay.frames import DeviceSample, TrackerFrame
    from vade_replay.step import LEFT, RIGHT, step
    state = on_base(scene, base(0.0), rel, mode=Mode.ONBASESLIDE, slide_rate=slide_rate)
    world = CollisionWorld(scene)
    for n in range(1, round(rate * seconds) + 1):
        t_ns = n * 10**9 // rate
        b = base(t_ns * 1e-9)
        inputs = TrackerFrame(n, t_ns, ((LEFT, DeviceSample(b.position, b.rotation, True)),
                                        (RIGHT, DeviceSample((5.0, 5.0, 5.0), sp.IDENTITY_QUAT,
                                                             False))))
        state, events = step(scene, world, state, inputs)
        yield n, state, events



# --- the static test's edges (a test audit: no physics test told these apart) -------------

@pytest.mark.parametrize("physics", [{}, {"slide_onset": "sub_step"},
                                     {"slide_integrator": "euler"},
                                     {"slide_integrator": "midpoint", "slide_onset": "sub_step"}])
def test_dynamic_friction_above_static_never_drives_a_resting_part_uphill(physics):
    """tan(14 deg) = 0.249 lies between f_s = 0.2 and f_d = 0.3: static friction is beaten,
    but dynamic friction is more than gravity's pull along the plane, so the part at rest
    does not move (it would slide uphill: friction reversing a motion never begun)."""
    scene = plate_scene(physics, friction=(0.2, 0.3))
    state = on_base(scene, tilt_x(-14.0), sp.Pose((0.0, 0.0, 0.04)))
    for n, s, _ in run(scene, state, 60):
        assert s.parts[0].motion.slide == (0.0, 0.0), (n, s.parts[0].motion.slide)


def test_a_frictionless_level_plane_holds_a_resting_part_static():
    """|g_t| = 0 is not more than f_s N = 0: the static test is strict (|g_t| > f_s N), so a
    part at rest on a level frictionless plane stays ONBASESTATIC, no event."""
    scene = plate_scene(friction=(0.0, 0.0))
    state = on_base(scene, tilt_x(0.0), sp.Pose((0.0, 0.0, 0.04)))
    for n, s, events in run(scene, state, 30):
        assert not events, events
        assert s.parts[0].mode is Mode.ONBASESTATIC
