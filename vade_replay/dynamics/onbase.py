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
that would reverse the velocity stops the part at the instant the velocity reaches zero.
With ``located`` (physics ``slide_onset: "located"``, the default) the instant a part at rest
starts to slip is found within the sub-step (``_onset``: the static test on the frame's
gravity path, sampled and bisected), and after a stop the scheme resumes from the next such
instant; between them ``analytic``, ``analytic4`` and ``midpoint`` take closed-form flows
under frozen gravity.
``slide_integrator``:

- ``analytic4`` (default, one sub-step a frame): two exact flows of h/2 under gravity (``g_t``
  and ``N``) combined from its values at the two Gauss nodes, the commutator-free scheme of
  Blanes and Moan (2006): exact under a still base, fourth order while it turns, also
  through a stop (its instant is bisected on the whole scheme, ``_flow``). 5.5e-10 m after
  1 s on a 30 degree incline turning at 1 rad/s at 1/60 s (vade-bench).
- ``analytic``: gravity held at the interval's mid time, and the exact solution for it.
  While the velocity is along ``g_t`` the acceleration is constant (any sliding along an
  axis; a plane from rest under a still base); across ``g_t`` in a plane the friction
  direction turns, and the flow takes the closed form of ``_plane_flow``, stop instant
  included. Exact (to round-off) under a still base, second order while the base turns:
  on a 30 degree incline, f_d 0.2, 1 m/s across the slope, 1 s at 1/240 s sub-steps 9e-14 m
  from a DOP853 reference; with the base turning at 1 rad/s about its normal, 5.0e-6 m.
- ``midpoint``: the constant-acceleration update with the friction direction frozen at the
  interval's start. The same as ``analytic`` along ``g_t``; across it, first order
  (2.7e-3 m at 1/240 s and 2.7e-4 m at 1/2400 s in the still-incline case above).
- ``euler``: semi-implicit (symplectic) Euler, for the benchmark: ``v += a h; x += v h``,
  first order even under constant acceleration, gravity at mid sub-step, no instants
  located. Friction never reverses it: a sub-step whose new velocity points against the
  old one ends at rest where it started (``x += 0 h``, the scheme's own position update
  with the velocity it stopped at); from rest the static test decides, as for the others.
- ``paper``: eqs. 3-4 once per frame under the frame's end gravity, no sub-steps: the angle
  test decides each frame, and friction opposes the downhill direction.

Turning: ``J w' = m ((r_perp x g) . u) - f_r w`` with ``r_perp(theta)`` the CM offset turned
by ``theta`` about the shaft. Integrators:

- ``yoshida4`` / ``yoshida6`` (default ``yoshida6``): symmetric compositions of the Strang
  splitting (exact viscous decay for half a step, half a kick, drift, half a kick, decay).
  Symplectic for the undamped pendulum (bounded energy error, no drift), order 4 / 6.
- ``verlet``: the Strang splitting itself, order 2, symplectic.
- ``rk4``: classical Runge-Kutta, order 4, not symplectic (energy drifts).
- ``euler``: semi-implicit (symplectic) Euler, order 1, for the benchmark: exact viscous
  decay and a kick at the sub-step's start time, then a drift with the new rate:
  ``w = w e^{-c h} + alpha(theta, t) h; theta += w h``. Symplectic for the undamped
  pendulum (bounded energy error), first order.
- ``paper``: eq. 11, one step per frame: ``w += alpha dt; A += w dt + 0.5 alpha dt^2``.
"""

from __future__ import annotations

import math
from typing import Final

from .. import spatial as sp
from .free import COMPOSITIONS

TURN_INTEGRATORS = ("yoshida6", "yoshida4", "verlet", "rk4", "euler", "paper")
SLIDE_INTEGRATORS = ("analytic", "analytic4", "midpoint", "euler", "paper")
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


def _from_rest(gt: tuple[float, ...], n_load: float, fs: float,
               fd: float) -> list[float] | None:
    """At rest: None while static friction holds, else the acceleration as it starts to
    slide (along ``g_t``, dynamic friction opposing the impending motion)."""
    gmag = math.sqrt(sum(c * c for c in gt))
    if gmag <= fs * n_load or gmag <= fd * n_load:
        return None
    scale = 1.0 - fd * n_load / gmag
    return [c * scale for c in gt]


def _slide_substep(x: list[float], v: list[float], h: float, gt: tuple[float, ...],
                   n_load: float, fs: float, fd: float, plane_exact: bool = False,
                   until_stop: bool = False) -> float:
    """One sub-step with Coulomb friction under constant ``g_t``; edits x, v in place.

    While the velocity is along ``g_t`` (or friction or ``g_t`` is zero) the acceleration is
    constant and the update is exact. Otherwise, in a plane, ``plane_exact`` takes the closed-
    form solution (``_plane_flow``); without it the friction direction is frozen at the
    sub-step's start (the ``midpoint`` scheme, first order in that case). A part at rest
    starts by the static test under this ``g_t``. With ``until_stop`` a part that friction
    stops returns the time left (the caller decides when it starts again); otherwise the
    static test under this ``g_t`` decides the rest of the sub-step. Returns the time left
    (0.0: the whole sub-step was done)."""
    k = len(x)
    while h > 0.0:
        speed = math.sqrt(sum(c * c for c in v))
        if speed == 0.0:
            acc = _from_rest(gt, n_load, fs, fd)
            if acc is not None:
                for i in range(k):
                    x[i] += 0.5 * acc[i] * h * h
                    v[i] = acc[i] * h
            return 0.0
        line = False
        if plane_exact and k == 2:
            c = fd * n_load
            gmag = math.hypot(gt[0], gt[1])
            across = abs(v[0] * gt[1] - v[1] * gt[0])
            # Along g_t to within _PARALLEL, but not to the last bit: the motion of a line.
            line = c > 0.0 and gmag > _PARALLEL * c and 0.0 < across <= _PARALLEL * speed * gmag
            if c > 0.0 and gmag > _PARALLEL * c and across > _PARALLEL * speed * gmag:
                if speed <= _TINY_SPEED * (c + gmag) * h:
                    v[0] = v[1] = 0.0  # immeasurably slow: at rest, the static test decides
                    if until_stop:
                        return h
                    continue
                h = _plane_flow(x, v, h, gt, gmag, c, speed)
                if until_stop and h > 0.0:
                    return h
                continue
        friction = fd * n_load / speed
        acc = [gt[i] - friction * v[i] for i in range(k)]
        along = sum(acc[i] * v[i] for i in range(k)) / speed
        if line:
            # Accelerated along the velocity itself, it keeps its direction. The components'
            # own update (friction across it, no gravity across) would scale the round-off
            # across by 1 - c h / |v|, below -1 near a stop: a reversal (a full stress run).
            acc = [along * v[i] / speed for i in range(k)]
        if along < 0.0:
            t_stop = speed / -along
            if t_stop < h:
                # Friction stops the part within the sub-step; it never reverses it.
                for i in range(k):
                    x[i] += v[i] * t_stop + 0.5 * acc[i] * t_stop * t_stop
                    v[i] = 0.0
                h -= t_stop
                if until_stop:
                    return h
                continue
        for i in range(k):
            x[i] += v[i] * h + 0.5 * acc[i] * h * h
            v[i] += acc[i] * h
        return 0.0
    return 0.0


def _euler_substep(x: list[float], v: list[float], h: float, gt: tuple[float, ...],
                   n_load: float, fs: float, fd: float) -> None:
    """One semi-implicit Euler sub-step (``v += a h; x += v h``); edits x, v in place."""
    k = len(x)
    speed = math.sqrt(sum(c * c for c in v))
    if speed == 0.0:
        acc = _from_rest(gt, n_load, fs, fd)
        if acc is not None:
            for i in range(k):
                v[i] = acc[i] * h
                x[i] += v[i] * h
        return
    friction = fd * n_load / speed
    new = [v[i] + h * (gt[i] - friction * v[i]) for i in range(k)]
    if sum(a * b for a, b in zip(new, v)) <= 0.0:
        # Friction would turn it back: it stops, and stays where it was in this sub-step.
        for i in range(k):
            v[i] = 0.0
        return
    for i in range(k):
        v[i] = new[i]
        x[i] += new[i] * h


# Below these ratios the friction direction does not turn measurably within a sub-step (the
# velocity is along g_t to 1e-12 rad, or g_t is 1e-12 of the friction), and the constant-
# acceleration update is exact to round-off; the closed form would need u0^4 ~ 1e48.
_PARALLEL: Final = 1e-12
# A speed below this fraction of what a sub-step's accelerations add is treated as rest: for
# a part that accelerates from it, e^{2|a| lambda} ~ (speed gained / speed)^2 in the closed
# form would overflow.
_TINY_SPEED: Final = 1e-100


def _plane_flow(x: list[float], v: list[float], h: float, gt: tuple[float, ...], gmag: float,
                c: float, s0: float) -> float:
    """Exact flow of ``v' = g_t - c v/|v|`` in a plane over ``h`` (``g_t``, ``c`` constant).

    With ``psi`` the angle from ``g_t`` to ``v``, ``u = tan(psi/2)`` and ``k = c/|g_t|`` the
    equations separate: ``|v| ~ u^(k-1) (1 + u^2)`` along the trajectory, and time and
    both position components are sums of powers of ``u``. In ``lambda = ln(u0/u)``
    (``a = k - 1``, ``b = k + 1``, ``w = 1 + u0^2``, ``L(m) = (1 - e^{-m lambda})/m``):

      t       = s0/(|g_t| w)      (L(a) + u0^2 L(b))
      x_along = s0^2/(|g_t| w^2)  (L(2a) - u0^4 L(2b))
      x_perp  = 2 s0^2/(|g_t| w^2)(u0 L(2a+1) + u0^3 L(2b-1))
      v_along = s0 e^{-a lambda} (1 - u0^2 e^{-2 lambda})/w,  v_perp = 2 s0 u0 e^{-(a+1) lambda}/w

    ``psi`` only shrinks: the part turns downhill. For ``k > 1`` it stops at ``lambda = inf``,
    ``t_stop = s0/(|g_t| w) (1/a + u0^2/b)``, moving downhill at that instant. ``lambda(h)``
    comes from a safeguarded Newton iteration on ``t`` (monotone in lambda). Edits x, v in
    place; returns the time left after a stop within the sub-step (0.0 when it does not stop).
    """
    e1x, e1y = gt[0] / gmag, gt[1] / gmag
    vp = v[0] * e1x + v[1] * e1y
    vq = v[1] * e1x - v[0] * e1y
    if vq < 0.0:
        e2x, e2y, vq = e1y, -e1x, -vq
    else:
        e2x, e2y = -e1y, e1x
    u0 = vq / (s0 + vp) if vp >= 0.0 else (s0 - vp) / vq
    u2 = u0 * u0
    w = 1.0 + u2
    a = c / gmag - 1.0
    b = a + 2.0
    at = s0 / (gmag * w)
    ax = s0 * s0 / (gmag * w * w)
    if a > 0.0:
        t_stop = at * (1.0 / a + u2 / b)
        if t_stop <= h:
            # Friction stops the part within the sub-step; it never reverses it.
            along = ax * (0.5 / a - u2 * u2 * 0.5 / b)
            perp = 2.0 * ax * (u0 / (2.0 * a + 1.0) + u2 * u0 / (2.0 * b - 1.0))
            x[0] += along * e1x + perp * e2x
            x[1] += along * e1y + perp * e2y
            v[0] = v[1] = 0.0
            return h - t_stop
    # Start from t(lambda) to second order: t'(0) = s0/|g_t|, t''(0) = -at (a + u0^2 b).
    d1, d2 = s0 / gmag, -at * (a + u2 * b)
    disc = d1 * d1 + 2.0 * d2 * h
    lam = 2.0 * h / (d1 + math.sqrt(disc)) if disc > 0.0 else h / d1
    lo, hi = 0.0, math.inf
    if a < 0.0:
        # t >= at L(a) bounds lambda; Newton on this convex part would overshoot (overflow).
        hi = math.log1p(-a * h / at) / -a
        lam = min(lam, hi)
    for _ in range(200):
        ea = math.expm1(-a * lam)
        eb = math.expm1(-b * lam)
        la = -ea / a if a != 0.0 else lam
        r = at * (la - u2 * eb / b) - h
        if r < 0.0:
            lo = lam
        elif r > 0.0:
            hi = lam
        else:
            break
        step = -r / (at * (1.0 + ea + u2 * (1.0 + eb)))
        if abs(step) <= 1e-15 * lam:
            lam += step
            break
        lam += step
        if not lo < lam < hi:
            lam = 0.5 * (lo + hi) if hi < math.inf else 2.0 * lo
    # L(m) for the positions; 2b and 2b - 1 are positive, 2a and 2a + 1 may be zero.
    l2a = -math.expm1(-2.0 * a * lam) / (2.0 * a) if a != 0.0 else lam
    l2a1 = -math.expm1(-(2.0 * a + 1.0) * lam) / (2.0 * a + 1.0) if a != -0.5 else lam
    along = ax * (l2a + u2 * u2 * math.expm1(-2.0 * b * lam) / (2.0 * b))
    perp = 2.0 * ax * (u0 * l2a1 - u2 * u0 * math.expm1(-(2.0 * b - 1.0) * lam) / (2.0 * b - 1.0))
    ea = math.exp(-a * lam) * s0 / w
    e2 = math.exp(-2.0 * lam)
    v_along = ea * (1.0 - u2 * e2)
    v_perp = 2.0 * ea * u0 * math.exp(-lam)
    x[0] += along * e1x + perp * e2x
    x[1] += along * e1y + perp * e2y
    v[0] = v_along * e1x + v_perp * e2x
    v[1] = v_along * e1y + v_perp * e2y
    return 0.0


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


# The composition's sub-step stages, by (scheme, sub-step, damping): a turning part's are
# the same frame after frame (a tracker's 60 Hz frames differ by a nanosecond at most), so
# they are made once, not 7 tuples of 3 new floats and 7 exponentials a frame (the object
# census, tools/object_census.py: ``turn`` was the step's largest maker after the encoder).
# The same operations on the same values: the same bits.
_STAGES: dict[tuple[str, float, float], list[tuple[float, float, float]]] = {}
_STAGES_AT_MOST: Final = 64


def _turn_stages(integrator: str, h: float, damping: float) -> list[tuple[float, float, float]]:
    key = (integrator, h, damping)
    stages = _STAGES.get(key)
    if stages is None:
        stages = [(w * h, 0.5 * w * h, math.exp(-0.5 * damping * w * h))
                  for w in _TURN_WEIGHTS[integrator]]
        if len(_STAGES) >= _STAGES_AT_MOST:
            _STAGES.clear()
        _STAGES[key] = stages
    return stages


def turn(force: TurnForce, theta: float, omega: float, dt: float, steps: int,
         integrator: str, frame_dt: float = 0.0) -> tuple[float, float]:
    """Advance (theta, omega) over a frame of ``dt`` seconds in ``steps`` sub-steps; with
    ``frame_dt``, over the first ``dt`` seconds of a frame of ``frame_dt`` (the force's
    gravity path is the frame's: ``turning_point``)."""
    if integrator == "paper":
        alpha = force.alpha(theta, 1.0 if frame_dt == 0.0 else dt / frame_dt) \
            - force.damping * omega
        return theta + omega * dt + 0.5 * alpha * dt * dt, omega + alpha * dt
    h = dt / steps
    inv_dt = 1.0 / (dt if frame_dt == 0.0 else frame_dt)
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
    if integrator == "euler":
        decay = math.exp(-force.damping * h)
        for i in range(steps):
            omega = omega * decay + h * force.alpha(theta, i * h * inv_dt)
            theta += h * omega
        return theta, omega
    stages = _turn_stages(integrator, h, force.damping)
    t = 0.0
    alpha = force.alpha(theta, 0.0)
    # The hot loop of a turning part: ``force.alpha(theta, t * inv_dt)`` written out, the
    # same operations in the same order (so the same bits), without a method call and its
    # eight attribute loads per evaluation. ``math.cos`` by name: compiled, a C call.
    a0, a1, a2, b0, b1, b2, phi = (force.a0, force.a1, force.a2, force.b0, force.b1, force.b2,
                                   force.phi)
    for _ in range(steps):
        for wh, half, decay in stages:
            omega = (omega * decay + half * alpha)
            theta += wh * omega
            t += wh
            if phi == 0.0:
                alpha = a0 * math.cos(theta) - b0 * math.sin(theta)
            else:
                tau = t * inv_dt
                c, s = math.cos(-tau * phi), math.sin(-tau * phi)
                k = 1.0 - c
                alpha = ((a0 * c + a1 * s + a2 * k) * math.cos(theta)
                         - (b0 * c + b1 * s + b2 * k) * math.sin(theta))
            omega = (omega + half * alpha) * decay
    return theta, omega

# The commutator-free fourth-order scheme of Blanes and Moan (2006) with two exponentials:
# flows of h/2 under (w_main F(t_early) + w_back F(t_late)), then under the weights swapped,
# F(t) the sliding equations with gravity frozen at t, t_early and t_late the Gauss nodes.
_CF4_EARLY: Final = 0.5 - math.sqrt(3.0) / 6.0
_CF4_LATE: Final = 0.5 + math.sqrt(3.0) / 6.0
_CF4_MAIN: Final = 0.5 + math.sqrt(3.0) / 3.0
_CF4_BACK: Final = 0.5 - math.sqrt(3.0) / 3.0


def turning_point(force: TurnForce, theta: float, omega: float, dt: float,
                  max_step_s: float, integrator: str) -> tuple[float, float]:
    """``(s, theta)``: the fraction of a frame of ``dt`` at which a swing that turned back
    within it (``omega`` at its start, the other sign or zero at its end) comes to rest,
    and its angle there, by bisection on the fraction, each trial integrated from the
    frame's start as the frame is (sub-steps of at most ``max_step_s``). A holding torque
    stops the part there (``step._slide_and_turn``): stopped at the frame's end, it had
    swung back by up to ``alpha dt^2 / 2`` (a physics audit: 0.012 rad at 60 Hz)."""
    lo, hi = 0.0, 1.0
    theta_hi = theta
    for _ in range(48):  # to ~4e-15 of the frame
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        span = mid * dt
        a, w = turn(force, theta, omega, span, substeps(span, max_step_s), integrator, dt)
        if w * omega > 0.0:
            lo = mid
        else:
            hi, theta_hi = mid, a
    if hi == 1.0:  # (every trial still turning: the stop is at the frame's end)
        theta_hi = turn(force, theta, omega, dt, substeps(dt, max_step_s), integrator)[0]
    return hi, theta_hi


def substeps(dt: float, max_step_s: float) -> int:
    return max(1, math.ceil(dt / max_step_s - 1e-9))


def slide(mate_kind: str, normals: tuple[sp.Vec3, ...], axis: sp.Vec3 | None,
          dirs: tuple[sp.Vec3, ...], path: GravityPath, x: tuple[float, ...],
          v: tuple[float, ...], dt: float, steps: int, *, f_static: float, f_dynamic: float,
          blocked: tuple[float, ...], integrator: str,
          located: bool = True) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Advance the slide coordinates ``x`` and rates ``v`` over a frame of ``dt`` seconds.

    ``located`` (physics ``slide_onset: "located"``, the default): the instants where the part
    stops and starts to slip are found within the sub-step. Without it (``"sub_step"``, how
    recordings were made before 2026-11-22): a sub-step's held gravity decides a part at
    rest for the whole sub-step, and after a stop for the rest of it."""
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
    if integrator == "euler":
        for i in range(steps):
            g = path.at((i + 0.5) / steps)
            n_load, _ = normal_load(mate_kind, normals, axis, g)
            gt = project_blocked(tangential(dirs, g), blocked)
            _euler_substep(xs, vs, h, gt, n_load, f_static, f_dynamic)
        return tuple(xs), tuple(vs)
    if not located:
        for i in range(steps):
            if integrator == "analytic4":
                _flow(integrator, xs, vs, path, i / steps, (i + 1) / steps, dt, mate_kind,
                      normals, axis, dirs, blocked, f_static, f_dynamic, False)
                continue
            g = path.at((i + 0.5) / steps)
            n_load, _ = normal_load(mate_kind, normals, axis, g)
            gt = project_blocked(tangential(dirs, g), blocked)
            _slide_substep(xs, vs, h, gt, n_load, f_static, f_dynamic, integrator == "analytic")
        return tuple(xs), tuple(vs)
    # analytic, analytic4, midpoint: sub-step by sub-step, with the instants where friction
    # stops the part and where it starts to slip again located within the sub-step.
    for i in range(steps):
        a, b = i / steps, (i + 1) / steps
        tau = a
        for _ in range(_MAX_EVENTS):
            if not any(c != 0.0 for c in vs):
                tau = _onset(path, tau, b, mate_kind, normals, axis, dirs, blocked,
                             f_static, f_dynamic)
                if tau < 0.0:
                    break
            left = _flow(integrator, xs, vs, path, tau, b, dt, mate_kind, normals, axis, dirs,
                         blocked, f_static, f_dynamic)
            if left <= 0.0:
                break
            tau = b - left
            if tau >= b:
                break
    return tuple(xs), tuple(vs)


# Stops and starts located within one sub-step, at most (a part chattering between stick
# and slip faster than this rests for the rest of the sub-step).
_MAX_EVENTS: Final = 8


def _drive_at(path: GravityPath, tau: float, mate_kind: str, normals: tuple[sp.Vec3, ...],
              axis: sp.Vec3 | None, dirs: tuple[sp.Vec3, ...],
              blocked: tuple[float, ...]) -> tuple[tuple[float, ...], float]:
    """Gravity along the slide directions (less what a wall holds) and the normal load, at
    ``tau`` of the frame."""
    g = path.at(tau)
    n_load, _ = normal_load(mate_kind, normals, axis, g)
    return project_blocked(tangential(dirs, g), blocked), n_load


def _slips(path: GravityPath, tau: float, mate_kind: str, normals: tuple[sp.Vec3, ...],
           axis: sp.Vec3 | None, dirs: tuple[sp.Vec3, ...], blocked: tuple[float, ...],
           fs: float, fd: float) -> bool:
    """Whether a part at rest at ``tau`` starts to slide (``_from_rest``'s test)."""
    gt, n_load = _drive_at(path, tau, mate_kind, normals, axis, dirs, blocked)
    gmag = math.sqrt(sum(c * c for c in gt))
    return gmag > fs * n_load and gmag > fd * n_load


def _onset(path: GravityPath, a: float, b: float, mate_kind: str,
           normals: tuple[sp.Vec3, ...], axis: sp.Vec3 | None, dirs: tuple[sp.Vec3, ...],
           blocked: tuple[float, ...], fs: float, fd: float) -> float:
    """When a part at rest from ``a`` starts to slip within ``[a, b]`` (frame fractions), or
    -1.0 if static friction holds there. Sampled at a, the middle and b (the turn of the
    base within a sub-step is small and smooth), then the first slipping sample is bisected
    down to round-off: the onset is not rounded to a sub-step, which would make the whole
    slide after it first order in the step, whatever the scheme."""
    if _slips(path, a, mate_kind, normals, axis, dirs, blocked, fs, fd):
        return a
    mid = 0.5 * (a + b)
    if _slips(path, mid, mate_kind, normals, axis, dirs, blocked, fs, fd):
        hi = mid
    elif _slips(path, b, mate_kind, normals, axis, dirs, blocked, fs, fd):
        hi = b
    else:
        return -1.0
    lo = a
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if _slips(path, mid, mate_kind, normals, axis, dirs, blocked, fs, fd):
            hi = mid
        else:
            lo = mid
    return hi


def _flow(integrator: str, xs: list[float], vs: list[float], path: GravityPath, a: float,
          b: float, dt: float, mate_kind: str, normals: tuple[sp.Vec3, ...],
          axis: sp.Vec3 | None, dirs: tuple[sp.Vec3, ...], blocked: tuple[float, ...],
          fs: float, fd: float, until_stop: bool = True) -> float:
    """The scheme over ``[a, b]`` of the frame from the present state (edits xs, vs);
    returns the part of the frame left when friction stopped the part (0.0: done). Without
    ``until_stop`` the held gravity decides the rest of the interval after a stop."""
    if integrator == "analytic4":
        if not until_stop:
            return _cf4(xs, vs, path, a, b, dt, mate_kind, normals, axis, dirs, blocked, fs,
                        fd, False)
        x0, v0 = list(xs), list(vs)
        if _cf4(xs, vs, path, a, b, dt, mate_kind, normals, axis, dirs, blocked, fs, fd,
                True) <= 0.0:
            return 0.0
        # Friction stopped it within [a, b]. The instant one half-flow gives is of low
        # order (its combined gravity is only right together with the other half's), so
        # the instant is bisected on the whole scheme: the latest t at which [a, t] in
        # one step still moves. There the speed is ~0 and the position fourth order.
        lo, hi = a, b
        x_lo = list(x0)
        for _ in range(_STOP_BISECTIONS):
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
            xt, vt = list(x0), list(v0)
            if _cf4(xt, vt, path, a, mid, dt, mate_kind, normals, axis, dirs, blocked, fs,
                    fd, True) > 0.0:
                hi = mid
            else:
                lo, x_lo = mid, xt
        for k in range(len(xs)):
            xs[k] = x_lo[k]
            vs[k] = 0.0
        return b - hi
    # analytic, midpoint: gravity held at the middle of the interval.
    h = (b - a) * dt
    gt, n_load = _drive_at(path, 0.5 * (a + b), mate_kind, normals, axis, dirs, blocked)
    return _slide_substep(xs, vs, h, gt, n_load, fs, fd, integrator == "analytic", True) / dt


# Bisections of a stop instant within an analytic4 sub-step (to ~1e-12 of a frame).
_STOP_BISECTIONS: Final = 40


def _cf4(xs: list[float], vs: list[float], path: GravityPath, a: float, b: float, dt: float,
         mate_kind: str, normals: tuple[sp.Vec3, ...], axis: sp.Vec3 | None,
         dirs: tuple[sp.Vec3, ...], blocked: tuple[float, ...], fs: float, fd: float,
         until_stop: bool) -> float:
    """analytic4 over ``[a, b]``: two exact flows of h/2 under gravity (drive and normal
    load) combined from the two Gauss nodes (``_CF4_*``). Returns the part of the frame
    left after a stop in a half-flow (with ``until_stop``), else 0.0."""
    h = (b - a) * dt
    gt_a, n_a = _drive_at(path, a + _CF4_EARLY * (b - a), mate_kind, normals, axis, dirs,
                          blocked)
    gt_b, n_b = _drive_at(path, a + _CF4_LATE * (b - a), mate_kind, normals, axis, dirs,
                          blocked)
    for half in range(2):
        w_a, w_b = (_CF4_MAIN, _CF4_BACK) if half == 0 else (_CF4_BACK, _CF4_MAIN)
        gt = tuple([w_a * gt_a[k] + w_b * gt_b[k] for k in range(len(gt_a))])
        left = _slide_substep(xs, vs, 0.5 * h, gt, max(0.0, w_a * n_a + w_b * n_b), fs, fd,
                              True, until_stop)
        if left > 0.0:
            return (left + (0.5 * h if half == 0 else 0.0)) / dt
    return 0.0
