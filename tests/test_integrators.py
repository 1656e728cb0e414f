"""The benchmark's extra integrators: each has the order it claims, against closed forms and
DOP853 references, and each is selectable from a session like the others.

- turning, ``euler`` (semi-implicit): order 1, and symplectic: the undamped pendulum's energy
  error stays bounded instead of drifting;
- sliding, ``euler`` (semi-implicit): order 1 (exactly ``a h t / 2`` behind the closed form
  under constant acceleration); friction stops it but never reverses it;
- free rotation, ``rk4``: order 4; ``euler`` (semi-implicit): order 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import make_session, run_records, session_doc
from vade_replay import spatial as sp
from vade_replay.dynamics import free, onbase
from vade_replay.scene import Physics

G = 9.8

# --- turning: issue 5's gear pendulum, released 60 degrees from hanging -------------------

MASS, OFFSET, J_CM, F_R = 0.2, 0.03, 1e-4, 2e-4
J = J_CM + MASS * OFFSET ** 2
R0 = (0.0, OFFSET * math.sin(math.pi / 3), -OFFSET * math.cos(math.pi / 3))
STILL = onbase.GravityPath((0.0, 0.0, -G), sp.IDENTITY_QUAT, sp.IDENTITY_QUAT)


def _gear_reference(damping: float, times: np.ndarray) -> np.ndarray:
    """theta'' = (m/J) (r(theta) x g) . x - (f_r/J) theta', r by Rodrigues about x."""
    r0 = np.array(R0)

    def rhs(_, y):
        c, s = math.cos(y[0]), math.sin(y[0])
        r = np.array([0.0, r0[1] * c - r0[2] * s, r0[1] * s + r0[2] * c])
        return [y[1], (MASS * np.cross(r, [0.0, 0.0, -G])[0] - damping * y[1]) / J]
    sol = solve_ivp(rhs, (0.0, float(times[-1])), [0.0, 0.0], method="DOP853", t_eval=times,
                    rtol=1e-13, atol=1e-15)
    return sol.y[0]


def _swing(integrator: str, steps: int, seconds: float, damping: float):
    force = onbase.TurnForce(STILL, (1.0, 0.0, 0.0), R0, MASS, J, damping)
    theta, omega, out = 0.0, 0.0, []
    for _ in range(round(seconds * 60)):
        theta, omega = onbase.turn(force, theta, omega, 1.0 / 60.0, steps, integrator)
        out.append((theta, omega))
    return np.array(out)


def test_turn_euler_is_first_order_against_dop853():
    times = np.arange(1, 61) / 60.0
    ref = _gear_reference(F_R, times)
    errors = [np.max(np.abs(_swing("euler", n, 1.0, F_R)[:, 0] - ref)) for n in (16, 32, 64)]
    assert errors[0] < 1e-2
    for coarse, fine in zip(errors, errors[1:]):
        assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.15), errors


def test_turn_euler_is_symplectic_its_energy_error_does_not_drift():
    path = _swing("euler", 4, 60.0, 0.0)
    theta, omega = path[:, 0], path[:, 1]
    # E = J w^2 / 2 - m r(theta) . g, from the release at rest.
    height = R0[1] * np.sin(theta) + R0[2] * np.cos(theta)
    energy = 0.5 * J * omega ** 2 + MASS * G * height
    scale = MASS * G * OFFSET * 0.5
    error = np.abs(energy - MASS * G * R0[2]) / scale
    first, last = error[:600].max(), error[-600:].max()
    assert 1e-3 < first < 0.1                    # first order: visible, bounded
    assert last < 1.2 * first                    # and no drift over 60 s


def test_turn_euler_with_exact_decay_is_stable_where_stiff_damping_is_large():
    """``w e^{-c h}``: a huge friction takes the old rate away instead of reversing it
    hundreds of times over (``w (1 - c h)`` would be -2970 rad/s); the kick remains."""
    force = onbase.TurnForce(STILL, (1.0, 0.0, 0.0), R0, MASS, J, 10.0)  # c h = 595
    theta, omega = onbase.turn(force, 0.0, 5.0, 1.0 / 60.0, 1, "euler")
    kick = force.alpha(0.0, 0.0) / 60.0
    assert omega == pytest.approx(kick, rel=1e-12) and theta == pytest.approx(kick / 60.0)


# --- sliding ------------------------------------------------------------------------------

FS, FD = 0.3, 0.2
AXIS = ((0.0, 1.0, 0.0),)


def _tilted(deg: float) -> onbase.GravityPath:
    q = sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(-deg))
    return onbase.GravityPath((0.0, 0.0, -G), q, q)


def _slide(kind, dirs, path, v0, steps, seconds, integrator="euler"):
    normals = AXIS if kind == "axis" else ((0.0, 0.0, 1.0),)
    axis = AXIS[0] if kind == "axis" else None
    x, v, out = tuple(0.0 for _ in dirs), v0, []
    for _ in range(round(seconds * 60)):
        x, v = onbase.slide(kind, normals, axis, dirs, path, x, v, 1.0 / 60.0, steps,
                            f_static=FS, f_dynamic=FD, blocked=(), integrator=integrator)
        out.append((x, v))
    return out


def test_slide_euler_is_first_order_on_the_closed_form():
    th = math.radians(20.0)
    a = G * (math.sin(th) - FD * math.cos(th))
    for steps in (1, 4, 16):
        h = 1.0 / (60 * steps)
        x, _ = _slide("axis", AXIS, _tilted(20.0), (0.0,), steps, 1.0)[-1]
        # Semi-implicit Euler under constant a: x_n = a h^2 n (n + 1) / 2 = a t^2/2 + a h t/2.
        assert x[0] - 0.5 * a == pytest.approx(0.5 * a * h, rel=1e-9)


def _coulomb_reference(gt, n_load, v0, times):
    def rhs(_, y):
        s = math.hypot(y[2], y[3])
        return [y[2], y[3], gt[0] - FD * n_load * y[2] / s, gt[1] - FD * n_load * y[3] / s]
    sol = solve_ivp(rhs, (0.0, float(times[-1])), [0.0, 0.0, *v0], method="DOP853",
                    t_eval=times, rtol=1e-12, atol=1e-15)
    return sol.y[:2].T


def test_slide_euler_is_first_order_across_a_slope_against_dop853():
    dirs = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0))
    path = _tilted(30.0)
    gt = onbase.tangential(dirs, path.g0)
    n_load, _ = onbase.normal_load("plane", ((0.0, 0.0, 1.0),), None, path.g0)
    ref = _coulomb_reference(gt, n_load, (0.0, 1.0), np.arange(1, 61) / 60.0)
    errors = []
    for steps in (8, 16, 32):
        xs = np.array([x for x, _ in _slide("plane", dirs, path, (0.0, 1.0), steps, 1.0)])
        errors.append(np.max(np.linalg.norm(xs - ref, axis=1)))
    for coarse, fine in zip(errors, errors[1:]):
        assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.15), errors


def test_slide_euler_friction_stops_but_never_reverses():
    dirs = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0))
    flat = onbase.GravityPath((0.0, 0.0, -G), sp.IDENTITY_QUAT, sp.IDENTITY_QUAT)
    for v0, steps in (((0.5, 0.0), 1), ((0.3, -0.4), 4), ((0.5, 0.0), 7)):
        path = _slide("plane", dirs, flat, v0, steps, 1.0)
        speed0, prev = math.hypot(*v0), v0
        for x, v in path:
            assert math.hypot(*v) <= speed0
            assert v[0] * prev[0] + v[1] * prev[1] >= 0.0  # never turned back
            if any(v):
                prev = v
        x_end, v_end = path[-1]
        assert v_end == (0.0, 0.0)
        # Stopped within first-order error of the exact stop distance v0^2 / (2 f_d g).
        exact = speed0 ** 2 / (2 * FD * G)
        h = 1.0 / (60 * steps)
        assert abs(math.hypot(*x_end) - exact) <= 1.01 * speed0 * h
        # And it stays stopped, exactly.
        assert all(x == x_end for x, _ in path[-10:])


def test_slide_euler_below_the_friction_angle_does_not_move():
    dirs = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0))
    path = _slide("plane", dirs, _tilted(15.0), (0.0, 0.0), 4, 60.0)
    assert all(x == (0.0, 0.0) and v == (0.0, 0.0) for x, v in path)


def test_slide_euler_agrees_with_the_others_where_it_should():
    """Not bit-for-bit (it is a different scheme), but at 1e-4 s steps within 1e-4 m."""
    dirs = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0))
    fine = _slide("plane", dirs, _tilted(30.0), (0.0, 1.0), 160, 1.0)[-1][0]
    exact = _slide("plane", dirs, _tilted(30.0), (0.0, 1.0), 4, 1.0, "analytic")[-1][0]
    assert math.dist(fine, exact) < 1e-3


# --- free rotation ------------------------------------------------------------------------

MOMENTS = (0.3 * (0.05**2 + 0.02**2) / 12, 0.3 * (0.10**2 + 0.02**2) / 12,
           0.3 * (0.10**2 + 0.05**2) / 12)
W0 = (0.1, 5.0, 0.1)
M0 = tuple(i * w for i, w in zip(MOMENTS, W0))


def _box_reference(seconds: float) -> sp.Quat:
    inertia = np.array(MOMENTS)

    def rhs(_, y):
        w, (x, yq, z, s) = y[:3], y[3:]
        dq = 0.5 * np.array([s * w[0] + yq * w[2] - z * w[1], s * w[1] + z * w[0] - x * w[2],
                             s * w[2] + x * w[1] - yq * w[0], -x * w[0] - yq * w[1] - z * w[2]])
        return np.concatenate([np.cross(inertia * w, w) / inertia, dq])
    sol = solve_ivp(rhs, (0.0, seconds), [*W0, 0.0, 0.0, 0.0, 1.0], method="DOP853",
                    rtol=1e-13, atol=1e-15)
    q = sol.y[3:, -1]
    return tuple(q / np.linalg.norm(q))


def _box(rotate, seconds: float, step: float) -> sp.Quat:
    q, m = sp.IDENTITY_QUAT, M0
    for _ in range(round(seconds * 60)):
        q, m = rotate(q, m, 1.0 / 60.0, MOMENTS, max_step_s=step)
    return q


@pytest.mark.parametrize("rotate, order, steps", [
    (free.rotate_rk4, 4, (1 / 120, 1 / 240)),
    (free.rotate_euler, 1, (1 / 1920, 1 / 3840)),
])
def test_free_rotation_order_against_dop853(rotate, order, steps):
    ref = _box_reference(2.0)
    errors = [sp.quat_angle_between(_box(rotate, 2.0, h), ref) for h in steps]
    assert math.log2(errors[0] / errors[1]) == pytest.approx(order, abs=0.3), errors


def test_free_rotation_rk4_at_60hz_is_accurate_on_the_tumbling_box():
    # One step per frame: 1.4e-7 rad after 2 s; its |L| drifts a little (not conserved).
    q = _box(free.rotate_rk4, 2.0, 1 / 60)
    assert sp.quat_angle_between(q, _box_reference(2.0)) < 1e-6


def test_new_schemes_are_selectable_through_advance_and_omega_world():
    start = free.start(t_ns=0, cm=sp.ZERO3, velocity=sp.ZERO3, omega_world=W0,
                       world_from_part=sp.IDENTITY, part_from_principal=sp.IDENTITY_QUAT,
                       principal_moments=MOMENTS)
    for model, rotate in (("rk4", free.rotate_rk4), ("euler", free.rotate_euler)):
        flight = free.advance(start, 10**9 // 60, model=model, moments=MOMENTS, order=6,
                              max_step_s=1 / 240)
        q, m = rotate(sp.IDENTITY_QUAT, M0, (10**9 // 60) * 1e-9, MOMENTS, max_step_s=1 / 240)
        assert flight.world_from_principal == q and flight.momentum_principal == m
        w = free.omega_world(flight, model=model, moments=MOMENTS)
        assert w == sp.quat_rotate(q, tuple(x / i for x, i in zip(m, MOMENTS)))


def test_physics_validates_the_names():
    for name in free.FREE_ROTATIONS:
        Physics(free_rotation=name)
    Physics(turn_integrator="euler", slide_integrator="euler")
    for bad in ({"free_rotation": "spin"}, {"free_rotation_order": 5},
                {"turn_integrator": "leapfrog"}, {"slide_integrator": "rk4"}):
        with pytest.raises(ValueError):
            Physics(**bad)


def test_a_session_can_select_each_new_scheme():
    box = {"name": "box", "shape": {"type": "box", "size": [0.10, 0.05, 0.02]}, "density": 3000,
           "pose": {"position": [0.0, 0.0, 1.0]}}
    hand = [{"t": 0.0, "position": [0.0, 0.0, 1.0], "grip": False}, {"t": 0.1, "grip": True},
            {"t": 0.4, "position": [0.0, 0.1, 1.2],
             "xyzw": list(sp.quat_axis_angle(sp.normalize((0.3, 1.0, 0.2)), 1.5)),
             "grip": False}]
    finals = {}
    for rotation in ("momentum", "rk4", "euler"):
        doc = session_doc(parts=[box], right_hand=hand, duration_s=0.7,
                          physics={"free_rotation": rotation, "turn_integrator": "euler",
                                   "slide_integrator": "euler"}, environment=[])
        physics = make_session(doc).build_scene().physics
        assert (physics.free_rotation, physics.turn_integrator) == (rotation, "euler")
        records = run_records(doc)
        assert records[-1].parts[0].mode == "INSPACE"
        finals[rotation] = records[-1].parts[0].rotation_xyzw
    assert sp.quat_angle_between(finals["rk4"], finals["momentum"]) < 1e-6
    assert 1e-6 < sp.quat_angle_between(finals["euler"], finals["momentum"]) < 0.05


def test_sub_step_bounds_default_to_the_benchmarks_choice_or_the_shared_one():
    physics = Physics()
    assert physics.slide_integrator == "analytic4"
    assert physics.turn_step_s == 1 / 120 and physics.slide_step_s == 1 / 60
    # The second-order schemes keep their own (analytic's, the default before analytic4).
    assert Physics(slide_integrator="analytic").slide_step_s == 1 / 180
    assert physics.onbase_max_step_s is None
    assert Physics(onbase_max_step_s=0.01).turn_step_s == 0.01
    assert Physics(onbase_max_step_s=0.01).slide_step_s == 0.01
    split = Physics(turn_max_step_s=1 / 120, slide_max_step_s=1 / 480)
    assert (split.turn_step_s, split.slide_step_s) == (1 / 120, 1 / 480)
    doc = session_doc(parts=[{"name": "b", "shape": {"type": "box", "size": [0.1, 0.1, 0.1]},
                              "density": 1000}], right_hand=[{"t": 0.0, "position": [0, 0, 1]}],
                      duration_s=0.1, physics={"turn_max_step_s": 1 / 120})
    assert make_session(doc).build_scene().physics.turn_step_s == 1 / 120
