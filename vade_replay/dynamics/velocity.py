"""Velocities of a held part from its recent poses (paper 5.1, NOTES.md).

``two_frame`` is the paper's estimate from the last two poses: the velocity at the middle
of the last interval, with the tracker noise amplified by ``sqrt(2) / dt``.

``window_fit_stops`` (the default since 2026-11-23) is ``window_fit``, except where its
slope points back against the way the hand went over the window and the last step nearly
stood still: there the slope of the line through the last three samples. A hand carried at 1 m/s that
stops three frames before opening was read as throwing the part back at 0.36 m/s (an
engineer's trial), the quadratic through the motion and the stop overshooting it; a throw
from a backswing (its slope against the window's way too) moves in its last step and is
kept.

``window_fit_corners`` (the default since 2026-11-23, fourth session) is
``window_fit_stops``, except where the hand's last three steps are steady and the fit is
off their mean by more than four times their scatter (``_unless_cornered``): the hand's
path turned a corner within the window, which the quadratic spans and overshoots. There
the slope of the line through the last four samples. Keyframes are joined by straight
lines, so a keyframed hand turns in one frame: a researcher's trial let a pin go three
frames after the hand turned straight down at 0.17 m/s, and it flew at 0.5 m/s, sideways
too. A tracked hand does not turn so: its steps change by ``a dt`` each, and the fit's lag
to their mean is ~1.5 of that.

``window_fit`` fits a quadratic in time, by least squares, to the last ``window`` positions
and rotation vectors (taken relative to the newest orientation), and returns its slope at
the newest sample. A straight line would be the velocity at the middle of the window and lag
a hand that accelerates into the throw (by ``a * span / 2``: 0.67 m/s at 20 m/s^2 over five
60 Hz samples); the quadratic has no lag under constant acceleration, and over seven samples
it still halves the two-frame noise (gain 0.68/dt against 1.41/dt).

Samples with equal timestamps (a duplicated tracker sample), or closer than 0.5 ms, carry
noise rather than rate: only the newest of them is used. With fewer than three distinct times
the fit is a line, with fewer than two the velocity is zero, never a division by zero.
Rotation vectors are unwrapped (summed frame-to-frame steps), so spins of any speed that turn
less than half a turn per frame are measured right.
"""

from __future__ import annotations

import math
from typing import Final

from .. import spatial as sp

Sample = tuple[int, sp.Vec3, sp.Quat]  # time_ns, world CM, world rotation of the part


# Samples closer than this to the next one carry noise, not rate: 0.5 ms, half the interval
# of a 1 kHz tracker.
MIN_INTERVAL_NS: Final = 500_000


# Samples travel as plain Python tuples (``tuple``, ``list``: items typed Any). Typed as
# ``Sample``, the compiled build would unpack every one into a C struct and build it again
# as a new tuple of new floats wherever it is stored (``_distinct``: 2.5x slower than as
# Python).
def _distinct(history: tuple) -> list:
    """Oldest first; of samples closer together than MIN_INTERVAL_NS, only the newest."""
    out: list = []
    last_t = 0  # (the time of out[-1]: a typed int, where the sample's are Python objects)
    for item in history:
        sample: tuple = item  # (a tuple: compiled, indexed in C, not as any object)
        t: int = sample[0]
        if out and t - last_t < MIN_INTERVAL_NS:
            out[-1] = sample
        else:
            out.append(sample)
        last_t = t
    return out


def _moments(times: list[float]) -> tuple[float, float, float, float, float]:
    """Sums of t^k and the determinant of the normal equations of x(t) = c0 + c1 t + c2 t^2
    (the same for every coordinate and for both velocities). Each sum is added from 0.0 in
    sample order, the bits of ``sum`` on Python 3.11 (3.12's ``sum`` compensates, which
    this does not, so the bits do not depend on the Python). Computed afresh: compiled,
    the ``lru_cache`` that held them cost more in hashing its key than the sums."""
    n = len(times)
    s1 = s2 = s3 = s4 = 0.0
    for t in times:
        s1 += t
        s2 += t * t
        s3 += t * t * t
        s4 += t * t * t * t
    det = n * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s3 * s2) + s2 * (s1 * s3 - s2 * s2)
    return s1, s2, s3, s4, det


def _turn_between(older: tuple, newer: tuple) -> sp.Vec3:
    """Rotation vector from ``newer`` to ``older`` (world axes). (Plain tuples, as in
    ``_distinct``.) Computed afresh each time a pair is met as the window slides:
    compiled, a cache keyed by the pair's packed bits cost twice the computation."""
    return sp.quat_to_rotvec(sp.quat_mul(older, sp.quat_conj(newer)))


def new_sample(history: tuple, t_ns: int, cm: sp.Vec3, rotation: sp.Quat) -> tuple:
    """A held part's new sample for its ``history``: ``(t_ns, cm, rotation)``, and where
    there is a sample before it, that one's time, the turn back to it (``_turn_between``)
    and its rotation (the same object), which ``estimate`` would otherwise work out again
    in every frame the two stay in its window (a window of seven: six turns a frame, each
    a Python call of ``atan2``, compiled). ``estimate`` uses the turn only between the two
    samples it was taken of (``_distinct`` may drop the one before; a tracker whose time
    steps back can bring another sample of that time next to it: the rotation tells them
    apart), so a history of plain ``(t_ns, cm, rotation)`` samples, or a mix, gives the
    same bits."""
    if not history:
        return (t_ns, cm, rotation)
    before = history[-1]
    q_before = before[2]
    return (t_ns, cm, rotation, before[0], _turn_between(q_before, rotation), q_before)


def _slope_at_zero(times: list[float], values: list[sp.Vec3],
                   moments: tuple[float, float, float, float, float]) -> sp.Vec3:
    """d/dt at t = 0 of the least-squares polynomial (degree 2, or 1 for two points);
    ``moments`` are ``_moments(times)`` (used for three points or more), shared by the
    linear and the angular velocity."""
    n = len(times)
    if n < 2:
        return sp.ZERO3
    if n == 2:
        dt = times[1] - times[0]
        return sp.scale(sp.sub(values[1], values[0]), 1.0 / dt)
    s1, s2, s3, s4, det = moments
    if det == 0.0:
        return sp.ZERO3
    # sum(v), sum(t v), sum(t t v) of each coordinate in sample order, as (t * t) * v: each
    # product rounded, then added from 0.0 in order, the bits of sum(map(mul, ...)). The
    # three coordinates are summed side by side, each sample read once (compiled, reading
    # a Vec3 out of the list unpacks it: once a sample, not once a coordinate).
    a0 = a1 = a2 = b0 = b1 = b2 = c0 = c1 = c2 = 0.0
    for i in range(n):
        v0, v1, v2 = values[i]
        t = times[i]
        tt = t * t
        a0 += v0
        b0 += t * v0
        c0 += tt * v0
        a1 += v1
        b1 += t * v1
        c1 += tt * v1
        a2 += v2
        b2 += t * v2
        c2 += tt * v2
    return (_coefficient(n, a0, b0, c0, s1, s2, s3, s4) / det,
            _coefficient(n, a1, b1, c1, s1, s2, s3, s4) / det,
            _coefficient(n, a2, b2, c2, s1, s2, s3, s4) / det)


def _coefficient(n: int, y0: float, y1: float, y2: float, s1: float, s2: float, s3: float,
                 s4: float) -> float:
    """Cramer's numerator of the slope c1 of the normal equations."""
    return n * (y1 * s4 - s3 * y2) - y0 * (s1 * s4 - s3 * s2) + s2 * (s1 * y2 - y1 * s2)


def kept(history: tuple, window: int, span_ns: int) -> tuple:
    """The samples of ``history`` (oldest first) a fit needs: the last ``window``, and
    before them those within ``span_ns`` of the newest (``estimate``)."""
    n = len(history)
    if n <= window:
        return history
    first = n - window
    if span_ns > 0:
        newest: tuple = history[n - 1]
        t_new: int = newest[0]
        while first > 0:
            older: tuple = history[first - 1]
            t_old: int = older[0]
            if t_new - t_old > span_ns:
                break
            first -= 1
    return history[first:]


def spacing_ns(span_ns: int, window: int) -> float:
    """How far apart (ns) the samples a fit takes are at least: three quarters of a 60 Hz
    step for the defaults (``span_ns / (window - 1)``), so every frame at 60 Hz or less;
    0 without a span (``_spaced``, and the base's samples, ``step._base_sample``)."""
    if span_ns <= 0 or window < 2:
        return 0.0
    return 0.75 * span_ns / (window - 1)


def _spaced(samples: list, window: int, span_ns: int) -> list:
    """At most ``window`` of ``samples`` (oldest first), the newest and, going back, each
    at least three quarters of ``span_ns / (window - 1)`` before the one kept after it:
    the stream as the fit and its checks were made for, a frame every 1/60 s or more
    (every one at 60 Hz or less, where this is the last ``window``). Denser frames (a log
    of unaligned devices, a frame at every stamp: several between two of the hand's own
    samples, joined by straight lines) made the stop and corner checks take a hand's own
    noise between two samples for its steps (an engineer's trial: a still hand let go at
    0.08 m/s whatever the window)."""
    gap = spacing_ns(span_ns, window)
    if gap <= 0.0:
        return samples[-window:]
    out = [samples[-1]]
    newest: tuple = samples[-1]
    t_kept: int = newest[0]
    for i in range(len(samples) - 2, -1, -1):
        if len(out) >= window:
            break
        sample: tuple = samples[i]
        t: int = sample[0]
        if t_kept - t >= gap:
            out.append(sample)
            t_kept = t
    out.reverse()
    return out


def estimate(history: tuple, *, method: str, window: int,
             grip: sp.Vec3 = sp.ZERO3, span_ns: int = 0) -> tuple[sp.Vec3, sp.Vec3]:
    """Linear and angular velocity (world) of the part at the newest sample of ``history``.

    ``grip`` (part axes, from the centre of mass) is the point of the part the hand holds
    it by: its path is fitted, and the centre of mass's velocity is the rigid body's,
    ``v_grip + w x (cm - grip)``. A part turned in the hand moves its centre of mass on a
    circle about the grip, which the quadratic fits poorly (a physics audit: a gear spun
    on its bore at 10 rad/s let go 5.4 % fast); the grip point moves as the hand does.
    At ``(0, 0, 0)``, the centre of mass's own path, as before (the same bits).

    The fit takes the last ``window`` samples and, before them, those within ``span_ns``
    of the newest (``physics.release_span_s``): a tracker log of unaligned devices makes
    a frame at every device's stamp (330 a second for a headset at 90 Hz and two
    controllers at 120 Hz), where seven frames span 18 ms, about two of the hand's own
    samples, and the fit is their noise (an engineer's trial: a pin held still over its
    bore let go at 0.08 m/s sideways, and it missed). At 60 Hz the span is the window's."""
    samples = _distinct(kept(history, window, span_ns))
    if len(samples) < 2:
        return sp.ZERO3, sp.ZERO3
    samples = samples[-2:] if method == "two_frame" else _spaced(samples, window, span_ns)
    t_last: int = samples[-1][0]
    # Times in seconds before the newest sample; rotation vectors relative to the newest
    # orientation, in world axes: for a constant angular velocity w they are exactly t w.
    # (Each time read as a typed int: compiled, the arithmetic on the sample's own object
    # was a generic subtraction and multiplication, each a new object.)
    times: list[float] = []
    for item in samples:
        sample: tuple = item
        t: int = sample[0]
        times.append((t - t_last) * 1e-9)
    gripped = grip[0] != 0.0 or grip[1] != 0.0 or grip[2] != 0.0
    positions = [sample[1] for sample in samples] if not gripped else \
        [sp.add(sample[1], sp.quat_rotate(sample[2], grip)) for sample in samples]
    # Unwrapped: summed frame-to-frame steps (each under half a turn), so a spin faster than
    # half a turn per window is not folded back into [0, pi]. Newest pair first.
    rotvecs = [sp.ZERO3]
    for i in range(len(samples) - 1, 0, -1):
        newer: tuple = samples[i]
        older: tuple = samples[i - 1]
        # The turn kept with the newer sample (``new_sample``) where it was taken back to
        # this older one: the same time and the very rotation object.
        step: sp.Vec3 = newer[4] if len(newer) > 5 and newer[3] == older[0] \
            and newer[5] is older[2] else _turn_between(older[2], newer[2])
        rotvecs.append(sp.add(rotvecs[-1], step))
    rotvecs.reverse()
    moments = _moments(times)
    v = _slope_at_zero(times, positions, moments)
    w = _slope_at_zero(times, rotvecs, moments)
    if (method == "window_fit_stops" or method == "window_fit_corners") and len(samples) > 3:
        # A hand that stops: the quadratic through the motion and the stop overshoots it,
        # and its slope at the newest sample points back against the way the hand went
        # over the window. Then the line through the last three samples is the velocity
        # (zero for a hand that has rested two steps; its noise is the quadratic's, ~0.7
        # std / dt a coordinate, so a hand at rest, whose way is noise, loses nothing).
        v = _unless_overshot(v, positions, times)
        w = _unless_overshot(w, rotvecs, times)
        if method == "window_fit_corners" and len(samples) > 4:
            v = _unless_cornered(v, positions, times)
            w = _unless_cornered(w, rotvecs, times)
    if gripped:  # the centre of mass's: w x (cm - grip), the grip turned as the part is now
        v = sp.sub(v, sp.cross(w, sp.quat_rotate(samples[-1][2], grip)))
    return v, w


def _unless_cornered(fit: sp.Vec3, values: list[sp.Vec3], times: list[float]) -> sp.Vec3:
    """The fit's slope, or the line's through the last four samples where their three steps
    are steady and the fit is off their mean velocity by more than four times their scatter
    (the largest step's distance from the mean) and a hundredth of it: the path turned a
    corner within the window (``window_fit_corners``). A fit that is the line already (a
    straight stretch of keyframes) is left as it is. (Written out on floats: with lists of
    vectors it doubled the cost of every held part's velocity, ~2.7 us.)"""
    n = len(values)
    a0, a1, a2 = values[n - 4]
    b0, b1, b2 = values[n - 3]
    c0, c1, c2 = values[n - 2]
    d0, d1, d2 = values[n - 1]
    k = 1.0 / (times[n - 3] - times[n - 4])
    p0, p1, p2 = (b0 - a0) * k, (b1 - a1) * k, (b2 - a2) * k
    k = 1.0 / (times[n - 2] - times[n - 3])
    q0, q1, q2 = (c0 - b0) * k, (c1 - b1) * k, (c2 - b2) * k
    k = 1.0 / (times[n - 1] - times[n - 2])
    r0, r1, r2 = (d0 - c0) * k, (d1 - c1) * k, (d2 - c2) * k
    third = 1.0 / 3.0
    m0, m1, m2 = (p0 + q0 + r0) * third, (p1 + q1 + r1) * third, (p2 + q2 + r2) * third
    # (The largest as ``max`` takes it, written out: compiled, ``max`` is a Python call.)
    scatter = _length(p0 - m0, p1 - m1, p2 - m2)
    q_off = _length(q0 - m0, q1 - m1, q2 - m2)
    if q_off > scatter:
        scatter = q_off
    r_off = _length(r0 - m0, r1 - m1, r2 - m2)
    if r_off > scatter:
        scatter = r_off
    off = _length(fit[0] - m0, fit[1] - m1, fit[2] - m2)
    if off <= 4.0 * scatter + 0.01 * _length(m0, m1, m2) + 1e-9:
        return fit
    return _line_slope(times[-4:], values[-4:])


def _length(x: float, y: float, z: float) -> float:
    """``sp.norm((x, y, z))``, the same operations, on three floats."""
    return math.sqrt(x * x + y * y + z * z)


def _unless_overshot(fit: sp.Vec3, values: list[sp.Vec3], times: list[float]) -> sp.Vec3:
    """The fit's slope, or the line's through the last three samples where the fit points
    back against the window's way and the last step nearly stood still (under a quarter of
    the fit's speed): a stop. A throw from a backswing points back against the window's way
    too, but its last step moves (a review: 2 m/s after 60 m/s^2, a 10 rad/s flick after
    400 rad/s^2 were cut to their lagging line)."""
    if sp.dot(fit, sp.sub(values[-1], values[0])) >= 0.0:
        return fit
    step = sp.scale(sp.sub(values[-1], values[-2]), 1.0 / (times[-1] - times[-2]))
    if sp.dot(step, step) >= 0.0625 * sp.dot(fit, fit):
        return fit
    return _line_slope(times[-3:], values[-3:])


def _line_slope(times: list[float], values: list[sp.Vec3]) -> sp.Vec3:
    """Slope of the least-squares line through the samples (two or more distinct times).
    The values are taken from the newest, so that samples all equal give exactly zero."""
    n = len(times)
    mean_t = 0.0
    for t in times:
        mean_t += t
    mean_t /= n
    w0, w1, w2 = values[n - 1]
    stt = 0.0
    s0 = s1 = s2 = 0.0
    for i in range(n):
        dt = times[i] - mean_t
        v0, v1, v2 = values[i]
        stt += dt * dt
        s0 += dt * (v0 - w0)
        s1 += dt * (v1 - w1)
        s2 += dt * (v2 - w2)
    return (s0 / stt, s1 / stt, s2 / stt)
