"""What a part keeps of its velocity where it snaps onto a constraint
(``physics.snap_velocity``): ``along_constraint`` (the default) keeps its velocity relative
to the base along the constraint and its spin about a shaft, losing the rest as in a plastic
contact; ``zero`` (the paper's snap) starts it at rest. Held to closed forms: Coulomb
friction's uniform deceleration on a level plate, viscous decay of a balanced wheel's spin.
(A pin dropped into its bore, landing fast along its axis: ``tests/test_landing.py``.)"""

from __future__ import annotations

import math

import pytest

from conftest import make_session, run_records, table

G = 9.8                  # physics.gravity's default, m/s^2
MU_D = 0.3               # the block's dynamic friction on the plate
TOL = 1e-4               # physics.contact_tolerance's default, m


def _block() -> dict:
    """A 50 x 50 x 40 mm aluminium block on the plate's top plane (static friction 0.4)."""
    return {"name": "block", "density": 2700,
            "shape": {"type": "box", "size": [0.05, 0.05, 0.04]},
            "pose": {"position": [0.3, -0.1, 0.76]},
            "assembly": {"constraints": [{
                "type": "plane", "name": "bottom_on_top",
                "part": {"point": [0, 0, -0.02], "normal": [0, 0, -1]},
                "base": {"point": [0, 0, 0.01], "normal": [0, 0, 1]},
                "friction": {"static": 0.4, "dynamic": MU_D}}]}}


def _block_let_go_moving(vx: float, *, base_vx: float = 0.0, snap: str | None = None,
                         vz: float = -0.01) -> dict:
    """A block carried over a level plate held still in the left hand (top at z 0.96) and
    let go at t 1.0 s, 2 mm above it, while the hand moves at ``vx`` along x and ``vz``
    down; the hand goes on so for 0.2 s (a constant velocity through the release, which
    the window fit reads exactly). ``base_vx``: the left hand moves along x so too."""
    def line(t: float, x0: float, v: float) -> float:
        return x0 + v * (t - 1.0)
    right = [{"t": 0.0, "position": [0.3, -0.1, 0.76], "grip": False},
             {"t": 0.2, "grip": True},
             {"t": 0.6, "position": [line(0.6, 0.0, vx), 0.2, line(0.6, 0.982, vz)]},
             {"t": 1.0, "position": [0.0, 0.2, 0.982], "grip": False},
             {"t": 1.2, "position": [line(1.2, 0.0, vx), 0.2, line(1.2, 0.982, vz)]},
             {"t": 1.4, "position": [0.3, 0.0, 1.1]}]
    left = [{"t": 0, "position": [line(0.0, 0.0, base_vx), 0.2, 0.95], "grip": True}]
    if base_vx:
        left = [{"t": 0.6, "position": [line(0.6, 0.0, base_vx), 0.2, 0.95], "grip": True},
                {"t": 1.2, "position": [line(1.2, 0.0, base_vx), 0.2, 0.95]}]
    doc = {"format": "vade-session/1", "name": "snap_block", "units": "m",
           "base": {"name": "plate", "shape": {"type": "box", "size": [0.3, 0.3, 0.02]}},
           "parts": [_block()],
           "environment": [table()], "physics": {},
           "tracker": {"rate_hz": 60, "duration_s": 2.0,
                       "devices": {"left_hand": left, "right_hand": right}}}
    if snap is not None:
        doc["physics"]["snap_velocity"] = snap
    return doc


def _causes(records) -> list[str]:
    return [e.cause for r in records for e in r.events if e.kind == "ModeChanged"]


def _release(records):
    frame = next(r for r in records for e in r.events if e.kind == "PartReleased")
    event = next(e for e in frame.events if e.kind == "PartReleased")
    return frame, event


def test_a_block_let_go_sliding_along_the_plate_slides_on_until_friction_stops_it():
    """Let go at 0.5 m/s along the plate and 0.01 m/s down onto it: the snap keeps the
    0.5 m/s along it and loses the 0.01 into it. From the next frame on it slides as
    Coulomb friction's closed form has it, x = x0 + v t - a t^2 / 2 with a = f_d g, and
    stops (``held_by_friction``) after v^2 / (2 a), to 1e-9 m. Under ``zero`` (the paper's
    snap) the same release leaves it resting where it was let go."""
    records = run_records(_block_let_go_moving(0.5))
    frame, event = _release(records)
    v = event.linear_velocity
    assert v == pytest.approx((0.5, 0.0, -0.01), abs=1e-9)  # the hand's, as fitted
    block = frame.parts[0]
    assert block.mode == "ONBASESLIDE"
    assert block.linear_velocity == pytest.approx((v[0], v[1], 0.0), abs=1e-12)
    x0, t0 = block.position[0], frame.time_ns * 1e-9
    a = MU_D * G
    t_stop = v[0] / a
    for r in records[frame.frame + 1:]:
        t = r.time_ns * 1e-9 - t0
        x = r.parts[0].position[0]
        if t < t_stop:
            assert r.parts[0].mode == "ONBASESLIDE"
            assert x - x0 == pytest.approx(v[0] * t - 0.5 * a * t * t, abs=1e-9)
            assert r.parts[0].linear_velocity[0] == pytest.approx(v[0] - a * t, abs=1e-9)
        else:
            assert r.parts[0].mode == "ONBASESTATIC"
            assert x - x0 == pytest.approx(v[0] ** 2 / (2 * a), abs=1e-9)
        assert r.parts[0].position[2] == pytest.approx(block.position[2], abs=1e-12)
    assert _causes(records) == ["grabbed", "released_on_constraint", "held_by_friction"]

    paper = run_records(_block_let_go_moving(0.5, snap="zero"))
    assert _causes(paper) == ["grabbed", "released_on_constraint"]
    assert paper[-1].parts[0].mode == "ONBASESTATIC"
    assert paper[-1].parts[0].position == pytest.approx(_release(paper)[0].parts[0].position,
                                                        abs=1e-12)


@pytest.mark.parametrize("vx, rests", [(0.0, True), (0.01, True), (0.02, True),
                                       (0.03, False), (0.1, False)])
def test_a_motion_friction_would_end_within_the_tolerance_is_rest(vx, rests):
    """Friction holds the block at rest on the level plate, so its kept speed only carries it
    v^2 / (2 f_d g): 0.017 mm at 0.01 m/s, 0.068 mm at 0.02, within the contact tolerance
    (0.1 mm), is rest (``ONBASESTATIC`` at once, the frames those of ``zero``: a hand let go
    at rest, its fit's round-off, or a tracker's noise, does not set the part sliding for a
    frame); 0.15 mm at 0.03 m/s is a slide that friction stops there."""
    records = run_records(_block_let_go_moving(vx))
    frame, _ = _release(records)
    if rests:
        assert frame.parts[0].mode == "ONBASESTATIC"
        assert _causes(records) == ["grabbed", "released_on_constraint"]
        paper = run_records(_block_let_go_moving(vx, snap="zero"))
        assert [(r.parts, r.events) for r in records] == [(r.parts, r.events) for r in paper]
    else:
        assert frame.parts[0].mode == "ONBASESLIDE"
        assert _causes(records) == ["grabbed", "released_on_constraint", "held_by_friction"]
        moved = records[-1].parts[0].position[0] - frame.parts[0].position[0]
        assert moved == pytest.approx(vx ** 2 / (2 * MU_D * G), abs=1e-9)
        assert moved > TOL


def test_only_the_velocity_relative_to_the_base_is_kept():
    """Both hands moving together along x at 0.3 m/s as the block is let go: it is at rest
    relative to the plate, so it rests on it (and rides with it; its recorded world velocity
    is the plate's). Let go from a plate moving at 0.3 m/s by a hand at rest, it slides back
    along the plate at 0.3 m/s relative to it."""
    together = run_records(_block_let_go_moving(0.3, base_vx=0.3, vz=0.0))
    frame, event = _release(together)
    assert event.linear_velocity == pytest.approx((0.3, 0.0, 0.0), abs=1e-9)
    assert frame.parts[0].mode == "ONBASESTATIC"
    assert frame.parts[0].linear_velocity == pytest.approx((0.3, 0.0, 0.0), abs=1e-9)
    assert _causes(together) == ["grabbed", "released_on_constraint"]

    behind = run_records(_block_let_go_moving(0.0, base_vx=0.3, vz=0.0))
    frame, _ = _release(behind)
    assert frame.parts[0].mode == "ONBASESLIDE"
    # World velocity: the plate's 0.3 plus the -0.3 it slides at relative to the plate.
    assert frame.parts[0].linear_velocity == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    assert "held_by_friction" in _causes(behind)


# A balanced wheel (the benchmark's gear without its weight) spun onto a horizontal shaft.
F_R = 2e-5                       # rotational friction, N m s / rad
SPIN = 2.0 * math.pi             # the hand's turn about the shaft, rad/s


def _wheel_spun_onto_its_shaft(snap: str | None = None) -> dict:
    """The stand's shaft runs along world x from (0, 0.2, 1.0); the hand brings the wheel
    onto it at x 0.12, its axis along the shaft (turned 90 degrees about y), turns it
    about the shaft at one turn a second from 0.8 s, and opens at 1.0 s still turning."""
    half = math.sqrt(0.5)
    keys = [{"t": 0.0, "position": [0.3, -0.1, 0.745], "grip": False},
            {"t": 0.2, "grip": True},
            {"t": 0.6, "position": [0.12, 0.2, 1.0], "xyzw": [0.0, half, 0.0, half]}]
    for k in range(1, 7):  # a tenth of a turn a keyframe: slerp takes the turn as meant
        t = 0.6 + 0.1 * k
        phi = SPIN * (t - 0.8) if t > 0.8 else 0.0
        c, s = math.cos(phi / 2), math.sin(phi / 2)
        # q_x(phi) * q_y(90 deg)
        q = [s * half, c * half, s * half, c * half]
        keys.append({"t": round(t, 6), "position": [0.12, 0.2, 1.0], "xyzw": q,
                     **({"grip": False} if abs(t - 1.0) < 1e-9 else {})})
    keys.append({"t": 1.4, "position": [0.3, 0.0, 1.1]})
    doc = {"format": "vade-session/1", "name": "spun_wheel", "units": "m",
           "base": {"name": "stand", "shape": {"type": "compound", "children": [
               {"type": "box", "size": [0.02, 0.1, 0.16],
                "pose": {"position": [-0.01, 0.0, -0.03]}},
               {"type": "cylinder", "radius": 0.006, "height": 0.2, "sections": 32,
                "pose": {"position": [0.1, 0.0, 0.0], "euler_deg": [0, 90, 0]}}]}},
           "parts": [{"name": "wheel", "density": 7800,
                      "pose": {"position": [0.3, -0.1, 0.745]},
                      "shape": {"type": "gear", "radius": 0.04, "height": 0.01, "teeth": 16,
                                "tooth_depth": 0.004, "inner_radius": 0.006},
                      "assembly": {"constraints": [{
                          "type": "axis", "name": "bore_on_shaft", "radius": 0.006,
                          "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
                          "base": {"point": [0, 0, 0], "direction": [1, 0, 0]},
                          "slide": False,
                          "friction": {"rotational": F_R}}]}}],
           "environment": [table()], "physics": {},
           "tracker": {"rate_hz": 60, "duration_s": 2.0, "devices": {
               "left_hand": [{"t": 0, "position": [0.0, 0.2, 1.0], "grip": True}],
               "right_hand": keys}}}
    if snap is not None:
        doc["physics"]["snap_velocity"] = snap
    return doc


def test_a_wheel_spun_onto_its_shaft_goes_on_turning_as_viscous_friction_has_it():
    """The spin about the shaft is kept, the rest of the hand's turn lost; from the next
    frame the balanced wheel turns as w(t) = w0 exp(-f_r t / J) (gravity has no torque on
    it), to 1e-9 relative. Under ``zero`` it is let go at rest and stays so."""
    doc = _wheel_spun_onto_its_shaft()
    records = run_records(doc)
    frame, event = _release(records)
    assert event.angular_velocity[0] == pytest.approx(SPIN, rel=1e-6)
    wheel = frame.parts[0]
    assert wheel.mode == "ONBASESLIDE"
    w0 = event.angular_velocity[0]
    assert wheel.angular_velocity == pytest.approx((w0, 0.0, 0.0), abs=1e-12)
    mate = make_session(doc).build_scene().parts[0].assembly.mates[0]
    decay = F_R / mate.inertia_about_axis
    t0 = frame.time_ns * 1e-9
    for r in records[frame.frame + 1:]:
        t = r.time_ns * 1e-9 - t0
        w = r.parts[0].angular_velocity
        assert r.parts[0].mode == "ONBASESLIDE"
        assert w[0] == pytest.approx(w0 * math.exp(-decay * t), rel=1e-9)
        assert abs(w[1]) < 1e-12 and abs(w[2]) < 1e-12
        assert r.parts[0].position == pytest.approx(wheel.position, abs=1e-12)
    assert records[-1].time_ns * 1e-9 - t0 > 0.9  # a second of turning checked

    paper = run_records(_wheel_spun_onto_its_shaft(snap="zero"))
    frame, _ = _release(paper)
    assert all(r.parts[0].angular_velocity == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
               for r in paper[frame.frame:])


def test_the_paper_model_snaps_at_rest():
    """``model: paper`` selects ``snap_velocity: zero``."""
    doc = _block_let_go_moving(0.5)
    doc["physics"] = {"model": "paper"}
    assert make_session(doc).build_scene().physics.snap_velocity == "zero"


def _block_on_a_slope(v_downhill: float, deg: float, snap: str | None = None) -> dict:
    """A review's scene: the plate tilted ``deg`` about x in the left hand (its +y edge up),
    default friction (static 0.3, dynamic 0.2), the block let go 0.5 mm above it while the
    hand moves ``v_downhill`` down the slope."""
    th = math.radians(deg)
    down = (0.0, -math.cos(th), -math.sin(th))
    on = (0.0, 0.2 - 0.0305 * math.sin(th), 0.95 + 0.0305 * math.cos(th))

    def at(t: float) -> list[float]:
        return [on[i] + v_downhill * down[i] * (t - 1.0) for i in range(3)]
    doc = _block_let_go_moving(0.0, snap=snap)
    del doc["parts"][0]["assembly"]["constraints"][0]["friction"]
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [deg, 0, 0], "grip": True}]
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [0.3, -0.1, 0.76], "grip": False},
        {"t": 0.2, "grip": True},
        {"t": 0.6, "position": at(0.6), "euler_deg": [deg, 0, 0]},
        {"t": 1.0, "position": at(1.0), "euler_deg": [deg, 0, 0], "grip": False},
        {"t": 1.2, "position": at(1.2), "euler_deg": [deg, 0, 0]},
        {"t": 1.4, "position": [0.3, 0.0, 1.2]}]
    return doc


@pytest.mark.parametrize("v_downhill", [0.0, 0.003, -0.003])
def test_a_block_let_go_at_rest_on_a_slope_static_friction_alone_holds_stays(v_downhill):
    """A review: on a slope of 14 degrees static friction (0.3, 16.7 degrees) holds the
    block, dynamic (0.2, 11.3) would not stop a slide. Let go by a hand at rest (its fit's
    round-off, 1e-14 m/s, either way along the slope) or at 3 mm/s, it rests: a motion of
    under the contact tolerance a frame is inside the band of stiction (Karnopp's), and the
    frames are those of ``zero``. (Before, round-off pointing downhill slid it off the
    plate.) At 2 cm/s down the slope it slides, and nothing stops it: dynamic friction
    cannot, as the closed form's acceleration g (sin - f_d cos) > 0 says."""
    ours = run_records(_block_on_a_slope(v_downhill, 14.0))
    paper = run_records(_block_on_a_slope(v_downhill, 14.0, snap="zero"))
    assert _causes(ours) == ["grabbed", "released_on_constraint"]
    assert [(r.parts, r.events) for r in ours] == [(r.parts, r.events) for r in paper]
    sliding = run_records(_block_on_a_slope(0.02, 14.0))
    assert _causes(sliding)[:3] == ["grabbed", "released_on_constraint", "slid_off_base"]
    th = math.radians(14.0)
    assert G * (math.sin(th) - 0.2 * math.cos(th)) > 0.0


def test_a_hanging_gear_let_go_by_a_hand_moving_across_its_shaft_swings(recordings_dir):
    """A review: the gear of ``gear_pendulum`` (a weight on its rim, so its centre of mass
    lies off the shaft) let go hanging at rest while the hand moves across the shaft at
    0.3 m/s without turning. The shaft's reactions pass through it, so the angular momentum
    about it is kept: it turns at m (r x v).u / J, r from the shaft to the centre of mass,
    to 1e-9 relative; under ``zero`` it stays at rest."""
    import json
    doc = _wheel_spun_onto_its_shaft()
    gear = json.loads((recordings_dir / "gear_pendulum.json").read_text())["parts"][0]
    doc["parts"][0]["shape"] = gear["shape"]
    half = math.sqrt(0.5)

    def at(t: float) -> list[float]:
        return [0.12, 0.2 + 0.3 * (t - 1.0), 1.0]
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [0.3, -0.1, 0.745], "grip": False}, {"t": 0.2, "grip": True},
        {"t": 0.7, "position": at(0.7), "xyzw": [0, half, 0, half]},
        {"t": 1.0, "position": at(1.0), "xyzw": [0, half, 0, half], "grip": False},
        {"t": 1.2, "position": at(1.2), "xyzw": [0, half, 0, half]},
        {"t": 1.5, "position": [0.3, 0.0, 1.1]}]
    records = run_records(doc)
    frame, event = _release(records)
    body = make_session(doc).build_scene().parts[0]
    mate = body.assembly.mates[0]
    # The centre of mass where the gear was let go, from the shaft (y 0.2, z 1.0) to it.
    held = records[frame.frame - 1].parts[0]
    from vade_replay import spatial as sp
    cm = sp.Pose(held.position, held.rotation_xyzw).apply(body.center_of_mass)
    r = (0.0, cm[1] - 0.2, cm[2] - 1.0)
    v = event.linear_velocity
    assert v == pytest.approx((0.0, 0.3, 0.0), abs=1e-9)
    assert event.angular_velocity == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    expected = body.mass_kg * sp.cross(r, v)[0] / mate.inertia_about_axis
    assert abs(expected) > 0.1  # a swing worth the name
    assert frame.parts[0].mode == "ONBASESLIDE"
    assert frame.parts[0].angular_velocity[0] == pytest.approx(expected, rel=1e-9)
    doc["physics"]["snap_velocity"] = "zero"
    assert _release(run_records(doc))[0].parts[0].angular_velocity == (0.0, 0.0, 0.0)


def test_a_wheel_held_by_static_friction_let_go_by_a_noisy_hand_rests():
    """A review: a balanced wheel with a holding torque (static friction about the shaft)
    and no rotational friction, let go by a still hand read with tracker noise (a spin of
    0.003-0.02 rad/s). Nothing would slow a kept spin but the holding torque at a stop that
    never comes, so it turned for good; its turn of under the contact tolerance a frame is
    rest now, the frames those of ``zero``."""
    for seed in range(3):
        runs = []
        for snap in ("along_constraint", "zero"):
            doc = _wheel_spun_onto_its_shaft(snap)
            keys = doc["tracker"]["devices"]["right_hand"]
            for key in keys:  # the hand does not turn the wheel
                if "xyzw" in key:
                    key["xyzw"] = [0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)]
            friction = doc["parts"][0]["assembly"]["constraints"][0]["friction"]
            friction.update(rotational=0.0, holding_torque=0.01)
            doc["tracker"]["noise"] = {"seed": seed, "position_std": 0.0001,
                                       "rotation_std_deg": 0.02}
            runs.append(run_records(doc))
        frame, event = _release(runs[0])
        assert abs(event.angular_velocity[0]) > 1e-3  # the noise's spin, let go
        assert frame.parts[0].mode == "ONBASESTATIC"
        assert [(r.parts, r.events) for r in runs[0]] == [(r.parts, r.events) for r in runs[1]]


@pytest.mark.parametrize("yaw_deg", [0.0, 17.0, 30.0, 45.0])
def test_a_block_let_go_into_a_wall_stops_at_the_wall_in_the_frame_it_meets_it(yaw_deg):
    """A review (``wall2``): a block let go at 3 m/s straight at the wall of a plate turned
    30 degrees about the vertical kept a round-off of its speed along the wall after the
    block (1e-30 m/s: a motion into the obstacle less its projection onto the same
    direction), slid on for a frame, and logged ``held_by_friction`` after the block. The
    block is the stop: in the frame of the contact it is ONBASESTATIC, blocked by the base,
    at any turn of the plate, and nothing follows."""
    doc = make_session_doc_wall(3.0, yaw_deg)
    records = run_records(doc)
    contacts = [r.frame for r in records for e in r.events if e.kind == "ContactMade"]
    assert len(contacts) == 1
    hit = next(r for r in records if r.frame == contacts[0])
    assert [(e.kind, e.cause) for e in hit.events] == [("ContactMade", "blocked_by_base"),
                                                      ("ModeChanged", "blocked_by_base")]
    assert hit.parts[0].mode == "ONBASESTATIC"
    assert _causes(records) == ["grabbed", "released_on_constraint", "blocked_by_base"]
    # Against the wall: its inner face 0.13 m from the plate's centre, the block 0.025 m
    # half wide, within the contact tolerance.
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    x, y, _ = records[-1].parts[0].position
    along = -s * (x - 0.0) + c * (y - 0.2)
    assert 0.105 - TOL <= along <= 0.105


def make_session_doc_wall(speed: float, yaw_deg: float) -> dict:
    """``plane_block_wall``'s plate (a wall along its far edge) held still in the left hand,
    turned ``yaw_deg`` about the vertical; the block carried at ``speed`` straight at the
    wall and let go 5.5 cm short of it."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))

    def world(x: float, y: float, z: float) -> list[float]:
        return [c * x - s * y, 0.2 + s * x + c * y, 0.95 + z]
    y0 = 0.05 - speed * 0.15
    right = [{"t": 0.0, "position": [0.3, -0.1, 0.76], "grip": False},
             {"t": 0.2, "grip": True},
             {"t": 0.6, "position": world(0.0, y0, 0.032), "euler_deg": [0, 0, yaw_deg]},
             {"t": 0.75, "position": world(0.0, 0.05, 0.032), "grip": False},
             {"t": 0.9, "position": world(0.0, y0 + speed * 0.3, 0.032)}]
    return {"format": "vade-session/1", "name": "wall", "units": "m",
            "base": {"name": "plate_with_wall", "shape": {"type": "compound", "children": [
                {"type": "box", "size": [0.3, 0.3, 0.02]},
                {"type": "box", "size": [0.3, 0.02, 0.06],
                 "pose": {"position": [0.0, 0.14, 0.04]}}]}},
            "parts": [_block()],
            "environment": [table()],
            "tracker": {"rate_hz": 60, "duration_s": 1.2, "devices": {
                "left_hand": [{"t": 0, "position": [0.0, 0.2, 0.95],
                               "euler_deg": [0, 0, yaw_deg], "grip": True}],
                "right_hand": right}}}


@pytest.mark.parametrize("across, kept", [(3e-16, False), (3e-13, True), (1e-6, True)])
def test_a_block_keeps_what_is_left_of_its_rate_beyond_round_off(across, kept):
    """``_stop_at_block`` takes the rate into the obstacle off; what is left is kept unless
    it is within 16 ulps of the speed (the projection's round-off): 3e-16 m/s across a 3 m/s
    motion along x is dropped, 3e-13 m/s and 1 um/s are kept as they were."""
    from vade_replay import spatial as sp
    from vade_replay.state import OnBase
    from vade_replay.step import _stop_at_block
    old = OnBase(0, sp.IDENTITY, (0.0, 0.0), (3.0, across))
    new = old.moved((0.05, 0.0), (3.0, across), 0.0, 0.0)
    stopped = _stop_at_block(new, old, (0.05, 0.0), 0.0, True, False)
    assert stopped.blocked_slide == (1.0, 0.0)
    assert stopped.slide_rate == ((0.0, across) if kept else (0.0, 0.0))
