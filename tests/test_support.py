"""What holds a part up on a plane: the hull of where it meets the plane's faces
(``vade_replay.support``), and a block sliding over a slot it spans (a CAD user's trial:
it "slid off" into the slot and rested 9 mm inside the plate)."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from conftest import RECORDINGS, run_records
from vade_replay import spatial as sp
from vade_replay import support


def _rect(x0, y0, x1, y1) -> list:
    """A rectangle as two counter-clockwise triangles."""
    return [[(x0, y0), (x1, y0), (x1, y1)], [(x0, y0), (x1, y1), (x0, y1)]]


SQUARE = np.array([(-0.02, -0.02), (0.02, -0.02), (0.02, 0.02), (-0.02, 0.02)])


def test_the_hull_is_the_outer_corners_counter_clockwise():
    inner = np.array([(0.0, 0.0), (0.01, 0.005), (0.02, 0.0)])  # inside, and on an edge
    hull = support.convex_hull(np.vstack([SQUARE, inner, SQUARE]))
    assert sorted(map(tuple, hull)) == sorted(map(tuple, SQUARE))
    area2 = sum(hull[i][0] * hull[(i + 1) % 4][1] - hull[(i + 1) % 4][0] * hull[i][1]
                for i in range(4))
    assert area2 == pytest.approx(2 * 0.04 * 0.04, rel=1e-12)  # positive: counter-clockwise
    assert len(support.convex_hull(np.array([(0, 0), (1, 1), (2, 2)]))) < 3  # collinear


@pytest.mark.parametrize("foot, expected", [
    ((0.0, 0.0), 0.0),          # over the slot, the block spanning it: held
    ((0.0, 0.015), 0.0),        # over the plate beside it
    ((0.0, 0.0199), 0.0),       # just inside the footprint
    ((0.0, 0.03), 0.01),        # past the footprint's edge: 1 cm
    ((0.03, 0.03), math.sqrt(2) * 0.01)])   # past its corner
def test_a_footprint_spanning_a_slot_holds_its_centre_over_the_slot(foot, expected):
    """A 40 mm square footprint over a plate with a 12 mm slot along x through its middle:
    the plate on both sides holds it, so the hull of where they meet is the whole square;
    the distance outside it is a closed form."""
    plate = np.array(_rect(-0.1, 0.006, 0.1, 0.1) + _rect(-0.1, -0.1, 0.1, -0.006))
    assert support.support_gap(foot, SQUARE, plate) == pytest.approx(expected, abs=1e-15)


def test_past_a_plate_s_edge_the_gap_is_the_distance_to_the_edge():
    """The plate ends at y = 0.005: the footprint meets it in y in [-0.02, 0.005]; a centre
    of mass at y inside that is held, one past it is that far out."""
    plate = np.array(_rect(-0.1, -0.1, 0.1, 0.005))
    assert support.support_gap((0.0, 0.0), SQUARE, plate) == 0.0
    assert support.support_gap((0.0, 0.012), SQUARE, plate) == pytest.approx(0.007, abs=1e-15)
    # Wholly over a hole larger than the footprint: nothing holds it.
    hole = np.array(_rect(-0.1, 0.05, 0.1, 0.1))
    assert support.support_gap((0.0, 0.0), SQUARE, hole) == math.inf
    # Touching the plane along an edge only (two corners): no area holds it.
    assert support.support_gap((0.0, 0.0), SQUARE[:2], plate) == math.inf


def test_triangles_of_the_plane_only_and_each_counter_clockwise():
    vertices = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1e-6)], float)
    faces = np.array([(0, 2, 1), (0, 1, 3), (1, 4, 2)])  # clockwise seen from +z; a wall; near
    basis = support.plane_basis((0.0, 0.0, 1.0))
    tris = support.plane_triangles(vertices, faces, (0, 0, 0), (0, 0, 1), 1e-5, basis)
    assert len(tris) == 2  # the wall's corner (0, 0, 1) is off the plane
    for a, b, c in tris:
        assert (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0.0


def _slotted(doc: dict, slot_y: float, width: float) -> dict:
    """``plane_block_edge``'s plate (0.3 x 0.3 x 0.02 m) with a slot ``width`` wide along x
    (x in [-0.1, 0.1]) centred at ``slot_y`` across the block's path."""
    doc = copy.deepcopy(doc)
    plate, wall = doc["base"]["shape"]["children"]
    assert plate["size"] == [0.3, 0.3, 0.02] and "pose" not in plate
    lo, hi = slot_y - width / 2, slot_y + width / 2

    def box(x0, x1, y0, y1):
        return {"type": "box", "size": [x1 - x0, y1 - y0, 0.02],
                "pose": {"position": [(x0 + x1) / 2, (y0 + y1) / 2, 0.0]}}
    doc["base"]["shape"]["children"] = [
        box(-0.15, 0.15, hi, 0.15), box(-0.15, 0.15, -0.15, lo),
        box(-0.15, -0.1, lo, hi), box(0.1, 0.15, lo, hi), wall]
    return doc


def _in_base(record, part_index=0):
    base = sp.Pose(record.base.position, record.base.rotation_xyzw)
    p = record.parts[part_index]
    return base.inverse().compose(sp.Pose(p.position, p.rotation_xyzw))


def _slide(doc):
    records = run_records(doc)
    off = [r.frame for r in records for e in r.events
           if getattr(e, "cause", None) == "slid_off_base"]
    sliding = [r for r in records if r.parts[0].mode == "ONBASESLIDE"]
    return records, off, sliding


def test_a_block_slides_over_a_slot_it_spans_as_over_the_whole_plate():
    """The golden ``plane_block_edge``: the plate tilts, the block (0.05 m square) slides
    off its edge. With a 20 mm slot across its path (y = -0.08, its centre of mass passes
    over it), it used to slide off into the slot. It slides over it as over the whole
    plate: the same frames, its bottom on the plate's top (z = 0.03 in the base frame) to
    round-off, off only past the far edge (y = -0.15), where the golden leaves."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    whole, whole_off, _ = _slide(doc)
    slotted, off, sliding = _slide(_slotted(doc, -0.08, 0.02))
    assert off == whole_off and len(off) == 1
    crossing = [r for r in sliding if abs(_in_base(r).position[1] + 0.08) < 0.01]
    assert len(crossing) >= 3  # its centre of mass over the slot for some frames
    for r in sliding:
        assert _in_base(r).position[2] == pytest.approx(0.03, abs=1e-9)
    for a, b in zip(whole, slotted):
        if a.frame > off[0]:
            break
        assert np.allclose(a.parts[0].position, b.parts[0].position, atol=1e-12)
    leaving = next(r for r in slotted if r.frame == off[0])
    assert _in_base(leaving).position[1] < -0.15  # its centre of mass past the far edge


def test_a_block_over_a_slot_wider_than_it_falls_in():
    """The other side: a slot wider than the block (70 mm) holds nothing under it, and it
    leaves the plate as its centre of mass passes the slot's near edge."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    _, off, sliding = _slide(_slotted(doc, -0.09, 0.07))
    assert len(off) == 1
    y = _in_base(sliding[-1]).position[1]
    assert -0.055 - 0.02 < y < -0.055 + 0.002  # the last frame on it: near the near edge
