"""Two hands (the paper's middle class of parts): a part too heavy for one hand and not for
two is lifted when both hands close on it, follows the frame between the hands (origin
midway; turned frame by frame by the swing of the line between the hands and the mean of
their twists about it), and is let go when either hand opens. The left hand is free where
the base is fixed."""

from __future__ import annotations

import json
import math

import pytest

from conftest import (RECORDINGS, assert_falls_from_rest, run_cli, run_records,
                      session_doc)
from vade_replay import spatial as sp
from vade_replay.errors import SessionError

# 0.4 x 0.2 x 0.1 m at 1250 kg/m^3: 10 kg, on the table (top at 0.74).
CRATE = {"name": "crate", "shape": {"type": "box", "size": [0.4, 0.2, 0.1]}, "density": 1250,
         "pose": {"position": [0.0, 0.0, 0.79]}}
UP_Z = 1.2


def _still(position, t0, t1, **first):
    return [{"t": t0, "position": position, **first}, {"t": t1, "position": position}]


def _doc(*, left, right, parts=(CRATE,), physics=None, duration_s=2.0, **extra):
    doc = session_doc(parts=list(parts), right_hand=right, duration_s=duration_s,
                      physics=physics, **extra)
    doc["tracker"]["devices"]["left_hand"] = left
    return doc


def _lift(x, *, close_t, open_t=None, up_t=(0.4, 0.8)):
    """A hand at the crate's end x (at its top), closing at close_t, lifting it 0.41 m
    between up_t, opening at open_t."""
    keys = [{"t": 0.0, "position": [x, 0.0, 0.8], "grip": False},
            {"t": close_t, "grip": True},
            {"t": up_t[0], "position": [x, 0.0, 0.8]},
            {"t": up_t[1], "position": [x, 0.0, UP_Z]}]
    if open_t is not None:
        keys.append({"t": open_t, "grip": False})
    return keys


def _events(records, *kinds):
    return [(r.frame, e.kind, e.part, e.cause, e.hand) for r in records for e in r.events
            if e.kind in kinds]


def test_the_other_hand_joining_lifts_a_part_too_heavy_for_one():
    records = run_records(_doc(left=_lift(-0.21, close_t=0.2), right=_lift(0.21, close_t=0.1)))
    assert _events(records, "GrabRefused", "PartGrabbed") == [
        (6, "GrabRefused", "crate", "too_heavy_for_one_hand", "right_hand"),
        (12, "PartGrabbed", "crate", "grabbed", "both_hands")]
    last = records[-1].parts[0]
    assert last.mode == "INHAND"
    # Both hands lifted 0.41 m together: the crate with them, exactly, not turned.
    assert last.position == pytest.approx((0.0, 0.0, 0.79 + UP_Z - 0.8), abs=1e-12)
    assert last.rotation_xyzw == (0.0, 0.0, 0.0, 1.0)


def test_both_hands_closing_in_one_frame_take_it_once():
    records = run_records(_doc(left=_lift(-0.21, close_t=0.2), right=_lift(0.21, close_t=0.2)))
    assert _events(records, "GrabRefused", "PartGrabbed") == [
        (12, "PartGrabbed", "crate", "grabbed", "both_hands")]


def test_a_part_in_both_hands_moves_rigidly_with_them():
    """The hands turn together 90 degrees about a vertical line through (0.3, 0.1) and rise
    0.2 m, each hand turning with them: wherever they come to rest, the part has made the
    same rigid motion (the hands' rigid motion applied to the pose it was taken at)."""
    centre = (0.3, 0.1, 0.0)
    turn = sp.quat_axis_angle((0.0, 0.0, 1.0), math.pi / 2)
    motion = sp.Pose(sp.sub(centre, sp.quat_rotate(turn, centre)), turn)  # about the line
    lift = sp.Pose((0.0, 0.0, 0.2))

    def hand(x, tilt_deg):
        # Each hand has its own orientation (a tilt about the line between them keeps the
        # frame's y axis; here they tilt oppositely, so their y axes still sum upright-ish).
        q = sp.quat_from_euler_deg(tilt_deg, 0.0, 0.0)
        start = sp.Pose((x, 0.0, 0.8), q)
        end = lift.compose(motion).compose(start)
        return [{"t": 0.0, "position": list(start.position), "xyzw": list(q), "grip": False},
                {"t": 0.1, "grip": True},
                {"t": 0.2, "position": list(start.position), "xyzw": list(q)},
                {"t": 1.0, "position": list(end.position), "xyzw": list(end.rotation)}]

    records = run_records(_doc(left=hand(-0.21, 20.0), right=hand(0.21, -35.0),
                               duration_s=1.5))
    assert _events(records, "PartGrabbed") == [(6, "PartGrabbed", "crate", "grabbed",
                                                "both_hands")]
    expected = lift.compose(motion).compose(sp.Pose((0.0, 0.0, 0.79)))
    for r in records[61:]:  # from t = 1.0 s the hands are still at their end poses
        part = r.parts[0]
        assert part.position == pytest.approx(expected.position, abs=1e-12)
        assert sp.quat_angle_between(part.rotation_xyzw, expected.rotation) < 1e-12


def test_either_hand_opening_lets_go_and_it_falls_along_the_parabola():
    records = run_records(_doc(left=_lift(-0.21, close_t=0.1, open_t=1.2),
                               right=_lift(0.21, close_t=0.1)))
    changes = [(r.frame, e.from_mode, e.to_mode, e.cause) for r in records for e in r.events
               if e.kind == "ModeChanged"]
    assert [c[1:] for c in changes] == [("STATIC", "INHAND", "grabbed"),
                                        ("INHAND", "INSPACE", "released"),
                                        ("INSPACE", "STATIC", "hit_environment")]
    released = [e for r in records for e in r.events if e.kind == "PartReleased"]
    assert [(e.cause, e.hand) for e in released] == [("released", "both_hands")]
    # Still for 0.4 s before the left hand opened: it leaves at rest and falls
    # z(t) = z0 - g t^2 / 2 (the right hand, still closed, cannot hold it alone).
    assert max(abs(v) for v in released[0].linear_velocity) < 1e-12
    assert_falls_from_rest(records, changes[1][0], 0.79 + UP_Z - 0.8)
    assert records[-1].parts[0].position[2] == pytest.approx(0.79, abs=2e-4)


@pytest.mark.parametrize("mass_case, cause", [
    ("heavier than two hands lift", "too_heavy_for_two_hands"),
    ("the other hand out of reach", "too_heavy_for_one_hand"),
    ("the other hand holds a part", "too_heavy_for_one_hand"),
    ("two-hand lifting off", "too_heavy_for_one_hand")])
def test_two_hands_are_refused(mass_case, cause):
    parts = [CRATE]
    left = _lift(-0.21, close_t=0.1)
    physics = None
    if mass_case == "heavier than two hands lift":
        physics = {"two_hand_max_mass_kg": 9.0}
    elif mass_case == "the other hand out of reach":
        left = _lift(-0.3, close_t=0.1)   # 0.1 m beyond the crate's end: reach is 0.05
    elif mass_case == "the other hand holds a part":
        parts = [CRATE, {"name": "pin", "shape": {"type": "box", "size": [0.02, 0.02, 0.04]},
                         "density": 2700, "pose": {"position": [-0.3, 0.0, 0.76]}}]
        left = [{"t": 0.0, "position": [-0.3, 0.0, 0.79], "grip": False},
                {"t": 0.05, "grip": True},  # takes the pin
                {"t": 0.1, "position": [-0.3, 0.0, 0.79]},
                {"t": 0.15, "position": [-0.21, 0.0, 0.8]}]
    else:
        physics = {"two_hand_max_mass_kg": 5.0}  # at most one hand's: as before two hands
    records = run_records(_doc(left=left, right=_lift(0.21, close_t=0.2), parts=parts,
                               physics=physics))
    refused = [(e.part, e.cause, e.hand) for r in records for e in r.events
               if e.kind == "GrabRefused" and e.part == "crate"]
    assert refused[-1] == ("crate", cause, "right_hand")
    crate = records[-1].parts[[p.name for p in records[-1].parts].index("crate")]
    assert crate.mode == "STATIC" and crate.position == (0.0, 0.0, 0.79)


def test_the_left_hand_carrying_the_base_does_not_join():
    base = {"name": "plate", "shape": {"type": "box", "size": [0.2, 0.2, 0.02]},
            "pose": {"position": [-0.5, 0.0, 1.0]}}
    records = run_records(_doc(left=_lift(-0.21, close_t=0.1), right=_lift(0.21, close_t=0.2),
                               base=base))
    assert _events(records, "GrabRefused", "PartGrabbed") == [
        (12, "GrabRefused", "crate", "too_heavy_for_one_hand", "right_hand")]
    # ... it carries the base (the left hand's pose composed with hand_from_base, identity).
    assert records[-1].base.position == pytest.approx((-0.21, 0.0, UP_Z), abs=1e-12)
    assert records[-1].base.mode == "INHAND"


def test_a_fixed_base_stays_put_and_the_left_hand_grabs_as_the_right():
    base = {"name": "plate", "fixed": True, "shape": {"type": "box", "size": [0.2, 0.2, 0.02]},
            "pose": {"position": [-0.5, 0.0, 0.75]}}
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
           "density": 2700, "pose": {"position": [0.2, 0.3, 0.78]}}  # 0.35 kg
    left = [{"t": 0.0, "position": [0.2, 0.3, 0.83], "grip": False}, {"t": 0.1, "grip": True},
            {"t": 0.2, "position": [0.2, 0.3, 0.83]}, {"t": 0.6, "position": [0.2, 0.3, 1.13]}]
    right = [{"t": 0.0, "position": [0.5, -0.3, 1.0], "grip": False}]
    records = run_records(_doc(left=left, right=right, parts=[peg], base=base, duration_s=1.0))
    assert _events(records, "PartGrabbed") == [(6, "PartGrabbed", "peg", "grabbed", "left_hand")]
    assert records[-1].parts[0].position == pytest.approx((0.2, 0.3, 1.08), abs=1e-12)
    for r in records:
        assert r.base.position == (-0.5, 0.0, 0.75) and r.base.mode == "STATIC"


def test_hands_brought_together_hold_the_part_where_it_was():
    """Where the frame between the hands is undefined (the hands at one point) the part
    stays where it was, as when a hand has no sample; it follows again after."""
    left = _lift(-0.21, close_t=0.1, up_t=(0.2, 0.4)) + [
        {"t": 0.6, "position": [0.0, 0.0, UP_Z]}, {"t": 0.8, "position": [0.0, 0.0, UP_Z]},
        {"t": 1.0, "position": [-0.21, 0.0, UP_Z + 0.1]}]
    right = _lift(0.21, close_t=0.1, up_t=(0.2, 0.4)) + [
        {"t": 0.6, "position": [0.0, 0.0, UP_Z]}, {"t": 0.8, "position": [0.0, 0.0, UP_Z]},
        {"t": 1.0, "position": [0.21, 0.0, UP_Z + 0.1]}]
    records = run_records(_doc(left=left, right=right, duration_s=1.2))
    together = [r for r in records if 36 <= r.frame <= 48]
    assert together and all(r.parts[0].position == together[0].parts[0].position
                            for r in together)
    assert all(math.isfinite(v) for r in records for v in r.parts[0].position)
    assert records[-1].parts[0].position == pytest.approx((0.0, 0.0, 0.79 + UP_Z + 0.1 - 0.8),
                                                          abs=1e-12)


def test_session_errors_name_the_field():
    from conftest import make_session
    base = {"name": "plate", "fixed": True, "shape": {"type": "box", "size": [0.2, 0.2, 0.02]},
            "hand_from_base": {"position": [0, 0, 0.1]}}
    with pytest.raises(SessionError) as err:
        make_session(_doc(left=_lift(-0.21, close_t=0.1), right=_lift(0.21, close_t=0.1),
                          base=base)).build_scene()
    assert err.value.field == "base.hand_from_base"
    with pytest.raises(SessionError) as err:
        make_session(_doc(left=_lift(-0.21, close_t=0.1), right=_lift(0.21, close_t=0.1),
                          tools=[{"name": "both_hands", "max_mass_kg": 50}])).build_scene()
    assert err.value.field == "tools[0].name"


def test_the_golden_places_a_housing_with_both_hands():
    from vade_replay.recording import Recording
    from vade_replay.replay import recorded_records
    records = list(recorded_records(Recording(RECORDINGS / "two_hand_placed.mcap")))
    assert [(e.from_mode, e.to_mode, e.cause) for r in records for e in r.events
            if e.kind == "ModeChanged"] == [
        ("STATIC", "INHAND", "grabbed"), ("INHAND", "ONBASESLIDE", "released_on_constraint"),
        ("ONBASESLIDE", "PLACED", "reached_final_pose")]
    assert _events(records, "GrabRefused", "PartGrabbed", "PartReleased")[:3] == [
        (30, "GrabRefused", "housing", "too_heavy_for_one_hand", "right_hand"),
        (42, "PartGrabbed", "housing", "grabbed", "both_hands"),
        (192, "PartReleased", "housing", "released_on_constraint", "both_hands")]
    assert records[-1].base.mode == "STATIC"


def test_a_what_if_with_one_hands_strength_names_where_the_lift_fails():
    """``--set physics.two_hand_max_mass_kg=5``: could one person lift it without help?
    No: the replay names the frame where both hands took it, and the housing stays on the
    table. Exit 0: a what-if's difference is its answer."""
    result = run_cli("vade-replay", str(RECORDINGS / "two_hand_placed.mcap"), "--json",
                     "--set", "physics.two_hand_max_mass_kg=5")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["first_divergence"]["frame"] == 42
    # The frame lists only what moved: the housing moved in the recording, not in the run;
    # the report names its state on each side, not the listing.
    assert (summary["first_divergence"]["part"], summary["first_divergence"]["field"],
            summary["first_divergence"]["recorded"], summary["first_divergence"]["replayed"]
            ) == ("housing", "mode", "INHAND", "STATIC")
    assert summary["analysis"]["refused_grabs"] == {"too_heavy_for_one_hand": 2}
    assert summary["analysis"]["parts"]["housing"]["two_hand_grabs"] == 0
    recorded = json.loads(run_cli("vade-replay", str(RECORDINGS / "two_hand_placed.mcap"),
                                  "--json").stdout)["analysis"]["parts"]["housing"]
    assert (recorded["grabs"], recorded["two_hand_grabs"], recorded["tool_grabs"],
            recorded["refused_grabs"]) == (1, 1, 0, 1)
    assert summary["analysis"]["parts"]["housing"]["time_in_state_s"] == {"STATIC": 4.0}


def _hold_then(left_end, right_end, *, left_q=None, right_q=None, duration_s=1.5, noise=None,
               start=(-0.21, 0.21)):
    """Both hands close on the crate at t = 0.1 s (along x, at its ends, rotations as given
    or untracked), then move to their end poses by t = 1.0 s and stay."""
    def hand(x, end, q):
        keys = [{"t": 0.0, "position": [x, 0.0, 0.8], "grip": False},
                {"t": 0.1, "grip": True}, {"t": 0.2, "position": [x, 0.0, 0.8]},
                {"t": 1.0, "position": list(end)}]
        if q is not None:
            keys[2]["xyzw"] = [0.0, 0.0, 0.0, 1.0]
            keys[3]["xyzw"] = list(q)
        return keys
    doc = _doc(left=hand(start[0], left_end, left_q), right=hand(start[1], right_end, right_q),
               duration_s=duration_s)
    if noise:
        doc["tracker"]["noise"] = noise
    return run_records(doc)


def _expected(left_end, right_end, rotation):
    """The crate's pose for the frame between the hands at its end pose: the crate was taken
    with that frame at the midpoint (0, 0, 0.8) of hands at (+-0.21, 0, 0.8)."""
    mid = sp.scale(sp.add(left_end, right_end), 0.5)
    return sp.Pose(mid, rotation).compose(sp.Pose((0.0, 0.0, -0.8))).compose(
        sp.Pose((0.0, 0.0, 0.79)))


def _assert_at(records, expected):
    for r in records[61:]:
        assert r.parts[0].position == pytest.approx(expected.position, abs=1e-12)
        assert sp.quat_angle_between(r.parts[0].rotation_xyzw, expected.rotation) < 1e-12


def test_hands_drawing_apart_carry_it_at_their_midpoint_unturned():
    left, right = (-0.26, 0.0, 0.8), (0.36, 0.0, 0.8)
    _assert_at(_hold_then(left, right), _expected(left, right, (0.0, 0.0, 0.0, 1.0)))


def test_one_hand_raised_tilts_it_by_the_angle_of_the_line_between_them():
    """Untracked hand rotations (fixed): the frame turns by the swing alone, the least
    rotation from the line then to the line now: here about y by -atan(0.2 / 0.42)."""
    left, right = (-0.21, 0.0, 0.8), (0.21, 0.0, 1.0)
    tilt = sp.quat_axis_angle((0.0, 1.0, 0.0), -math.atan2(0.2, 0.42))
    _assert_at(_hold_then(left, right), _expected(left, right, tilt))


@pytest.mark.parametrize("left_deg, right_deg", [(40.0, 40.0), (10.0, 50.0), (-30.0, 70.0)])
def test_hands_turning_about_the_line_between_them_turn_it_by_their_mean(left_deg, right_deg):
    """Each hand turns about the line (x) by its own angle: the part turns by their mean."""
    left, right = (-0.21, 0.0, 0.8), (0.21, 0.0, 0.8)
    records = _hold_then(left, right,
                         left_q=sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(left_deg)),
                         right_q=sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(right_deg)))
    mean = sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians((left_deg + right_deg) / 2))
    _assert_at(records, _expected(left, right, mean))


def test_hands_along_their_own_axes_with_tracker_noise_do_not_flip_it():
    """A review's case: hands holding the crate lengthwise along y, rotations untracked,
    1 mm of tracker noise. The frame depends on the line between the hands, not on their
    axes, so the part turns only as the noisy line does: ~1 mm / 0.42 m a frame."""
    crate = {**CRATE, "shape": {"type": "box", "size": [0.2, 0.4, 0.1]}}
    def hand(y):
        return [{"t": 0.0, "position": [0.0, y, 0.8], "grip": False}, {"t": 0.1, "grip": True},
                {"t": 0.2, "position": [0.0, y, 0.8]}, {"t": 1.0, "position": [0.0, y, 1.1]}]
    doc = _doc(left=hand(-0.21), right=hand(0.21), parts=[crate], duration_s=1.2)
    doc["tracker"]["noise"] = {"seed": 7, "position_std": 0.001}
    records = run_records(doc)
    assert _events(records, "PartGrabbed")[0][4] == "both_hands"
    held = [r.parts[0] for r in records if r.parts[0].mode == "INHAND"]
    steps = [sp.quat_angle_between(a.rotation_xyzw, b.rotation_xyzw)
             for a, b in zip(held, held[1:])]
    assert len(held) > 60 and max(steps) < 0.02


@pytest.mark.parametrize("peg_near", ["left_hand", "right_hand"])
def test_the_same_gesture_mirrored_gives_the_same_result(peg_near):
    """Both hands close in one frame; a light peg is nearer one of them than the crate. That
    hand takes the peg (the part nearest it), and the crate is refused to the other, whichever
    side the peg is on: a two-hand grab needs the part to be the nearest to both hands."""
    x = -0.21 if peg_near == "left_hand" else 0.21
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.02, 0.02, 0.04]}, "density": 2700,
           "pose": {"position": [x + (0.01 if x > 0 else -0.01), 0.0, 0.8]}}  # the hand inside its box
    records = run_records(_doc(left=_lift(-0.21, close_t=0.1), right=_lift(0.21, close_t=0.1),
                               parts=[CRATE, peg]))
    other = "right_hand" if peg_near == "left_hand" else "left_hand"
    assert sorted(e[1:] for e in _events(records, "GrabRefused", "PartGrabbed")) == sorted([
        ("PartGrabbed", "peg", "grabbed", peg_near),
        ("GrabRefused", "crate", "too_heavy_for_one_hand", other)])


def _steps(records):
    held = [r.parts[0] for r in records if r.parts[0].mode == "INHAND"]
    return held, [sp.quat_angle_between(a.rotation_xyzw, b.rotation_xyzw)
                  for a, b in zip(held, held[1:])]


def test_carried_round_about_the_vertical_with_untracked_hands_it_turns_about_the_vertical():
    """A review's case: the hands carry the crate half a turn about the vertical in 10 degree
    keyframes, the right hand 5 mm higher, rotations untracked. The least rotation from the
    line at the grab to the line at the end is no turn about the vertical there (it turned
    the crate upside down, 157 degrees in one frame). Built frame by frame (the line's
    frame transported parallel along its path), it ends turned half a turn about the
    vertical, upright but for the transport's turn about the line: the angle swept times
    the sine of the line's tilt (pi sin(phi) over a latitude circle; the keyframes' chords
    are near one)."""
    keys_l, keys_r = [], []
    for k in range(19):
        t = 0.2 + 0.05 * k
        a = math.radians(10.0 * k)
        c, s_ = math.cos(a), math.sin(a)
        keys_l.append({"t": t, "position": [-0.21 * c, -0.21 * s_, 0.8]})
        keys_r.append({"t": t, "position": [0.21 * c, 0.21 * s_, 0.805]})
    left = [{"t": 0.0, "position": [-0.21, 0.0, 0.8], "grip": False}, {"t": 0.1, "grip": True}]
    right = [{"t": 0.0, "position": [0.21, 0.0, 0.805], "grip": False}, {"t": 0.1, "grip": True}]
    records = run_records(_doc(left=left + keys_l, right=right + keys_r, duration_s=1.3))
    held, steps = _steps(records)
    # 10 degrees a keyframe, 3 frames apart: 0.0582 rad a frame, and never more.
    assert max(steps) < math.radians(10.0) / 3 + 1e-3
    up = sp.quat_rotate(held[-1].rotation_xyzw, (0.0, 0.0, 1.0))
    phi = math.atan2(0.005, 0.42)
    assert math.acos(up[2]) == pytest.approx(math.pi * math.sin(phi), abs=1e-3)  # 0.037 rad
    along = sp.quat_rotate(held[-1].rotation_xyzw, (1.0, 0.0, 0.0))
    assert along[0] == pytest.approx(-1.0, abs=1e-3) and abs(along[1]) < 1e-3


def test_wrists_counter_turning_about_the_line_do_not_make_it_jump():
    """A review's case: the wrists turn -120 and +120 degrees about the line between them:
    the mean twist is none, all along (taken of the two wrists' whole turns since the grab,
    it jumped half a turn where they were 180 degrees apart)."""
    left, right = (-0.21, 0.0, 0.8), (0.21, 0.0, 0.8)
    records = _hold_then(left, right,
                         left_q=sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(-120.0)),
                         right_q=sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(120.0)))
    _, steps = _steps(records)
    assert max(steps) < 1e-9
    _assert_at(records, _expected(left, right, (0.0, 0.0, 0.0, 1.0)))


@pytest.mark.parametrize("nearer", ["left_hand", "right_hand"])
def test_a_light_part_both_hands_close_on_goes_to_the_nearer(nearer):
    """Both hands close in one frame on a peg between them: the nearer hand takes it (the
    left hand used to, acting first); the other is refused, the peg being in the first."""
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.02, 0.02, 0.04]}, "density": 2700,
           "pose": {"position": [0.0, 0.0, 0.76]}}
    near, far = 0.025, 0.045
    lx, rx = (-near, far) if nearer == "left_hand" else (-far, near)
    def hand(x):
        return [{"t": 0.0, "position": [x, 0.0, 0.76], "grip": False}, {"t": 0.1, "grip": True}]
    records = run_records(_doc(left=hand(lx), right=hand(rx), parts=[peg], duration_s=0.3))
    grabbed = [e for e in _events(records, "PartGrabbed", "GrabRefused")]
    assert grabbed[0] == (6, "PartGrabbed", "peg", "grabbed", nearer)
    assert [e[1:4] for e in grabbed[1:]] == [("GrabRefused", "peg", "held_by_other_hand")]


def _fixed_base_peg_doc(left, right, duration_s=1.5):
    base = {"name": "plate", "fixed": True, "shape": {"type": "box", "size": [0.2, 0.2, 0.02]},
            "pose": {"position": [-0.5, 0.3, 0.75]}}
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
           "density": 2700, "pose": {"position": [0.0, 0.0, 0.78]}}  # 0.35 kg
    return _doc(left=left, right=right, parts=[peg], base=base, duration_s=duration_s)


def test_a_part_is_handed_from_one_hand_to_the_other():
    """With the left hand free (a fixed base), the right hand takes the peg and lifts it; the
    left hand closes on it and takes it over (``handed_over``: no release by the right, no
    change of mode), carries it rigidly, and lets go of it. The right hand opening after the
    hand-over lets go of nothing."""
    right = [{"t": 0.0, "position": [0.0, 0.0, 0.8], "grip": False}, {"t": 0.1, "grip": True},
             {"t": 0.2, "position": [0.0, 0.0, 0.8]}, {"t": 0.5, "position": [0.0, 0.0, 1.0]},
             {"t": 0.8, "grip": False}, {"t": 1.0, "position": [0.3, -0.3, 1.0]}]
    left = [{"t": 0.0, "position": [-0.3, 0.3, 1.0], "grip": False},
            {"t": 0.5, "position": [0.0, 0.03, 1.0]}, {"t": 0.6, "grip": True},
            {"t": 0.7, "position": [0.0, 0.03, 1.0]}, {"t": 1.1, "position": [-0.2, 0.03, 1.2]},
            {"t": 1.3, "grip": False}]
    records = run_records(_fixed_base_peg_doc(left, right))
    assert _events(records, "PartGrabbed", "PartReleased", "GrabRefused") == [
        (6, "PartGrabbed", "peg", "grabbed", "right_hand"),
        (36, "PartGrabbed", "peg", "handed_over", "left_hand"),
        (78, "PartReleased", "peg", "released", "left_hand")]
    assert [(e.from_mode, e.to_mode) for r in records for e in r.events
            if e.kind == "ModeChanged"][:2] == [("STATIC", "INHAND"), ("INHAND", "INSPACE")]
    # From the hand-over the peg follows the left hand at the offset it was taken at.
    at = records[36]
    offset = sp.sub(at.parts[0].position, at.inputs.device("left_hand").position)
    for r in records[37:78]:
        hand = r.inputs.device("left_hand").position
        assert r.parts[0].position == pytest.approx(sp.add(hand, offset), abs=1e-12)


def test_two_hands_closing_on_one_light_part_in_one_frame_do_not_pass_it_on():
    """The nearer hand takes the peg; the other, closing in the same frame, is refused
    ``held_by_other_hand`` (it does not take it over in the frame it was taken)."""
    def hand(x):
        return [{"t": 0.0, "position": [x, 0.0, 0.78], "grip": False}, {"t": 0.1, "grip": True}]
    records = run_records(_fixed_base_peg_doc(hand(-0.03), hand(0.035), duration_s=0.4))
    assert _events(records, "PartGrabbed", "GrabRefused") == [
        (6, "PartGrabbed", "peg", "grabbed", "left_hand"),
        (6, "GrabRefused", "peg", "held_by_other_hand", "right_hand")]


def test_a_pass_within_one_frame_is_a_hand_over_too():
    """The right hand opens in the frame the left closes on the peg: a hand-over (a review
    found a release and a catch, the velocity fit reset, where one frame apart it was a
    hand-over)."""
    right = [{"t": 0.0, "position": [0.0, 0.0, 0.8], "grip": False}, {"t": 0.1, "grip": True},
             {"t": 0.2, "position": [0.0, 0.0, 0.8]}, {"t": 0.5, "position": [0.0, 0.0, 1.0]},
             {"t": 0.6, "grip": False}, {"t": 1.0, "position": [0.3, -0.3, 1.0]}]
    left = [{"t": 0.0, "position": [-0.3, 0.3, 1.0], "grip": False},
            {"t": 0.5, "position": [0.0, 0.03, 1.0]}, {"t": 0.6, "grip": True},
            {"t": 1.0, "position": [0.0, 0.03, 1.0]}]
    records = run_records(_fixed_base_peg_doc(left, right, duration_s=1.0))
    assert _events(records, "PartGrabbed", "PartReleased", "GrabRefused") == [
        (6, "PartGrabbed", "peg", "grabbed", "right_hand"),
        (36, "PartGrabbed", "peg", "handed_over", "left_hand")]
    assert records[-1].parts[0].mode == "INHAND"


def test_a_hand_over_keeps_the_pose_history_for_the_release_velocity():
    """Both hands move alike (the left 3 cm beside the right), speeding up from 0.5 to 1.5
    m/s just before the left takes the peg over and lets go a frame later: the release
    velocity is that of the same motion let go by the right hand alone (the fit's window
    reaches back across the hand-over, over the change of speed)."""
    def x(t):  # still, then 0.5 m/s from 0.2 s, then 1.5 m/s from 0.6 s
        return 0.0 if t <= 0.2 else 0.5 * (t - 0.2) if t <= 0.6 else 0.2 + 1.5 * (t - 0.6)

    def hand(dy, close_t, open_t):
        # Every keyframe has its position (a keyframe without one holds the last).
        keys = [{"t": 0.0, "grip": False}, {"t": close_t, "grip": True}, {"t": 0.2},
                {"t": 0.6}, {"t": 0.8}, {"t": open_t, "grip": False}]
        return sorted(({**k, "position": [x(k["t"]), dy, 0.8]} for k in keys),
                      key=lambda k: k["t"])
    # The left hand closes at frame 38 and opens at frame 39; the speed changed at frame 36.
    # (window_fit_stops: the default window_fit_corners takes that change for a keyframed
    # corner and the last stretch's 1.5 m/s, which the history would not show.)
    def spanning(doc: dict) -> dict:
        doc.setdefault("physics", {})["release_velocity"] = "window_fit_stops"
        return doc
    passed = run_records(spanning(_fixed_base_peg_doc(hand(0.03, 0.62, 0.65),
                                                      hand(0.0, 0.1, 0.7), duration_s=0.8)))
    alone = run_records(spanning(_fixed_base_peg_doc([{"t": 0.0, "position": [-0.4, 0.3, 1.0],
                                                       "grip": False}],
                                                     hand(0.0, 0.1, 0.65), duration_s=0.8)))
    assert _events(passed, "PartGrabbed")[1][1:] == ("PartGrabbed", "peg", "handed_over",
                                                     "left_hand")
    (v_passed,) = [e.linear_velocity for r in passed for e in r.events
                   if e.kind == "PartReleased"]
    (v_alone,) = [e.linear_velocity for r in alone for e in r.events
                  if e.kind == "PartReleased"]
    assert v_passed == pytest.approx(v_alone, abs=1e-9)
    # The fit spans the change of speed (a history begun at the hand-over would give 1.5).
    assert abs(v_alone[0] - 1.5) > 0.1
