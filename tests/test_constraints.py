"""Constraint recognition, snapping, session syntax and the golden sessions' stories."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest

from _onbase import gear_scene, plate_scene
from vade_replay import constraints as cn
from vade_replay import session as session_mod
from vade_replay import spatial as sp
from vade_replay.errors import SessionError
from vade_replay.replay import simulate

RECORDINGS = Path(__file__).resolve().parent.parent / "recordings"


def _mate(scene):
    return scene.parts[0].assembly.mates[0]


def test_plane_recognised_within_tolerance_and_snapped_flush():
    mate = _mate(plate_scene())
    tilt = sp.quat_axis_angle((1.0, 1.0, 0.0), math.radians(6.0))
    near = sp.Pose((0.05, -0.1, 0.04 + 0.003), tilt)   # 3 mm above, 6 deg off
    snapped = cn.recognise(mate, near)
    assert snapped is not None
    normal = sp.quat_rotate(snapped.rotation, (0.0, 0.0, -1.0))
    assert sp.norm(sp.sub(normal, (0.0, 0.0, -1.0))) < 1e-12
    assert snapped.apply((0.0, 0.0, -0.02))[2] == pytest.approx(0.02, abs=1e-12)
    # Outside the distance or the angle tolerance (defaults 5 mm, 10 deg): not recognised.
    assert cn.recognise(mate, sp.Pose((0.0, 0.0, 0.04 + 0.006))) is None
    assert cn.recognise(mate, sp.Pose((0.0, 0.0, 0.04),
                                      sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(11)))) is None


def test_axis_recognised_either_way_round_and_snapped_onto_the_shaft():
    mate = _mate(gear_scene())
    for flip in (0.0, 180.0):
        rotation = sp.quat_mul(sp.quat_axis_angle((0.0, 0.0, 1.0), math.radians(3.0)),
                               sp.quat_from_euler_deg(90.0 + flip, 0.0, 90.0))
        near = sp.Pose((0.05, 0.002, -0.003), rotation)
        snapped = cn.recognise(mate, near)
        assert snapped is not None
        axis = sp.quat_rotate(snapped.rotation, (0.0, 0.0, 1.0))
        assert abs(abs(axis[0]) - 1.0) < 1e-12
        assert snapped.position[1:] == pytest.approx((0.0, 0.0), abs=1e-12)
        assert snapped.position[0] == pytest.approx(0.05, abs=1e-3)  # keeps its place along
    assert cn.recognise(mate, sp.Pose((0.0, 0.006, 0.0),
                                      sp.quat_from_euler_deg(90.0, 0.0, 90.0))) is None


def _doc(name: str) -> dict:
    return json.loads((RECORDINGS / f"{name}.json").read_text())


def test_session_schema_is_strict_about_constraints():
    doc = _doc("shaft_slide_blocked")
    bad = copy.deepcopy(doc)
    bad["parts"][0]["assembly"]["constraints"][0]["frictoin"] = {}
    with pytest.raises(SessionError):
        session_mod.validate(bad, file="x.json")
    bad = copy.deepcopy(doc)
    del bad["parts"][0]["assembly"]["constraints"][0]["radius"]
    with pytest.raises(SessionError):
        session_mod.validate(bad, file="x.json")
    bad = copy.deepcopy(doc)
    bad["parts"][0]["asembly"] = bad["parts"][0].pop("assembly")
    with pytest.raises(SessionError):
        session_mod.validate(bad, file="x.json")
    session_mod.validate(doc, file="x.json")


def test_axis_that_misses_the_base_is_a_session_error():
    doc = _doc("shaft_slide_blocked")
    doc["parts"][0]["assembly"]["constraints"][0]["base"]["point"] = [0.5, 0.5, 0.0]
    with pytest.raises(SessionError, match="axis radius"):
        session_mod.parse(json.dumps(doc).encode(), {}, source="x.json").build_scene()


def _story(name: str):
    s = session_mod.load(RECORDINGS / f"{name}.json")
    out, last = [], None
    for record in simulate(s.build_scene(), s.tracker_frames()):
        out += [(e.from_mode, e.to_mode, e.cause) for e in record.events
                if e.kind == "ModeChanged"]
        last = record
    return out, last


GRAB = ("STATIC", "INHAND", "grabbed")
STORIES = {
    "shaft_slide_blocked": [GRAB, ("INHAND", "ONBASESLIDE", "released_on_constraint"),
                            ("ONBASESLIDE", "ONBASESTATIC", "blocked_by_base")],
    "shaft_slide_off": [GRAB, ("INHAND", "ONBASESLIDE", "released_on_constraint"),
                        ("ONBASESLIDE", "ONBASESTATIC", "blocked_by_base"),
                        ("ONBASESTATIC", "ONBASESLIDE", "static_friction_exceeded"),
                        ("ONBASESLIDE", "INSPACE", "slid_off_base"),
                        ("INSPACE", "STATIC", "hit_environment")],
    "plane_block_wall": [GRAB, ("INHAND", "ONBASESTATIC", "released_on_constraint"),
                         ("ONBASESTATIC", "ONBASESLIDE", "static_friction_exceeded"),
                         ("ONBASESLIDE", "ONBASESTATIC", "blocked_by_base")],
    "plane_block_edge": [GRAB, ("INHAND", "ONBASESTATIC", "released_on_constraint"),
                         ("ONBASESTATIC", "ONBASESLIDE", "static_friction_exceeded"),
                         ("ONBASESLIDE", "INSPACE", "slid_off_base"),
                         ("INSPACE", "STATIC", "hit_environment")],
    "gear_pendulum": [GRAB, ("INHAND", "ONBASESLIDE", "released_on_constraint")],
    "gear_tilted_shaft": [GRAB, ("INHAND", "ONBASESLIDE", "released_on_constraint")],
    "shaft_placed": [GRAB, ("INHAND", "ONBASESLIDE", "released_on_constraint"),
                     ("ONBASESLIDE", "PLACED", "reached_final_pose")],
}


@pytest.mark.parametrize("name", sorted(STORIES))
def test_golden_session_tells_the_papers_story(name):
    transitions, last = _story(name)
    assert transitions == STORIES[name]


def test_plane_block_tilts_past_the_friction_angle_before_sliding():
    """It stays put at 15 deg and starts between 21.8 deg (atan 0.4) and the next frame."""
    s = session_mod.load(RECORDINGS / "plane_block_wall.json")
    for record in simulate(s.build_scene(), s.tracker_frames()):
        if any(e.kind == "ModeChanged" and e.cause == "static_friction_exceeded"
               for e in record.events):
            q = record.base.rotation_xyzw
            tilt = math.degrees(sp.norm(sp.quat_to_rotvec(q)))
            assert math.degrees(math.atan(0.4)) < tilt < math.degrees(math.atan(0.4)) + 0.6
            return
    raise AssertionError("never slid")
