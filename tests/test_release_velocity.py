"""Release velocity from held poses: known throws, tracker noise, duplicated samples."""

from __future__ import annotations

import math

import numpy as np

from vade_replay import spatial as sp
from vade_replay.dynamics import velocity

RATE = 60
V_TRUE = np.array([1.2, -0.4, 2.0])
W_TRUE = np.array([0.5, 3.0, -1.0])
WINDOW = 7  # the default


def _history(rng, *, pos_std, rot_std, n=10, accel=(0.0, 0.0, 0.0), alpha=(0.0, 0.0, 0.0),
             t0_ns=10**9):
    """Held poses ending at the release (the last sample), where the velocities are the true
    ones: position p(t) = v t + a t^2 / 2 and rotation angle w t + alpha t^2 / 2 about fixed
    axes, t <= 0 before the release."""
    out = []
    q0 = sp.quat_from_euler_deg(10.0, -20.0, 30.0)
    t_end = t0_ns + (n - 1) * 10**9 // RATE
    for k in range(n):
        t_ns = t0_ns + k * 10**9 // RATE
        t = (t_ns - t_end) * 1e-9
        p = np.array([0.1, 0.2, 1.0]) + V_TRUE * t + 0.5 * np.array(accel) * t * t \
            + rng.normal(0.0, pos_std, 3)
        angle = W_TRUE * t + 0.5 * np.array(alpha) * t * t
        q = sp.quat_mul(sp.quat_from_rotvec(tuple(angle)), q0)
        q = sp.quat_mul(sp.quat_from_rotvec(tuple(rng.normal(0.0, rot_std, 3))), q)
        out.append((t_ns, tuple(float(x) for x in p), sp.quat_normalize(q)))
    return tuple(out)


def test_exact_without_noise():
    history = _history(np.random.default_rng(0), pos_std=0.0, rot_std=0.0)
    for method in ("window_fit_corners", "window_fit_stops", "window_fit", "two_frame"):
        v, w = velocity.estimate(history, method=method, window=WINDOW)
        assert np.allclose(v, V_TRUE, atol=1e-9)
        assert np.allclose(w, W_TRUE, atol=1e-9)


def test_no_lag_when_the_hand_accelerates_into_the_throw():
    # 20 m/s^2 of hand acceleration at release: the two-frame difference is the velocity
    # half a frame earlier (off by a dt / 2 = 0.167 m/s); the quadratic fit has no lag.
    accel = (0.0, 0.0, 20.0)
    history = _history(np.random.default_rng(0), pos_std=0.0, rot_std=0.0, accel=accel)
    v_fit, _ = velocity.estimate(history, method="window_fit", window=WINDOW)
    v_two, _ = velocity.estimate(history, method="two_frame", window=WINDOW)
    assert np.allclose(v_fit, V_TRUE, atol=1e-9)
    assert abs(v_two[2] - V_TRUE[2] + 20.0 / RATE / 2) < 1e-6
    v_stops, _ = velocity.estimate(history, method="window_fit_stops", window=WINDOW)
    assert np.allclose(v_stops, V_TRUE, atol=1e-9)  # the fit agrees with the last steps
    # Nor is an acceleration a corner: its steps change by a dt each, the fit is ~1.5 of
    # that from their mean.
    v_corners, _ = velocity.estimate(history, method="window_fit_corners", window=WINDOW)
    assert v_corners == v_fit


def test_window_fit_beats_two_frames_under_tracker_noise():
    # 1 mm and 0.2 degree of tracker noise, 300 throws.
    pos_std, rot_std = 1e-3, math.radians(0.2)
    rng = np.random.default_rng(42)
    errors = {"window_fit": [[], []], "two_frame": [[], []], "window_fit_stops": [[], []],
              "window_fit_corners": [[], []]}
    for _ in range(300):
        history = _history(rng, pos_std=pos_std, rot_std=rot_std)
        for method in errors:
            v, w = velocity.estimate(history, method=method, window=WINDOW)
            errors[method][0].append(np.linalg.norm(np.array(v) - V_TRUE))
            errors[method][1].append(np.linalg.norm(np.array(w) - W_TRUE))
    rms = {m: [math.sqrt(np.mean(np.square(e))) for e in errs] for m, errs in errors.items()}
    # Noise gains per axis: two frames sqrt(2)/dt, a 7-point quadratic 0.68/dt; in 3-D
    # sqrt(3) * std * gain: 0.147 m/s and 0.071 m/s.
    assert rms["two_frame"][0] > 0.12
    assert rms["window_fit"][0] < 0.085
    assert rms["window_fit"][0] < 0.6 * rms["two_frame"][0]
    assert rms["window_fit"][1] < 0.6 * rms["two_frame"][1]
    # A throw is not a stop: the check leaves the fit (and its noise) alone. Nor a corner:
    # noise seldom makes three steps steadier than a quarter of their distance from the fit
    # (it did in none of the 300).
    assert rms["window_fit_stops"] == rms["window_fit"]
    assert rms["window_fit_corners"] == rms["window_fit"]


def _stopping_hand(rest_samples: int, rng=None, pos_std=0.0):
    """An engineer's trial: a hand carried at (-0.67, 0.33, 0.67) m/s that stops, and rests
    ``rest_samples`` frames before it opens; linear tracker interpolation between keyframes,
    as vade-record makes it."""
    v = np.array([-0.67, 0.33, 0.67])
    q = sp.quat_from_euler_deg(0.0, 0.0, 0.0)
    out = []
    for k in range(12):
        moving = min(k, 11 - rest_samples)
        p = np.array([0.05, -0.05, 1.15]) + v * moving / RATE
        if rng is not None:
            p = p + rng.normal(0.0, pos_std, 3)
        out.append((10**9 + k * 10**9 // RATE, tuple(float(x) for x in p), q))
    return tuple(out)


def test_a_hand_that_stops_before_it_opens_does_not_throw_the_part_back():
    """The quadratic through the carry and the stop overshoots: window_fit read the trial's
    hand, at rest for three frames, as moving back at 0.36 m/s. window_fit_stops takes the
    line through the last three samples where the fit points back against the hand's way
    over the window: zero once the hand has rested two steps."""
    back, _ = velocity.estimate(_stopping_hand(3), method="window_fit", window=WINDOW)
    assert np.dot(back, [-0.67, 0.33, 0.67]) < 0.0 and np.linalg.norm(back) > 0.3
    for rest in (3, 5):
        v, w = velocity.estimate(_stopping_hand(rest), method="window_fit_stops",
                                 window=WINDOW)
        assert v == (0.0, 0.0, 0.0) and w == (0.0, 0.0, 0.0)
    # Still moving at the release: untouched.
    moving, _ = velocity.estimate(_stopping_hand(0), method="window_fit_stops", window=WINDOW)
    assert np.allclose(moving, [-0.67, 0.33, 0.67], atol=1e-9)
    # With 0.3 mm of tracker noise a rested hand's part gets the noise of a 3-point line
    # (0.7 std / dt a coordinate: ~0.02 m/s), not the overshoot.
    rng = np.random.default_rng(5)
    speeds = [np.linalg.norm(velocity.estimate(_stopping_hand(3, rng, 3e-4),
                                               method="window_fit_stops", window=WINDOW)[0])
              for _ in range(200)]
    assert np.sqrt(np.mean(np.square(speeds))) < 0.05


def test_duplicated_timestamps_are_skipped_not_divided_by():
    sample = (10**9, (0.0, 0.0, 1.0), sp.IDENTITY_QUAT)
    for method in ("window_fit", "two_frame"):
        v, w = velocity.estimate((sample, sample, sample), method=method, window=WINDOW)
        assert v == sp.ZERO3 and w == sp.ZERO3
    history = list(_history(np.random.default_rng(1), pos_std=0.0, rot_std=0.0))
    # A duplicate inside the window, and one as the newest sample.
    history.insert(4, history[3])
    history.append(history[-1])
    for method in ("window_fit", "two_frame"):
        v, w = velocity.estimate(tuple(history), method=method, window=WINDOW)
        assert np.allclose(v, V_TRUE, atol=1e-9) and np.allclose(w, W_TRUE, atol=1e-9)


def test_fast_spins_are_not_folded_back():
    # 100 rad/s turns 1.67 rad per 60 Hz frame: more than half a turn over the window.
    global W_TRUE
    saved = W_TRUE
    try:
        for spin in (35.0, 60.0, 100.0):
            W_TRUE = np.array([0.0, spin, 0.0])
            history = _history(np.random.default_rng(0), pos_std=0.0, rot_std=0.0)
            for method in ("window_fit", "two_frame"):
                _, w = velocity.estimate(history, method=method, window=WINDOW)
                assert np.allclose(w, W_TRUE, atol=1e-6), (spin, method, w)
    finally:
        W_TRUE = saved


def test_samples_microseconds_apart_do_not_make_huge_velocities():
    history = list(_history(np.random.default_rng(2), pos_std=0.0, rot_std=0.0))
    t, p, q = history[-1]
    history.append((t + 1000, (p[0] + 5e-4, p[1], p[2]), q))  # 1 us later, 0.5 mm of noise
    v, _ = velocity.estimate(tuple(history), method="window_fit", window=WINDOW)
    assert np.linalg.norm(np.array(v) - V_TRUE) < 0.1


def test_a_throw_from_a_backswing_is_not_taken_for_a_stop():
    """A review: a throw whose window starts in the backswing (the hand's way over the
    window points back, the throw forward) was cut to the lagging line of its last three
    samples (2 m/s read as 1.0, a 10 rad/s flick as 3.3). Its last step moves, so the fit
    stands: exact, as window_fit's, for motion quadratic in time."""
    def flick(v0, a, w0=(0.0, 0.0, 0.0), alpha=(0.0, 0.0, 0.0), n=10):
        out, t_end = [], 10**9 + (n - 1) * 10**9 // RATE
        for k in range(n):
            t_ns = 10**9 + k * 10**9 // RATE
            t = (t_ns - t_end) * 1e-9
            p = np.array([0.1, 0.2, 1.2]) + np.array(v0) * t + 0.5 * np.array(a) * t * t
            angle = np.array(w0) * t + 0.5 * np.array(alpha) * t * t
            out.append((t_ns, tuple(float(x) for x in p),
                        sp.quat_normalize(sp.quat_from_rotvec(tuple(angle)))))
        return tuple(out)
    for accel in (30.0, 45.0, 60.0, 90.0):
        history = flick((2.0, 0.0, 0.0), (accel, 0.0, 0.0))
        v, _ = velocity.estimate(history, method="window_fit_stops", window=WINDOW)
        assert v == velocity.estimate(history, method="window_fit", window=WINDOW)[0]
        assert abs(v[0] - 2.0) < 1e-9
    for alpha in (150.0, 250.0, 400.0):
        history = flick((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 10.0, 0.0), (0.0, alpha, 0.0))
        _, w = velocity.estimate(history, method="window_fit_stops", window=WINDOW)
        assert abs(w[1] - 10.0) < 1e-6


def _cornered_hand(steps_after: int, rng=None, pos_std=0.0):
    """A researcher's trial: keyframes (joined by straight lines, as vade-record makes them)
    take the hand diagonally down at (0.3, 0, -0.3) m/s, then straight down at 0.17 m/s;
    it opens ``steps_after`` frames after the corner."""
    out, p = [], np.array([0.02, 0.2, 1.06])
    q = sp.quat_from_euler_deg(0.0, 0.0, 0.0)
    for k in range(12):
        if k:
            p = p + (np.array([0.3, 0.0, -0.3]) if k <= 11 - steps_after
                     else np.array([0.0, 0.0, -0.17])) / RATE
        noisy = p if rng is None else p + rng.normal(0.0, pos_std, 3)
        out.append((10**9 + k * 10**9 // RATE, tuple(float(x) for x in noisy), q))
    return tuple(out)


def test_a_hand_that_turned_a_corner_before_it_opens_lets_go_at_its_last_velocity():
    """The quadratic through both straight stretches overshoots the corner: the trial's pin
    let go three frames after the hand turned straight down (0.17 m/s) flew at 0.5 m/s,
    sideways too, and missed the bore (window_fit_stops: the fit does not point back, so it
    is no stop). window_fit_corners takes the line through the last four samples where the
    last three steps are steady and the fit is far off them: exactly the last stretch's
    velocity, three or four frames after the corner (two after, the stop's check already
    takes the line; six after, the window holds the last stretch alone). Under tracker
    noise the steps' own scatter hides the corner as it grows: 0.1 mm leaves ~0.02 m/s
    (the stops' fit: 0.12), 0.3 mm most of the overshoot, never more than before."""
    last = np.array([0.0, 0.0, -0.17])
    for after in (3, 4):
        off, _ = velocity.estimate(_cornered_hand(after), method="window_fit_stops",
                                   window=WINDOW)
        v, _ = velocity.estimate(_cornered_hand(after), method="window_fit_corners",
                                 window=WINDOW)
        assert np.linalg.norm(np.array(off) - last) > 0.1
        assert np.allclose(v, last, atol=1e-9)

    def rms(method: str, std: float) -> float:
        rng = np.random.default_rng(3)
        errors = [np.linalg.norm(np.array(velocity.estimate(
            _cornered_hand(3, rng, std), method=method, window=WINDOW)[0]) - last)
            for _ in range(200)]
        return float(np.sqrt(np.mean(np.square(errors))))
    assert rms("window_fit_corners", 1e-4) < 0.03 < 0.1 < rms("window_fit_stops", 1e-4)
    assert rms("window_fit_corners", 3e-4) <= rms("window_fit_stops", 3e-4)


def _kept(history: tuple) -> tuple:
    """The same samples as a held part keeps them (``velocity.new_sample``: each with the
    time of the one before and the turn back to it)."""
    out: tuple = ()
    for t_ns, cm, q in history:
        out += (velocity.new_sample(out, t_ns, cm, q),)
    return out


def test_the_turns_kept_with_the_samples_give_the_same_bits():
    # A held part keeps with each sample the turn back to the one before; the estimate is
    # bit for bit the one from plain samples: noisy, accelerating, turning, every method,
    # and with samples duplicated or closer than MIN_INTERVAL_NS (which _distinct drops,
    # so a kept turn back to a dropped sample must not be used).
    rng = np.random.default_rng(3)
    for trial in range(40):
        history = _history(rng, pos_std=1e-3, rot_std=0.02, accel=(3.0, -1.0, 9.0),
                           alpha=(20.0, 5.0, -8.0))
        if trial % 2:
            # Duplicates and near-duplicates (0.2 ms after) of random samples.
            samples = list(history)
            for k in sorted(rng.choice(len(samples) - 1, 3, replace=False), reverse=True):
                t, cm, q = samples[k]
                dt = 0 if rng.random() < 0.5 else velocity.MIN_INTERVAL_NS // 2
                twin = sp.quat_mul(sp.quat_from_rotvec(tuple(rng.normal(0.0, 0.05, 3))), q)
                samples.insert(k + 1, (t + dt, cm, sp.quat_normalize(twin)))
            history = tuple(samples)
        kept = _kept(history)
        assert any(len(s) == 6 for s in kept)
        for method in ("window_fit_corners", "window_fit_stops", "window_fit", "two_frame"):
            for window in (2, 3, 5, WINDOW, 12):
                plain = velocity.estimate(history, method=method, window=window)
                assert velocity.estimate(kept, method=method, window=window) == plain
                # A sample's kept turn is used only back to the sample it was taken of: a
                # wrong one there would show (the older sample dropped by _distinct).
                assert velocity.estimate(kept[len(kept) // 2:], method=method,
                                         window=window) == \
                    velocity.estimate(history[len(history) // 2:], method=method,
                                      window=window)


def test_a_kept_turn_is_not_taken_across_a_tracker_time_that_steps_back():
    # Times 0, 10 ms, 0, 0.1 ms (a recording whose tracker time steps back): _distinct
    # keeps the first and the last, whose time before (0) is the first sample's too; the
    # last's kept turn is back to the third, not the first, and must not be used.
    q = [sp.quat_from_rotvec((0.0, 0.0, a)) for a in (0.0, 0.3, 0.1, 0.2)]
    cm = [(0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.2, 0.0), (0.0, 0.0, 0.3)]
    times = [0, 10_000_000, 0, 100_000]
    plain = tuple(zip(times, cm, q))
    kept = _kept(plain)
    for method in ("window_fit", "two_frame"):
        assert velocity.estimate(kept, method=method, window=WINDOW) == \
            velocity.estimate(plain, method=method, window=WINDOW)


def test_a_part_turned_about_its_grip_is_let_go_at_the_rigid_body_s_velocity():
    """A physics audit: a gear spun on its bore (the hand's grip) at 10 rad/s, its centre
    of mass 30 mm off, was let go 5.4 % fast (1.45 % at 5 rad/s) through the whole
    pipeline: the quadratic was fitted to the centre of mass's circle. Fitted at the grip, which stands still here, the centre
    of mass's velocity is the rigid body's, ``w x (cm - grip)``, to round-off; the centre
    of mass's own fit (``grip`` zero, ``release_point: cm``) keeps the old error."""
    offset = np.array([0.03, 0.0, 0.0])  # the centre of mass from the grip, part axes
    axis = np.array([0.0, 0.0, 1.0])
    grip_world = np.array([0.2, 0.1, 1.0])
    for rate in (5.0, 10.0):
        history = []
        for k in range(10):
            t_ns = 10**9 + k * 10**9 // RATE
            angle = rate * (t_ns - 10**9) * 1e-9
            q = sp.quat_from_rotvec(tuple(axis * angle))
            cm = grip_world + np.array(sp.quat_rotate(q, tuple(offset)))
            history.append((t_ns, tuple(float(x) for x in cm), q))
        history = tuple(history)
        q_last = history[-1][2]
        expected = np.cross(axis * rate, sp.quat_rotate(q_last, tuple(offset)))
        v, w = velocity.estimate(history, method="window_fit_corners", window=WINDOW,
                                 grip=tuple(-offset))
        assert np.allclose(w, axis * rate, atol=1e-9)
        assert np.linalg.norm(np.array(v) - expected) < 1e-9 * rate * 0.03, v
        at_cm, _ = velocity.estimate(history, method="window_fit_corners", window=WINDOW)
        error = np.linalg.norm(np.array(at_cm) - expected) / np.linalg.norm(expected)
        assert error > 0.02, error  # (2.3 % at 5 rad/s, more at 10: the circle's chord)
