"""Motion of a part constrained on the base: sliding with friction and turning on a shaft.

The equations are written in the base part's frame (NOTES.md, 5.2 and 5.3). The state is
the part's coordinate relative to the base (slide distance or in-plane 2-vector, angle
about the shaft) and its rates; scaled gravity expressed in base axes changes as the user
turns the base. Within a frame the base's orientation is interpolated by slerp between the
previous and the current tracker pose, so gravity in base axes is an exact rotation of its
value at the frame start: ``g(tau) = Rot(a, -tau phi) g0`` with ``R1 R0^T = exp(phi a)``.

**Fictitious forces are left out, deliberately.** The base frame is not inertial when the
hand accelerates or turns it; the full relative equations add ``-a_base``, Euler,
centrifugal and Coriolis terms. They are not included because (1) the paper does not, and
the user's hand moves slowly compared with the part's own motion; (2) they need the base's
acceleration and angular acceleration, second differences of tracker poses, which multiply
tracker noise by ``1/dt^2`` (1e-4 m noise at 60 Hz is 0.36 m/s^2, 4 % of g), so the part
would jitter on a hand that is held still; (3) with them left out, a part at rest on a still
base stays at rest bit for bit. The base is treated as re-oriented quasi-statically, every
sub-step, under the gravity that its current orientation implies.

Sliding (per unit mass): ``g_t`` is gravity along the allowed directions, ``N`` the normal
load. At rest it starts when ``|g_t| > f_s N``; moving, ``a = g_t - f_d N v/|v|``; a sub-step
that would reverse the velocity stops the part at the instant the velocity reaches zero,
and the static test decides the rest of the sub-step. Each sub-step is the constant-
acceleration update with gravity sampled at the sub-step's mid time and the friction
direction frozen at the sub-step's start. That is exact (to round-off) while the velocity
stays along ``g_t``: any sliding along an axis, and sliding on a plane that starts from rest
under a still base. On a plane with the velocity across ``g_t`` (after the base turned, or
along a wall) the friction direction turns within a sub-step and the scheme is first order
in the sub-step (measured: 2.7e-3 m after 1 s at 4 sub-steps per frame, 2.7e-4 m at 40, on
a 30 degree incline with f_d 0.2 and 1 m/s across the slope).

Turning: ``J w' = m ((r_perp x g) . u) - f_r w`` with ``r_perp(theta)`` the CM offset turned
by ``theta`` about the shaft. Integrators:

- ``yoshida4`` / ``yoshida6`` (default ``yoshida6``): symmetric compositions of the Strang
  splitting (exact viscous decay for half a step, half a kick, drift, half a kick, decay).
  Symplectic for the undamped pendulum (bounded energy error, no drift), order 4 / 6.
- ``verlet``: the Strang splitting itself, order 2, symplectic.
- ``rk4``: classical Runge-Kutta, order 4, not symplectic (energy drifts).
- ``paper``: eq. 11, one step per frame: ``w += alpha dt; A += w dt + 0.5 alpha dt^2``.
"""

from __future__ import annotations

import math

from .. import spatial as sp
from .free import COMPOSITIONS

TURN_INTEGRATORS = ("yoshida6", "yoshida4", "verlet", "rk4", "paper")
SLIDE_INTEGRATORS = ("midpoint", "paper")
_TURN_WEIGHTS = {"verlet": COMPOSITIONS[2], "yoshida4": COMPOSITIONS[4],
                 "yoshida6": COMPOSITIONS[6]}


# --- gravity in base axes across a frame ------------------------------------------------

class GravityPath:
    """Scaled gravity in base axes over one frame, ``at(tau)`` for tau in [0, 1]."""

    __slots__ = ("g0", "axg", "aag", "phi", "g1")

    def __init__(self, gravity_world: sp.Vec3, base_rot_start: sp.Quat,
                 base_rot_end: sp.Quat) -> None:
        inv0 = sp.quat_conj(base_rot_start)
        self.g0 = sp.quat_rotate(inv0, gravity_world)
        rotvec = sp.quat_to_rotvec(sp.quat_mul(base_rot_end, inv0))
        self.phi = sp.norm(rotvec)
        if self.phi == 0.0:
            self.axg = self.aag = sp.ZERO3
            self.g1 = self.g0
            return
        a = sp.quat_rotate(inv0, sp.scale(rotvec, 1.0 / self.phi))
        self.axg = sp.cross(a, self.g0)
        self.aag = sp.scale(a, sp.dot(a, self.g0))
        self.g1 = sp.quat_rotate(sp.quat_conj(base_rot_end), gravity_world)

    def at(self, tau: float) -> sp.Vec3:
        if self.phi == 0.0 or tau == 0.0:
            return self.g0
        if tau == 1.0:
            return self.g1
        c, s = math.cos(-tau * self.phi), math.sin(-tau * self.phi)
        g0, axg, aag, k = self.g0, self.axg, self.aag, 1.0 - c
        return (g0[0] * c + axg[0] * s + aag[0] * k, g0[1] * c + axg[1] * s + aag[1] * k,
                g0[2] * c + axg[2] * s + aag[2] * k)


# --- sliding ----------------------------------------------------------------------------

def normal_load(kind: str, normals: tuple[sp.Vec3, ...], axis: sp.Vec3 | None,
                g: sp.Vec3) -> tuple[float, bool]:
    """Normal load per unit mass ``N`` and whether gravity pulls the part off the base."""
    if kind == "axis":
        gu = sp.dot(g, axis)  # type: ignore[arg-type]
        return math.sqrt(max(0.0, sp.dot(g, g) - gu * gu)), False
    lift = 1e-12 * sp.norm(g)
    if kind == "plane":
        gn = sp.dot(g, normals[0])
        return max(0.0, -gn), gn > -lift
    # Two planes: split g's normal part over the two normals (n1, n2 unit, not parallel).
    n1, n2 = normals
    c = sp.dot(n1, n2)
    g1, g2 = sp.dot(g, n1), sp.dot(g, n2)
    det = 1.0 - c * c
    alpha, beta = (g1 - c * g2) / det, (g2 - c * g1) / det
    return max(0.0, -alpha) + max(0.0, -beta), alpha > lift or beta > lift


def tangential(dirs: tuple[sp.Vec3, ...], g: sp.Vec3) -> tuple[float, ...]:
    return tuple(sp.dot(g, e) for e in dirs)


def project_blocked(drive: tuple[float, ...], blocked: tuple[float, ...]) -> tuple[float, ...]:
    """Remove the part of a drive that pushes into a blocked direction (the wall holds it)."""
    if not blocked:
        return drive
    into = sum(d * b for d, b in zip(drive, blocked))
    if into <= 0.0:
        return drive
    return tuple(d - into * b for d, b in zip(drive, blocked))


def starts_sliding(gt: tuple[float, ...], n_load: float, f_static: float) -> bool:
    """The static test ``|g_t| > f_s N``."""
    return math.sqrt(sum(x * x for x in gt)) > f_static * n_load


def _slide_substep(x: list[float], v: list[float], h: float, gt: tuple[float, ...],
                   n_load: float, fs: float, fd: float) -> None:
    """One exact constant-acceleration sub-step with Coulomb friction; edits x, v in place."""
    k = len(x)
    while h > 0.0:
        speed = math.sqrt(sum(c * c for c in v))
        if speed == 0.0:
            gmag = math.sqrt(sum(c * c for c in gt))
            if gmag <= fs * n_load or gmag <= fd * n_load:
                return
            # Friction opposes the impending motion, which starts along g_t.
            scale = 1.0 - fd * n_load / gmag
            for i in range(k):
                a = gt[i] * scale
                x[i] += 0.5 * a * h * h
                v[i] = a * h
            return
        friction = fd * n_load / speed
        acc = [gt[i] - friction * v[i] for i in range(k)]
        along = sum(acc[i] * v[i] for i in range(k)) / speed
        if along < 0.0:
            t_stop = speed / -along
            if t_stop < h:
                # Friction stops the part within the sub-step; it never reverses it.
                for i in range(k):
                    x[i] += v[i] * t_stop + 0.5 * acc[i] * t_stop * t_stop
                    v[i] = 0.0
                h -= t_stop
                continue
        for i in range(k):
            x[i] += v[i] * h + 0.5 * acc[i] * h * h
            v[i] += acc[i] * h
        return


# --- turning ----------------------------------------------------------------------------

class TurnForce:
    """``alpha(theta, tau) = A(tau) cos(theta) - B(tau) sin(theta)`` over one frame.

    ``A = (m/J) g.(u x r0)`` and ``B = (m/J) g.r0``, so the gravity torque needs two dot
    products per frame and one sine and cosine of theta per evaluation.
    """

    __slots__ = ("a0", "a1", "a2", "b0", "b1", "b2", "phi", "damping")

    def __init__(self, path: GravityPath, axis: sp.Vec3, cm_offset: sp.Vec3, mass_kg: float,
                 inertia: float, rotational_friction: float) -> None:
        k = mass_kg / inertia
        w1 = sp.scale(sp.cross(axis, cm_offset), k)
        w2 = sp.scale(cm_offset, k)
        self.a0, self.b0 = sp.dot(path.g0, w1), sp.dot(path.g0, w2)
        self.a1, self.b1 = sp.dot(path.axg, w1), sp.dot(path.axg, w2)
        self.a2, self.b2 = sp.dot(path.aag, w1), sp.dot(path.aag, w2)
        self.phi = path.phi
        self.damping = rotational_friction / inertia

    def alpha(self, theta: float, tau: float) -> float:
        if self.phi == 0.0:
            return self.a0 * math.cos(theta) - self.b0 * math.sin(theta)
        c, s = math.cos(-tau * self.phi), math.sin(-tau * self.phi)
        k = 1.0 - c
        a = self.a0 * c + self.a1 * s + self.a2 * k
        b = self.b0 * c + self.b1 * s + self.b2 * k
        return a * math.cos(theta) - b * math.sin(theta)


def turn(force: TurnForce, theta: float, omega: float, dt: float, steps: int,
         integrator: str) -> tuple[float, float]:
    """Advance (theta, omega) over a frame of ``dt`` seconds in ``steps`` sub-steps."""
    if integrator == "paper":
        alpha = force.alpha(theta, 1.0) - force.damping * omega
        return theta + omega * dt + 0.5 * alpha * dt * dt, omega + alpha * dt
    h = dt / steps
    inv_dt = 1.0 / dt
    if integrator == "rk4":
        c = force.damping
        t = 0.0
        for _ in range(steps):
            k1t, k1w = omega, force.alpha(theta, t * inv_dt) - c * omega
            tm = (t + 0.5 * h) * inv_dt
            th2, w2 = theta + 0.5 * h * k1t, omega + 0.5 * h * k1w
            k2t, k2w = w2, force.alpha(th2, tm) - c * w2
            th3, w3 = theta + 0.5 * h * k2t, omega + 0.5 * h * k2w
            k3t, k3w = w3, force.alpha(th3, tm) - c * w3
            th4, w4 = theta + h * k3t, omega + h * k3w
            t += h
            k4t, k4w = w4, force.alpha(th4, t * inv_dt) - c * w4
            theta += h / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
            omega += h / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
        return theta, omega
    stages = [(w * h, 0.5 * w * h, math.exp(-0.5 * force.damping * w * h))
              for w in _TURN_WEIGHTS[integrator]]
    t = 0.0
    alpha = force.alpha(theta, 0.0)
    for _ in range(steps):
        for wh, half, decay in stages:
            omega = (omega * decay + half * alpha)
            theta += wh * omega
            t += wh
            alpha = force.alpha(theta, t * inv_dt)
            omega = (omega + half * alpha) * decay
    return theta, omega


def pendulum_energy(force: TurnForce, inertia: float, theta: float, omega: float) -> float:
    """``0.5 J w^2 + V(theta)`` per unit of J (still base): the undamped invariant."""
    return 0.5 * omega * omega - (force.a0 * math.sin(theta) + force.b0 * math.cos(theta))


def substeps(dt: float, max_step_s: float) -> int:
    return max(1, math.ceil(dt / max_step_s - 1e-9))


def slide(mate_kind: str, normals: tuple[sp.Vec3, ...], axis: sp.Vec3 | None,
          dirs: tuple[sp.Vec3, ...], path: GravityPath, x: tuple[float, ...],
          v: tuple[float, ...], dt: float, steps: int, *, f_static: float, f_dynamic: float,
          blocked: tuple[float, ...], integrator: str) -> tuple[tuple[float, ...],
                                                            tuple[float, ...]]:
    """Advance the slide coordinates ``x`` and rates ``v`` over a frame of ``dt`` seconds."""
    xs, vs = list(x), list(v)
    if integrator == "paper":
        # Eqs. 3-4: the angle test decides each frame; friction opposes the downhill direction.
        g = path.at(1.0)
        n_load, _ = normal_load(mate_kind, normals, axis, g)
        gt = project_blocked(tangential(dirs, g), blocked)
        gmag = math.sqrt(sum(c * c for c in gt))
        if gmag <= f_static * n_load:
            return x, tuple(0.0 for _ in x)
        scale = 1.0 - f_dynamic * n_load / gmag
        for i in range(len(xs)):
            a = gt[i] * scale
            xs[i] += vs[i] * dt + 0.5 * a * dt * dt
            vs[i] += a * dt
        return tuple(xs), tuple(vs)
    h = dt / steps
    for i in range(steps):
        g = path.at((i + 0.5) / steps)
        n_load, _ = normal_load(mate_kind, normals, axis, g)
        gt = project_blocked(tangential(dirs, g), blocked)
        _slide_substep(xs, vs, h, gt, n_load, f_static, f_dynamic)
    return tuple(xs), tuple(vs)
