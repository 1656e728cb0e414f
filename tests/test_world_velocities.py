"""The recorded velocities of the base and of parts on it are world velocities (physics
``velocities: world``): a researcher's trial found the base turning at 0.5 rad/s recorded
at rest, and placed parts riding it too, though the schema says "world velocity"."""

from __future__ import annotations

import json
import math

import pytest

from conftest import RECORDINGS, make_session, run_records
from vade_replay import spatial as sp

PIVOT = (0.0, 0.2, 0.95)        # the left hand, about which the base turns
OMEGA = (math.pi / 2, 0.0, 0.0)  # 90 degrees about x from t 2 s to 3 s


def _shaft_placed(velocities: str | None = None) -> dict:
    """``shaft_placed`` with the base turned about x, not about its shaft (z), so that the
    sleeve on it, 35 mm above the hand, moves (~55 mm/s)."""
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    doc["tracker"]["devices"]["left_hand"][-1]["euler_deg"] = [90, 0, 0]
    if velocities is not None:
        doc.setdefault("physics", {})["velocities"] = velocities
    return doc


def test_a_placed_part_on_a_turning_base_moves_with_it():
    """``shaft_placed``: the sleeve is PLACED, then the base turns 90 degrees about x in a
    second (pi/2 rad/s, about the hand). Each frame the base's and the sleeve's recorded
    velocities are those of their centres of mass over the frame, (cm_k - cm_k-1) / dt to
    round-off, and the rigid rotation's closed form, w x (cm - pivot), to within the
    chord's turn over a frame (|w|^2 r dt); their angular velocity is w. Under
    ``relative`` (before) they were recorded at rest."""
    scene = make_session(_shaft_placed()).build_scene()
    cm_part, cm_base = scene.parts[0].center_of_mass, scene.base.center_of_mass
    records = run_records(_shaft_placed())
    turning = [k for k in range(1, len(records))
               if 2.0 + 1e-6 < records[k].time_ns * 1e-9 <= 3.0 + 1e-6]
    assert len(turning) == 60 and all(records[k].parts[0].mode == "PLACED" for k in turning)
    for k in turning:
        now, before = records[k], records[k - 1]
        dt = (now.time_ns - before.time_ns) * 1e-9
        for snap, was, cm in ((now.parts[0], before.parts[0], cm_part),
                              (now.base, before.base, cm_base)):
            at = sp.Pose(snap.position, snap.rotation_xyzw).apply(cm)
            was_at = sp.Pose(was.position, was.rotation_xyzw).apply(cm)
            assert snap.linear_velocity == pytest.approx(
                sp.scale(sp.sub(at, was_at), 1.0 / dt), abs=1e-9)
            assert snap.angular_velocity == pytest.approx(OMEGA, abs=1e-9)
            r = sp.sub(at, PIVOT)
            bound = sp.norm(OMEGA) ** 2 * sp.norm(r) * dt
            assert sp.norm(sp.sub(snap.linear_velocity, sp.cross(OMEGA, r))) <= bound
    assert sp.norm(records[turning[0]].parts[0].linear_velocity) > 0.05  # m/s: it moves
    relative = run_records(_shaft_placed("relative"))
    for k in turning:
        assert relative[k].parts[0].linear_velocity == (0.0, 0.0, 0.0)
        assert relative[k].base.angular_velocity == (0.0, 0.0, 0.0)
        assert relative[k].parts[0].position == records[k].parts[0].position


def test_a_part_sliding_on_a_tilting_base_adds_the_bases_motion():
    """``gear_tilted_shaft``: the gear slides and turns on the shaft while the base tilts.
    Its recorded velocity is its velocity relative to the base (in world axes, as
    ``relative`` records it) plus the base's at its centre of mass: the difference of the
    two runs is exactly the base's motion there, and the angular velocities differ by the
    base's."""
    doc = json.loads((RECORDINGS / "gear_tilted_shaft.json").read_text())
    scene = make_session(doc).build_scene()
    ours = run_records(doc)
    doc.setdefault("physics", {})["velocities"] = "relative"
    theirs = run_records(doc)
    cm = scene.parts[0].center_of_mass
    checked = 0
    for k in range(1, len(ours)):
        if ours[k].parts[0].mode != "ONBASESLIDE" or ours[k].base == ours[k - 1].base:
            continue
        assert ours[k].parts[0].position == theirs[k].parts[0].position
        dt = (ours[k].time_ns - ours[k - 1].time_ns) * 1e-9
        before = sp.Pose(ours[k - 1].base.position, ours[k - 1].base.rotation_xyzw)
        after = sp.Pose(ours[k].base.position, ours[k].base.rotation_xyzw)
        point = after.inverse().apply(sp.Pose(ours[k].parts[0].position,
                                              ours[k].parts[0].rotation_xyzw).apply(cm))
        v_base = sp.scale(sp.sub(after.apply(point), before.apply(point)), 1.0 / dt)
        assert sp.sub(ours[k].parts[0].linear_velocity, theirs[k].parts[0].linear_velocity) \
            == pytest.approx(v_base, abs=1e-12)
        assert sp.sub(ours[k].parts[0].angular_velocity,
                      theirs[k].parts[0].angular_velocity) == pytest.approx(
            ours[k].base.angular_velocity, abs=1e-12)
        checked += 1
    assert checked > 30
