"""Free flight (paper 5.1, NOTES.md): exact translation, momentum-conserving rotation.

Translation of the centre of mass under scaled gravity is a closed form, evaluated from
the release state at any time: no integration, no drift.

Rotation of a torque-free rigid body conserves the world angular momentum ``L``, not the
angular velocity. ``momentum`` integrates it by splitting the kinetic energy
``T = sum L_i^2 / (2 I_i)`` over the principal axes: each piece is an exact rotation about
one principal axis, so ``|L|`` and the world ``L`` are conserved to round-off and the scheme
is symplectic; Strang splitting is second order and Yoshida's compositions raise it to
fourth or sixth. ``constant_omega`` is the paper's eq. 1b read as ``R(t) = exp(t [w0]x) R0``.

Two textbook schemes on Euler's equations (``L' = L x w`` in body axes, ``w = L / I``) and the
quaternion kinematics (``q' = q (w, 0) / 2``) are selectable too, so that the benchmark can
weigh them against the splitting: ``rk4`` (classical Runge-Kutta on both, the quaternion
normalised after every step; order 4, neither ``|L|`` nor the energy is conserved) and
``euler`` (semi-implicit Euler: ``L += h L x w(L)``, then the orientation turns by the exact
rotation ``exp(h w(L_new))`` in body axes; order 1, ``|L|`` grows by ``O(h^2)`` a step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from .. import spatial as sp

_CBRT2: Final = 2.0 ** (1.0 / 3.0)
_Y4 = (1.0 / (2.0 - _CBRT2), -_CBRT2 / (2.0 - _CBRT2), 1.0 / (2.0 - _CBRT2))
# Yoshida (1990) sixth order, solution A.
_W1, _W2, _W3 = -1.17767998417887, 0.235573213359357, 0.784513610477560
_W0 = 1.0 - 2.0 * (_W1 + _W2 + _W3)
_Y6 = (_W3, _W2, _W1, _W0, _W1, _W2, _W3)
COMPOSITIONS = {2: (1.0,), 4: _Y4, 6: _Y6}
FREE_ROTATIONS = ("momentum", "constant_omega", "rk4", "euler")


@dataclass(slots=True)
class Flight:
    """A part in free flight: release state and the rotation state at ``t_ns``."""

    t0_ns: int                    # release (or slide-off) time
    cm0: sp.Vec3                  # world CM at t0
    v0: sp.Vec3                   # world CM velocity at t0
    t_ns: int                     # time of the rotation state below
    world_from_principal: sp.Quat
    momentum_principal: sp.Vec3   # angular momentum in principal axes (momentum model)
    omega_world: sp.Vec3          # constant angular velocity (constant_omega model)
    # False while a part that left the base still touches it: the base does not stop it
    # until the two have separated once.
    base_clear: bool
    # While not clear, what of the base it passes: the surfaces (indices, see
    # ``collision.base_surfaces``) it touched as it left, the rest of the base stopping it
    # (``physics.flight_grace`` "touched"); None: the whole base ("whole_base", as before
    # 2026-11-23).
    grace: tuple[int, ...] | None
    # Per surface ``grace`` lists, the gap the part first left it at, raised to the farthest
    # it has been from it at a frame's start (``step._grace``, ``step._fly``): it is met at a
    # tenth of that (one left touching, at distance 0, is passed until then).
    grace_gaps: tuple[float, ...]
    # Whether it began where the part met a base face that could not hold it (a graze,
    # ``step._met_again``), and that face's normal (base axes).
    after_graze: bool
    grazed_normal: sp.Vec3
    # Since when (ns) the part has been met again and again so (0: it has not).
    held_ns: int

    # Not frozen, and its own __init__: see vade_replay/frames.py (a value all the same).
    def __init__(self, t0_ns: int, cm0: sp.Vec3, v0: sp.Vec3, t_ns: int,
                 world_from_principal: sp.Quat, momentum_principal: sp.Vec3,
                 omega_world: sp.Vec3, base_clear: bool = True,
                 grace: tuple[int, ...] | None = None,
                 grace_gaps: tuple[float, ...] = (), after_graze: bool = False,
                 grazed_normal: sp.Vec3 = sp.ZERO3, held_ns: int = 0) -> None:
        self.t0_ns = t0_ns
        self.cm0 = cm0
        self.v0 = v0
        self.t_ns = t_ns
        self.world_from_principal = world_from_principal
        self.momentum_principal = momentum_principal
        self.omega_world = omega_world
        self.base_clear = base_clear
        self.grace = grace
        self.grace_gaps = grace_gaps
        self.after_graze = after_graze
        self.grazed_normal = grazed_normal
        self.held_ns = held_ns


def start(*, t_ns: int, cm: sp.Vec3, velocity: sp.Vec3, omega_world: sp.Vec3,
          world_from_part: sp.Pose, part_from_principal: sp.Quat,
          principal_moments: sp.Vec3, base_clear: bool = True,
          grace: tuple[int, ...] | None = None,
          grace_gaps: tuple[float, ...] = (), after_graze: bool = False,
          grazed_normal: sp.Vec3 = sp.ZERO3, held_ns: int = 0) -> Flight:
    """Flight state from a release: CM position and velocity, angular velocity, part pose."""
    world_from_principal = sp.quat_normalize(sp.quat_mul(world_from_part.rotation,
                                                         part_from_principal))
    omega_principal = sp.quat_rotate(sp.quat_conj(world_from_principal), omega_world)
    momentum = (principal_moments[0] * omega_principal[0],
                principal_moments[1] * omega_principal[1],
                principal_moments[2] * omega_principal[2])
    return Flight(t_ns, cm, velocity, t_ns, world_from_principal, momentum, omega_world,
                  base_clear, grace, grace_gaps, after_graze, grazed_normal, held_ns)


def cm_at(flight: Flight, t_ns: int, gravity: sp.Vec3) -> tuple[sp.Vec3, sp.Vec3]:
    """Closed-form CM position and velocity at ``t_ns``."""
    tau = (t_ns - flight.t0_ns) * 1e-9
    c, v, g = flight.cm0, flight.v0, gravity
    half = 0.5 * tau * tau
    return ((c[0] + v[0] * tau + g[0] * half, c[1] + v[1] * tau + g[1] * half,
             c[2] + v[2] * tau + g[2] * half),
            (v[0] + g[0] * tau, v[1] + g[1] * tau, v[2] + g[2] * tau))


def _axis_flow(q: sp.Quat, m: list[float], axis: int, tau: float, moments: sp.Vec3) -> sp.Quat:
    """Exact flow of T_i = L_i^2 / (2 I_i) for time tau: rotate about principal axis i.

    One sine and one cosine, of the half angle: the body momentum turns by the full angle
    (double-angle formulas), the orientation quaternion by the half."""
    half = 0.5 * tau * m[axis] / moments[axis]
    hc, hs = math.cos(half), math.sin(half)
    c, s = hc * hc - hs * hs, 2.0 * hs * hc
    j, k = (axis + 1) % 3, (axis + 2) % 3
    mj, mk = m[j], m[k]
    m[j] = c * mj + s * mk
    m[k] = -s * mj + c * mk
    qx, qy, qz, qw = q
    if axis == 0:
        return (qw * hs + qx * hc, qy * hc + qz * hs, qz * hc - qy * hs, qw * hc - qx * hs)
    if axis == 1:
        return (qx * hc - qz * hs, qw * hs + qy * hc, qz * hc + qx * hs, qw * hc - qy * hs)
    return (qx * hc + qy * hs, qy * hc - qx * hs, qw * hs + qz * hc, qw * hc - qz * hs)


def _flows(order: int, steps: int, h: float) -> tuple[tuple[int, float], ...]:
    """The axis flows of ``steps`` composed Strang steps of ``h``, as (axis, time).

    Strang: axis 0 for h/2, axis 1 for h/2, axis 2 for h, axis 1 for h/2, axis 0 for h/2
    (the largest moment in the middle: its flow is the slowest, so the split error is
    least). Flows about the same axis commute, so where one Strang step ends and the next
    begins with axis 0 the two half flows are one: 29 flows instead of 35 per sixth-order
    step. Cached: a steady tracker asks for the same frame length again and again.
    """
    key = (order, steps, h)
    flows = _FLOWS.get(key)
    if flows is None:
        out: list[list] = []
        for _ in range(steps):
            for w in COMPOSITIONS[order]:
                wh = w * h
                for axis, tau in ((0, 0.5 * wh), (1, 0.5 * wh), (2, wh), (1, 0.5 * wh),
                                  (0, 0.5 * wh)):
                    if out and out[-1][0] == axis:
                        out[-1][1] += tau
                    else:
                        out.append([axis, tau])
        if len(_FLOWS) >= 64:
            _FLOWS.clear()
        flows = _FLOWS[key] = tuple((axis, tau) for axis, tau in out)
    return flows


_FLOWS: dict[tuple[int, int, float], tuple[tuple[int, float], ...]] = {}


def rotate_momentum(q: sp.Quat, momentum: sp.Vec3, dt_s: float, moments: sp.Vec3, *,
                    order: int, max_step_s: float) -> tuple[sp.Quat, sp.Vec3]:
    """Advance a torque-free body's orientation and body momentum by ``dt_s``."""
    if dt_s <= 0.0:
        return q, momentum
    steps = max(1, math.ceil(dt_s / max_step_s - 1e-9))
    # _axis_flow inlined: the three axes' flows, in the order _flows gives.
    i0, i1, i2 = moments
    m0, m1, m2 = momentum
    qx, qy, qz, qw = q
    # math.cos and math.sin called by name: compiled (mypyc), that is a direct C call;
    # bound to local names they would be Python calls with boxed floats.
    for axis, tau in _flows(order, steps, dt_s / steps):
        if axis == 0:
            half = 0.5 * tau * m0 / i0
            hc, hs = math.cos(half), math.sin(half)
            c, s = hc * hc - hs * hs, 2.0 * hs * hc
            m1, m2 = c * m1 + s * m2, -s * m1 + c * m2
            qx, qy, qz, qw = (qw * hs + qx * hc, qy * hc + qz * hs, qz * hc - qy * hs,
                              qw * hc - qx * hs)
        elif axis == 1:
            half = 0.5 * tau * m1 / i1
            hc, hs = math.cos(half), math.sin(half)
            c, s = hc * hc - hs * hs, 2.0 * hs * hc
            m2, m0 = c * m2 + s * m0, -s * m2 + c * m0
            qx, qy, qz, qw = (qx * hc - qz * hs, qw * hs + qy * hc, qz * hc + qx * hs,
                              qw * hc - qy * hs)
        else:
            half = 0.5 * tau * m2 / i2
            hc, hs = math.cos(half), math.sin(half)
            c, s = hc * hc - hs * hs, 2.0 * hs * hc
            m0, m1 = c * m0 + s * m1, -s * m0 + c * m1
            qx, qy, qz, qw = (qx * hc + qy * hs, qy * hc - qx * hs, qw * hs + qz * hc,
                              qw * hc - qz * hs)
    return sp.quat_normalize((qx, qy, qz, qw)), (m0, m1, m2)


def _rates(x: float, y: float, z: float, s: float, m0: float, m1: float, m2: float,
           i0: float, i1: float, i2: float) -> tuple[float, ...]:
    """Euler's equations and the quaternion kinematics: (q', L') at (q, L), body axes."""
    wx, wy, wz = m0 * i0, m1 * i1, m2 * i2
    return (0.5 * (s * wx + y * wz - z * wy), 0.5 * (s * wy + z * wx - x * wz),
            0.5 * (s * wz + x * wy - y * wx), -0.5 * (x * wx + y * wy + z * wz),
            m1 * wz - m2 * wy, m2 * wx - m0 * wz, m0 * wy - m1 * wx)


def rotate_rk4(q: sp.Quat, momentum: sp.Vec3, dt_s: float, moments: sp.Vec3, *,
               max_step_s: float) -> tuple[sp.Quat, sp.Vec3]:
    """Classical RK4 on Euler's equations and the quaternion kinematics (normalised)."""
    if dt_s <= 0.0:
        return q, momentum
    steps = max(1, math.ceil(dt_s / max_step_s - 1e-9))
    h = dt_s / steps
    h2, h6 = 0.5 * h, h / 6.0
    inv = (1.0 / moments[0], 1.0 / moments[1], 1.0 / moments[2])
    x, y, z, s = q
    m0, m1, m2 = momentum
    for _ in range(steps):
        a = _rates(x, y, z, s, m0, m1, m2, *inv)
        b = _rates(x + h2 * a[0], y + h2 * a[1], z + h2 * a[2], s + h2 * a[3],
                   m0 + h2 * a[4], m1 + h2 * a[5], m2 + h2 * a[6], *inv)
        c = _rates(x + h2 * b[0], y + h2 * b[1], z + h2 * b[2], s + h2 * b[3],
                   m0 + h2 * b[4], m1 + h2 * b[5], m2 + h2 * b[6], *inv)
        d = _rates(x + h * c[0], y + h * c[1], z + h * c[2], s + h * c[3],
                   m0 + h * c[4], m1 + h * c[5], m2 + h * c[6], *inv)
        x += h6 * (a[0] + 2.0 * (b[0] + c[0]) + d[0])
        y += h6 * (a[1] + 2.0 * (b[1] + c[1]) + d[1])
        z += h6 * (a[2] + 2.0 * (b[2] + c[2]) + d[2])
        s += h6 * (a[3] + 2.0 * (b[3] + c[3]) + d[3])
        m0 += h6 * (a[4] + 2.0 * (b[4] + c[4]) + d[4])
        m1 += h6 * (a[5] + 2.0 * (b[5] + c[5]) + d[5])
        m2 += h6 * (a[6] + 2.0 * (b[6] + c[6]) + d[6])
        x, y, z, s = sp.quat_normalize((x, y, z, s))
    return (x, y, z, s), (m0, m1, m2)


def rotate_euler(q: sp.Quat, momentum: sp.Vec3, dt_s: float, moments: sp.Vec3, *,
                 max_step_s: float) -> tuple[sp.Quat, sp.Vec3]:
    """Semi-implicit Euler: momentum first, then an exact turn at the new angular velocity."""
    if dt_s <= 0.0:
        return q, momentum
    steps = max(1, math.ceil(dt_s / max_step_s - 1e-9))
    h = dt_s / steps
    i0, i1, i2 = moments
    m0, m1, m2 = momentum
    for _ in range(steps):
        w0, w1, w2 = m0 / i0, m1 / i1, m2 / i2
        m0, m1, m2 = (m0 + h * (m1 * w2 - m2 * w1), m1 + h * (m2 * w0 - m0 * w2),
                      m2 + h * (m0 * w1 - m1 * w0))
        turn = (h * m0 / i0, h * m1 / i1, h * m2 / i2)
        if not math.isfinite(turn[0] * turn[0] + turn[1] * turn[1] + turn[2] * turn[2]):
            # Unstable (a stiff body at too long a step): NaN, which the step reports as a
            # numerical fault, rather than an exception from the trigonometry.
            nan = math.nan
            return (nan, nan, nan, nan), (nan, nan, nan)
        q = sp.quat_mul(q, sp.quat_from_rotvec(turn))
    return sp.quat_normalize(q), (m0, m1, m2)


_SYMMETRY_RTOL: Final = 1e-12


def symmetry(moments: sp.Vec3) -> tuple[int, float] | None:
    """``(axis, I_t)`` for an axisymmetric body: two principal moments equal (to 1e-12 of
    the largest, round-off of the mass properties) to ``I_t``, ``axis`` the third; None
    for a body with three distinct moments. A sphere is symmetric about any axis."""
    i0, i1, i2 = moments
    # (Written out, as ``max`` would take them: compiled, ``max`` and a loop over tuples
    # boxed each moment, every frame of a flight.)
    top = abs(i0)
    if abs(i1) > top:
        top = abs(i1)
    if abs(i2) > top:
        top = abs(i2)
    if abs(i0 - i1) <= _SYMMETRY_RTOL * top:
        return 2, 0.5 * (i0 + i1)
    if abs(i1 - i2) <= _SYMMETRY_RTOL * top:
        return 0, 0.5 * (i1 + i2)
    if abs(i2 - i0) <= _SYMMETRY_RTOL * top:
        return 1, 0.5 * (i2 + i0)
    return None


def rotate_symmetric(q: sp.Quat, momentum: sp.Vec3, dt_s: float, moments: sp.Vec3,
                     axis: int, transverse: float) -> tuple[sp.Quat, sp.Vec3]:
    """The torque-free axisymmetric body in closed form: no integration, no error.

    With ``I_t`` the two equal moments, ``T = |L|^2 / (2 I_t) + L_a^2 (1/I_a - 1/I_t) / 2``.
    The two terms commute (``|L|^2`` is a Casimir), so the exact flow is the product of
    theirs: a turn of the body about the world angular momentum at the rate ``|L| / I_t``,
    and a turn about its own symmetry axis at ``L_a (1/I_a - 1/I_t)`` (which carries the
    body-axis momentum round that axis: the free precession).
    """
    if dt_s <= 0.0:
        return q, momentum
    m = [momentum[0], momentum[1], momentum[2]]
    q = _symmetric_flow(q, m, dt_s, moments, axis, transverse)
    return sp.quat_normalize(q), (m[0], m[1], m[2])


# Two moments closer than this (relative to the larger) make a body a nearly symmetric top.
_NEAR_SYMMETRY_RTOL: Final = 1e-3


def near_symmetry(moments: sp.Vec3) -> tuple[int, float] | None:
    """``(axis, I_t)`` for a body whose two closest moments are within 0.1 % of each other
    (``I_t`` their mean, ``axis`` the third), and which ``symmetry`` does not already take;
    None otherwise."""
    i0, i1, i2 = moments
    best = None
    for axis, a, b in ((2, i0, i1), (0, i1, i2), (1, i2, i0)):
        gap = abs(a - b) / max(abs(a), abs(b))
        if gap <= _NEAR_SYMMETRY_RTOL and (best is None or gap < best[0]):
            best = (gap, axis, 0.5 * (a + b))
    return None if best is None else (best[1], best[2])


def _symmetric_flow(q: sp.Quat, m: list[float], tau: float, moments: sp.Vec3, axis: int,
                    transverse: float) -> sp.Quat:
    """The exact symmetric-top flow of ``rotate_symmetric`` for ``tau`` (``m`` in place)."""
    q = _axis_flow(q, m, axis, tau * (1.0 / moments[axis] - 1.0 / transverse) * moments[axis],
                   moments)
    spin = sp.quat_rotate(q, (m[0], m[1], m[2]))
    return sp.quat_mul(sp.quat_from_rotvec(sp.scale(spin, tau / transverse)), q)


def rotate_near_symmetric(q: sp.Quat, momentum: sp.Vec3, dt_s: float, moments: sp.Vec3,
                          axis: int, transverse: float, *, order: int,
                          max_step_s: float) -> tuple[sp.Quat, sp.Vec3]:
    """A nearly symmetric top: the symmetric top's exact flow, split with the small rest.

    ``T = S + P``: ``S = |L|^2 / (2 I_t) + L_a^2 (1/I_a - 1/I_t) / 2`` (exact, as in
    ``rotate_symmetric``) and ``P = sum L_i^2 (1/I_i - 1/I_t) / 2`` over the two nearly equal
    axes, each an exact turn about its axis and both small. Strang (P/2, S, P/2) composed to
    ``order``: the splitting error is proportional to P, so it vanishes as the body becomes
    symmetric, where the three-axis splitting's does not (a thin rod with moments 1e-6
    apart: 1.3e-9 rad over 10 s against 2 rad; tests/test_free_flight.py).
    """
    if dt_s <= 0.0:
        return q, momentum
    steps = max(1, math.ceil(dt_s / max_step_s - 1e-9))
    h = dt_s / steps
    i, j = [k for k in range(3) if k != axis]
    ci = (1.0 / moments[i] - 1.0 / transverse) * moments[i]
    cj = (1.0 / moments[j] - 1.0 / transverse) * moments[j]
    m = [momentum[0], momentum[1], momentum[2]]
    for _ in range(steps):
        for w in COMPOSITIONS[order]:
            half = 0.5 * w * h
            q = _axis_flow(q, m, i, half * ci, moments)
            q = _axis_flow(q, m, j, half * cj, moments)
            q = _symmetric_flow(q, m, w * h, moments, axis, transverse)
            q = _axis_flow(q, m, j, half * cj, moments)
            q = _axis_flow(q, m, i, half * ci, moments)
    return sp.quat_normalize(q), (m[0], m[1], m[2])


def advance(flight: Flight, t_ns: int, *, model: str, moments: sp.Vec3, order: int,
            max_step_s: float) -> Flight:
    """The flight with its rotation state moved to ``t_ns`` (translation is closed form)."""
    if t_ns <= flight.t_ns:
        return flight
    dt = (t_ns - flight.t_ns) * 1e-9
    if model == "constant_omega":
        q = sp.quat_normalize(sp.quat_mul(sp.quat_from_rotvec(sp.scale(flight.omega_world, dt)),
                                          flight.world_from_principal))
        return Flight(flight.t0_ns, flight.cm0, flight.v0, t_ns, q, flight.momentum_principal,
                      flight.omega_world, flight.base_clear, flight.grace,
                      flight.grace_gaps, flight.after_graze, flight.grazed_normal,
                      flight.held_ns)
    if model == "rk4":
        q, m = rotate_rk4(flight.world_from_principal, flight.momentum_principal, dt, moments,
                          max_step_s=max_step_s)
    elif model == "euler":
        q, m = rotate_euler(flight.world_from_principal, flight.momentum_principal, dt, moments,
                            max_step_s=max_step_s)
    elif (sym := symmetry(moments)) is not None:
        q, m = rotate_symmetric(flight.world_from_principal, flight.momentum_principal, dt,
                                moments, *sym)
    elif (near := near_symmetry(moments)) is not None:
        q, m = rotate_near_symmetric(flight.world_from_principal, flight.momentum_principal,
                                     dt, moments, *near, order=order, max_step_s=max_step_s)
    else:
        q, m = rotate_momentum(flight.world_from_principal, flight.momentum_principal, dt,
                               moments, order=order, max_step_s=max_step_s)
    return Flight(flight.t0_ns, flight.cm0, flight.v0, t_ns, q, m, flight.omega_world,
                  flight.base_clear, flight.grace, flight.grace_gaps, flight.after_graze,
                  flight.grazed_normal, flight.held_ns)


def max_angular_speed(momentum: sp.Vec3, moments: sp.Vec3) -> float:
    """The largest |w| a torque-free body reaches with this momentum (body axes) and energy.

    With x_i = L_i^2, |L|^2 = sum x_i and 2E = sum x_i / I_i are conserved, and
    |w|^2 = sum x_i / I_i^2 is linear in x: its maximum over that segment of the simplex lies
    where one x_i is zero, so the three pairs are tried. Far tighter than |L| / I_min (1800x
    for a thin rod turning end over end), which keeps conservative advancement cheap.
    """
    x = [m * m for m in momentum]
    total = sum(x)
    if total == 0.0:
        return 0.0
    energy2 = sum(xi / i for xi, i in zip(x, moments))
    best = sum(xi / (i * i) for xi, i in zip(x, moments))
    for a, b in ((0, 1), (0, 2), (1, 2)):
        ia, ib = moments[a], moments[b]
        # Equal moments (or ones a few ulps apart, whose inverses are equal in floats): |w|
        # is the same all along that edge, which the body reaches only if it is already on
        # it; the current state's value covers it.
        if 1.0 / ia == 1.0 / ib:
            continue
        xa = (energy2 - total / ib) / (1.0 / ia - 1.0 / ib)
        xb = total - xa
        if xa >= 0.0 and xb >= 0.0:
            best = max(best, xa / (ia * ia) + xb / (ib * ib))
    # Round-off allowance: the bound must never be below the true speed.
    return math.sqrt(best) * (1.0 + 1e-9)


def omega_world(flight: Flight, *, model: str, moments: sp.Vec3) -> sp.Vec3:
    """Current angular velocity in world axes."""
    if model == "constant_omega":
        return flight.omega_world
    m = flight.momentum_principal
    body = (m[0] / moments[0], m[1] / moments[1], m[2] / moments[2])
    return sp.quat_rotate(flight.world_from_principal, body)


def pose(flight: Flight, cm: sp.Vec3, *, part_from_principal: sp.Quat,
         center_of_mass: sp.Vec3) -> sp.Pose:
    """World pose of the part frame given the world CM and the flight's rotation."""
    rotation = sp.quat_normalize(sp.quat_mul(flight.world_from_principal,
                                             sp.quat_conj(part_from_principal)))
    return sp.Pose(sp.sub(cm, sp.quat_rotate(rotation, center_of_mass)), rotation)
