"""Sliding on the base against closed forms (paper 5.2, NOTES.md)."""

from __future__ import annotations

import math

import pytest

from _onbase import G, on_base, plate_scene, run, tilt_x
from vade_replay import spatial as sp
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
    scene = plate_scene()
    state = on_base(scene, tilt_x(0.0), sp.Pose((0.0, 0.0, 0.04)))
    record = list(run(scene, state, 3, left=lambda n: tilt_x(180.0)))
    first_events = record[0][2]
    assert [(e.from_mode, e.to_mode, e.cause) for e in first_events] == \
        [("ONBASESTATIC", "INSPACE", "gravity_lifts_off")]
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
