"""Release velocity from held poses: known throws, tracker noise, duplicated samples."""

from __future__ import annotations

import math

import numpy as np

from vade_replay import spatial as sp
from vade_replay.dynamics import velocity

RATE = 60
V_TRUE = np.array([1.2, -0.4, 2.0])
W_TRUE = np.array([0.5, 3.0, -1.0])


def _history(rng, *, pos_std, rot_std, n=8, t0_ns=10**9):
    out = []
    q0 = sp.quat_from_euler_deg(10.0, -20.0, 30.0)
    for k in range(n):
        t_ns = t0_ns + k * 10**9 // RATE
        t = (t_ns - t0_ns) * 1e-9
        p = np.array([0.1, 0.2, 1.0]) + V_TRUE * t + rng.normal(0.0, pos_std, 3)
        q = sp.quat_mul(sp.quat_from_rotvec(tuple(W_TRUE * t)), q0)
        q = sp.quat_mul(sp.quat_from_rotvec(tuple(rng.normal(0.0, rot_std, 3))), q)
        out.append((t_ns, tuple(float(x) for x in p), sp.quat_normalize(q)))
    return tuple(out)


def test_exact_without_noise():
    history = _history(np.random.default_rng(0), pos_std=0.0, rot_std=0.0)
    for method in ("window_fit", "two_frame"):
        v, w = velocity.estimate(history, method=method, window=5)
        assert np.allclose(v, V_TRUE, atol=1e-9)
        assert np.allclose(w, W_TRUE, atol=1e-9)


def test_window_fit_beats_two_frames_under_tracker_noise():
    # 1 mm and 0.2 degree of tracker noise, 200 throws.
    pos_std, rot_std = 1e-3, math.radians(0.2)
    rng = np.random.default_rng(42)
    errors = {"window_fit": [[], []], "two_frame": [[], []]}
    for _ in range(200):
        history = _history(rng, pos_std=pos_std, rot_std=rot_std)
        for method in errors:
            v, w = velocity.estimate(history, method=method, window=5)
            errors[method][0].append(np.linalg.norm(np.array(v) - V_TRUE))
            errors[method][1].append(np.linalg.norm(np.array(w) - W_TRUE))
    rms = {m: [math.sqrt(np.mean(np.square(e))) for e in errs] for m, errs in errors.items()}
    # Two frames: error ~ sqrt(2) * std * rate * sqrt(3) = 0.147 m/s.
    # A 5-point line fit: std * sqrt(3 / sum((t - mean)^2)) ~ 0.037 m/s in 3-D.
    assert rms["window_fit"][0] < 0.06
    assert rms["window_fit"][0] < 0.4 * rms["two_frame"][0]
    assert rms["window_fit"][1] < 0.4 * rms["two_frame"][1]
    assert rms["two_frame"][0] > 0.1  # the paper's estimate really does amplify the noise


def test_duplicated_timestamps_do_not_divide_by_zero():
    sample = (10**9, (0.0, 0.0, 1.0), sp.IDENTITY_QUAT)
    for method in ("window_fit", "two_frame"):
        v, w = velocity.estimate((sample, sample, sample), method=method, window=5)
        assert v == sp.ZERO3 and w == sp.ZERO3
    # A duplicate inside a window still leaves a finite, correct fit.
    history = list(_history(np.random.default_rng(1), pos_std=0.0, rot_std=0.0))
    history.insert(4, history[3])
    v, w = velocity.estimate(tuple(history), method="window_fit", window=5)
    assert np.allclose(v, V_TRUE, atol=1e-9) and np.allclose(w, W_TRUE, atol=1e-9)
    # The paper's two-frame estimate over a duplicated last sample gives zero, not inf.
    v, w = velocity.estimate(tuple(history[:5]), method="two_frame", window=5)
    assert v == sp.ZERO3
