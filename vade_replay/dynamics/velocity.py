"""Velocities of a held part from its recent poses (paper 5.1, NOTES.md).

``two_frame`` is the paper's estimate from the last two poses. ``window_fit`` fits a
straight line, by least squares, to the last ``window`` positions and rotation vectors
(taken relative to the newest orientation) and returns the slopes: tracker noise is
averaged instead of amplified. Samples with equal timestamps (a duplicated tracker sample)
carry no rate information; when the samples span no time, the velocity is zero rather than
a division by zero.
"""

from __future__ import annotations

from .. import spatial as sp

Sample = tuple[int, sp.Vec3, sp.Quat]  # time_ns, world CM, world rotation of the part


def _slope(times: list[float], values: list[sp.Vec3]) -> sp.Vec3:
    n = len(times)
    t_mean = sum(times) / n
    denom = sum((t - t_mean) ** 2 for t in times)
    if denom <= 0.0:
        return sp.ZERO3
    out = []
    for axis in range(3):
        v_mean = sum(v[axis] for v in values) / n
        out.append(sum((t - t_mean) * (v[axis] - v_mean) for t, v in zip(times, values)) / denom)
    return (out[0], out[1], out[2])


def estimate(history: tuple[Sample, ...], *, method: str, window: int) -> tuple[sp.Vec3, sp.Vec3]:
    """Linear and angular velocity (world) at the newest sample of ``history``."""
    if len(history) < 2:
        return sp.ZERO3, sp.ZERO3
    if method == "two_frame":
        samples = history[-2:]
    else:
        samples = history[-window:]
    t_last, _, q_last = samples[-1]
    inv_last = sp.quat_conj(q_last)
    times = [(t - t_last) * 1e-9 for t, _, _ in samples]
    positions = [p for _, p, _ in samples]
    # World-frame rotation vectors relative to the newest orientation: for a constant
    # angular velocity w they are exactly (t - t_last) w.
    rotvecs = [sp.quat_to_rotvec(sp.quat_mul(q, inv_last)) for _, _, q in samples]
    return _slope(times, positions), _slope(times, rotvecs)
