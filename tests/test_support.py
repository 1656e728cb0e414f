"""What holds a part up on a plane: the hull of where it meets the plane's faces
(``vade_replay.support``), a block sliding over a slot it spans (a CAD user's trial:
it "slid off" into the slot and rested 9 mm inside the plate), and a part whose centre of
mass overhangs its footprint over a groove under its arm."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from conftest import RECORDINGS, run_records
from vade_replay import spatial as sp
from vade_replay import support


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
    ((0.0, 0.0), 0.0), ((0.0, 0.0199), 0.0), ((0.02, 0.02), 0.0),   # inside, on a corner
    ((0.0, 0.03), 0.01), ((0.03, 0.03), math.sqrt(2) * 0.01)])      # past an edge, a corner
def test_the_gap_is_the_distance_outside_the_hull(foot, expected):
    assert support.support_gap(foot, SQUARE) == pytest.approx(expected, abs=1e-15)


def test_a_segment_of_contact_holds_a_foot_on_it_and_none_holds_nothing():
    segment = np.array([(-0.05, 0.0), (0.05, 0.0)])
    assert support.support_gap((0.01, 0.0), segment) == pytest.approx(0.0, abs=1e-15)
    assert support.support_gap((0.01, 0.003), segment) == pytest.approx(0.003, abs=1e-15)
    assert support.support_gap((0.08, 0.0), segment) == pytest.approx(0.03, abs=1e-15)
    assert support.support_gap((0.0, 0.0), np.zeros((0, 2))) == math.inf


@pytest.mark.parametrize("point, nearest", [
    ((0.005, -0.01), (0.005, -0.01)),                       # inside: itself
    ((0.0, 0.03), (0.0, 0.02)), ((0.03, 0.03), (0.02, 0.02)),  # past an edge, a corner
    ((-0.05, 0.001), (-0.02, 0.001))])
def test_the_hull_s_point_nearest_a_foot(point, nearest):
    d, x, y = support.nearest_in_hull(point, support.convex_hull(SQUARE))
    assert (x, y) == pytest.approx(nearest, abs=1e-15)
    assert d == pytest.approx(math.dist(point, nearest), abs=1e-15)
    assert d == support.distance_outside(point, support.convex_hull(SQUARE))
    d, x, y = support.nearest_in_hull((0.08, 0.01), np.array([(-0.05, 0.0), (0.05, 0.0)]))
    assert (d, x, y) == pytest.approx((math.hypot(0.03, 0.01), 0.05, 0.0), abs=1e-15)


def test_the_distance_to_a_part_s_pieces_in_its_plane():
    """``distance_to_pieces``, which tells whether a part's own faces cover its centre of
    mass: 0 in or on a triangle, the nearest edge or segment's distance outside; a
    triangle of no area is its edges (its sides' signs would put every point in it)."""
    tri = np.array([[(0.0, 0.0), (0.02, 0.0), (0.0, 0.02)]])
    none = np.zeros((0, 2, 2))
    assert support.distance_to_pieces((0.005, 0.005), tri, none) == 0.0
    assert support.distance_to_pieces((0.01, 0.01), tri, none) == 0.0  # on its long edge
    assert support.distance_to_pieces((0.03, 0.0), tri, none) == pytest.approx(0.01, abs=1e-15)
    flat = np.array([[(0.0, 0.0), (0.01, 0.0), (0.02, 0.0)]])
    assert support.distance_to_pieces((0.01, 0.005), flat, none) == pytest.approx(0.005,
                                                                                 abs=1e-15)
    assert support.distance_to_pieces((0.05, 0.0), flat, none) == pytest.approx(0.03,
                                                                               abs=1e-15)
    line = np.array([[(-0.05, 0.0), (0.05, 0.0)]])
    assert support.distance_to_pieces((0.01, 0.003), np.zeros((0, 3, 2)), line) == \
        pytest.approx(0.003, abs=1e-15)
    assert support.distance_to_pieces((0.0, 0.0), np.zeros((0, 3, 2)), none) == math.inf


def test_crossings_of_segments():
    a = np.array([[(-1.0, 0.0), (1.0, 0.0)], [(-1.0, 2.0), (1.0, 2.0)]])
    b = np.array([[(0.5, -1.0), (0.5, 1.0)],     # crosses the first at (0.5, 0)
                  [(-2.0, 1.0), (2.0, 1.0)],     # parallel to both: none
                  [(1.0, 2.0), (1.0, 3.0)]])     # meets the second at its end
    got = sorted(map(tuple, support.crossings(a, b)))
    assert got == [(0.5, 0.0), (1.0, 2.0)]
    assert len(support.crossings(a, np.zeros((0, 2, 2)))) == 0


def test_the_edges_that_bound_a_box_s_face_and_a_rod_s_line_of_contact():
    """A box's bottom: its four sides, not the diagonal between its two triangles. A rod
    lying on a line of its facets: that line's edge (no face lies in the plane)."""
    import trimesh
    box = trimesh.creation.box(extents=[0.04, 0.06, 0.02])
    edges = support.plane_edges(box.vertices, box.faces, (0, 0, -0.01), (0, 0, -1), 1e-6)
    ends = box.vertices[edges]
    assert len(edges) == 4 and np.all(ends[:, :, 2] == -0.01)
    assert sorted(np.round(np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1), 12)) == \
        [0.04, 0.04, 0.06, 0.06]
    rod = trimesh.creation.cylinder(radius=0.02, height=0.1, sections=48)
    rod.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    low = rod.vertices[:, 2].min()
    edges = support.plane_edges(rod.vertices, rod.faces, (0, 0, low), (0, 0, -1), 1e-6)
    ends = rod.vertices[edges]
    assert len(edges) == 1 and np.allclose(ends[0, :, 2], low, atol=1e-15)
    assert abs(ends[0, 0, 1] - ends[0, 1, 1]) == pytest.approx(0.1, abs=1e-12)


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


def _rod_doc(slot: bool) -> tuple[dict, dict]:
    """The golden's block replaced by a rod (r 20 mm, 100 mm long, 48 facets) lying along
    its slide on a line of its facets (the next line 0.17 mm up, past the tolerance)."""
    import trimesh
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    if slot:
        doc = _slotted(doc, -0.08, 0.012)
    r = 0.02
    rod = trimesh.creation.cylinder(radius=r, height=0.1, sections=48)
    rod.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    part = doc["parts"][0]
    part["shape"] = {"type": "mesh", "file": "rod.stl"}
    part["assembly"]["constraints"][0]["part"]["point"] = [0, 0, -r]
    doc["tracker"]["devices"]["right_hand"][2]["position"] = [0.0, 0.16, 0.95 + 0.01 + r + 0.002]
    return doc, {"rod.stl": rod.export(file_type="stl")}


def test_a_rod_on_a_line_of_its_facets_spans_a_slot_as_the_block_does():
    """A review: a rod whose contact with the plane is a line (no face lies on it) was
    dropped into a slot it spans (no area held it) and flew 2.4 mm into the far side's top.
    A segment of contact holds a centre of mass on it: the same frames as without the slot."""
    plain = run_records(*_rod_doc(False))
    slotted = run_records(*_rod_doc(True))
    causes = [[(r.frame, e.cause) for r in run for e in r.events if hasattr(e, "to_mode")]
              for run in (plain, slotted)]
    assert causes[0] == causes[1] and ("slid_off_base" in {c for _, c in causes[1]})
    for a, b in zip(plain, slotted):
        assert np.allclose(a.parts[0].position, b.parts[0].position, atol=1e-12)


def _u_doc(*pieces: tuple[float, float, float, float]) -> dict:
    """``plane_block_edge`` with its block made a U (two legs 5 mm wide at x = +-22.5 mm, a
    bridge over them; its centre of mass over the notch) and its plate made of ``pieces``
    (x0, x1, y0, y1: boxes 20 mm thick), beside the wall."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    part = doc["parts"][0]
    part["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.005, 0.05, 0.02], "pose": {"position": [-0.0225, 0, -0.01]}},
        {"type": "box", "size": [0.005, 0.05, 0.02], "pose": {"position": [0.0225, 0, -0.01]}},
        {"type": "box", "size": [0.05, 0.05, 0.02], "pose": {"position": [0, 0, 0.01]}}]}
    part["assembly"]["constraints"][0]["part"]["point"] = [0, 0, -0.02]
    wall = doc["base"]["shape"]["children"][1]
    doc["base"]["shape"]["children"] = [
        {"type": "box", "size": [x1 - x0, y1 - y0, 0.02],
         "pose": {"position": [(x0 + x1) / 2, (y0 + y1) / 2, 0.0]}}
        for x0, x1, y0, y1 in pieces] + [wall]
    return doc


def test_a_u_shaped_part_is_not_held_by_a_rib_under_its_notch():
    """A review: a U-shaped part (two legs 5 mm wide, 45 mm apart) whose legs are over open
    slots, with ribs under its bridge between them, was held up by the ribs, which its
    legs never touch (the first version took the hull of its corners, not its faces). It
    leaves the plane as it starts to slide, as without the ribs, and lands on the ribs."""
    y = (-0.15, 0.13)
    doc = _u_doc((-0.15, -0.03, *y), (0.03, 0.15, *y), (-0.012, -0.006, *y), (0.006, 0.012, *y))
    records = run_records(doc)
    changes = [(r.frame, e.cause) for r in records for e in r.events if hasattr(e, "to_mode")]
    sliding = next(f for f, c in changes if c == "static_friction_exceeded")
    assert (sliding, "slid_off_base") in changes  # at once: nothing holds its legs
    landed = [r for r in records if r.parts[0].mode == "ONBASESTATIC" and r.frame > sliding]
    assert landed and _in_base(landed[-1]).position[2] == pytest.approx(0.01, abs=2e-4)


def _l_part(doc: dict) -> dict:
    """``plane_block_edge``'s block made an L: a foot 50 x 50 x 20 mm on the plane and an arm
    100 mm long over it, reaching 75 mm past the foot on +x. Its centre of mass is at
    x = 33.3 mm in the part's frame, 8.3 mm past its footprint (nothing here tips a part:
    on a plate it slides as the block does)."""
    doc = copy.deepcopy(doc)
    doc["parts"][0]["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.05, 0.05, 0.02], "pose": {"position": [0, 0, -0.01]}},
        {"type": "box", "size": [0.1, 0.05, 0.02], "pose": {"position": [0.05, 0, 0.01]}}]}
    return doc


def _grooved(doc: dict, x0: float, x1: float) -> dict:
    """The plate with a groove from x0 to x1 (base frame) along its whole length (y)."""
    doc = copy.deepcopy(doc)
    plate, wall = doc["base"]["shape"]["children"]
    assert plate["size"] == [0.3, 0.3, 0.02] and "pose" not in plate

    def box(a, b):
        return {"type": "box", "size": [b - a, 0.3, 0.02],
                "pose": {"position": [(a + b) / 2, 0.0, 0.0]}}
    doc["base"]["shape"]["children"] = [box(-0.15, x0), box(x1, 0.15), wall]
    return doc


def test_an_overhanging_part_slides_over_a_groove_under_its_arm_as_over_the_plate():
    """An L-shaped part whose centre of mass overhangs its footprint, on a plate with a
    12 mm groove under its centre of mass (x 28-40 mm) and not under its footprint (x up
    to 25 mm). It "slid off" into the groove as it started to slide, fell with its foot
    through the top face it had left, and rested 19.9 mm inside the plate: the hull of
    contact (its footprint) never holds a centre of mass off it. Its footprint wholly on
    the faces now holds it as the faces under its centre of mass do: the same frames as
    without the groove to the bit until it leaves, round-off after (its leaving instant is
    found by a root of a different distance), its bottom on the plate's top while it
    slides, and it leaves in the frame its centre of mass passes the plate's edge
    (y = -0.15), not 25 mm on where its footprint's far edge does."""
    doc = _l_part(json.loads((RECORDINGS / "plane_block_edge.json").read_text()))
    plain, plain_off, _ = _slide(doc)
    grooved, off, sliding = _slide(_grooved(doc, 0.028, 0.040))
    assert off == plain_off and len(off) == 1
    assert [(r.frame, e.cause) for r in grooved for e in r.events if hasattr(e, "to_mode")] \
        == [(r.frame, e.cause) for r in plain for e in r.events if hasattr(e, "to_mode")]
    assert len(sliding) >= 15
    for r in sliding:
        assert _in_base(r).position[2] == pytest.approx(0.03, abs=1e-9)
    for a, b in zip(plain, grooved):
        if a.frame < off[0]:
            assert a.parts[0].position == b.parts[0].position
        assert np.allclose(a.parts[0].position, b.parts[0].position, rtol=0, atol=1e-8)
    before, leaving = (next(r for r in grooved if r.frame == k) for k in (off[0] - 1, off[0]))
    assert _in_base(before).position[1] > -0.15 > _in_base(leaving).position[1]
    assert grooved[-1].parts[0].mode == "STATIC"  # on the table, below the plate


def test_an_overhanging_part_whose_footprint_is_cut_by_the_groove_leaves():
    """The other side: a groove (x 15-45 mm) under its centre of mass and under 10 mm of its
    footprint leaves the footprint's point nearest the centre of mass 10 mm off what holds
    it, and it leaves the plate as it starts to slide."""
    doc = _l_part(json.loads((RECORDINGS / "plane_block_edge.json").read_text()))
    records, off, sliding = _slide(_grooved(doc, 0.015, 0.045))
    changes = [(r.frame, e.cause) for r in records for e in r.events if hasattr(e, "to_mode")]
    started = next(f for f, c in changes if c == "static_friction_exceeded")
    assert off == [started]


def test_an_overhanging_part_leaves_a_plate_s_edge_when_its_footprint_does():
    """The L's arm along its slide (toward the plate's edge, y = -0.15): its centre of mass
    passes the edge 33 mm before its foot's front edge does. Held while its footprint is
    wholly on the plate, as on the plate (its centre of mass used to decide: it left as
    that passed the edge, and landed on the plate again the next frame), it leaves in the
    frame the footprint's point nearest its centre of mass, the front edge, passes the
    plate's edge, and falls to the table."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    doc["parts"][0]["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.05, 0.05, 0.02], "pose": {"position": [0, 0, -0.01]}},
        {"type": "box", "size": [0.05, 0.1, 0.02], "pose": {"position": [0, -0.05, 0.01]}}]}
    records, off, sliding = _slide(doc)
    assert len(off) == 1
    before, leaving = (next(r for r in records if r.frame == k) for k in (off[0] - 1, off[0]))
    front = -0.025  # the foot's front edge, part frame (its centre of mass at y = -0.0333)
    assert _in_base(before).position[1] + front > -0.15 > _in_base(leaving).position[1] + front
    assert _in_base(before).position[1] - 0.0333 < -0.15  # its centre of mass past the edge
    changes = [c for r in records for e in r.events if hasattr(e, "to_mode")
               for c in [e.cause] if r.frame > off[0]]
    assert changes == ["hit_environment"]


@pytest.mark.parametrize("x0, x1", [(0.015, 0.030), (-0.030, 0.030)])
def test_an_overhanging_part_is_not_held_by_the_plate_under_its_arm(x0, x1):
    """A review: a groove cutting 10 mm of the L's footprint (x 15-30 mm) or taking all of
    it (x -30-30 mm, the foot touching nothing) held it while the plate under its arm (its
    centre of mass at x = 33.3 mm, off its own faces) was there, and slid it to the far edge
    as on the plain plate; a groove 15 mm wider (under its centre of mass too) left it at
    once. The faces under a centre of mass the part's own faces do not cover hold nothing:
    the hull of contact decides, and it leaves as it starts to slide."""
    doc = _l_part(json.loads((RECORDINGS / "plane_block_edge.json").read_text()))
    records, off, _ = _slide(_grooved(doc, x0, x1))
    changes = [(r.frame, e.cause) for r in records for e in r.events if hasattr(e, "to_mode")]
    started = next(f for f, c in changes if c == "static_friction_exceeded")
    assert off == [started]


def test_an_overhanging_part_trailing_its_arm_leaves_when_its_footprint_does():
    """A review: the L's arm trailing its slide (on +y, the plate's edge at y = -0.15
    ahead), its foot passes the edge 8.3 mm before its centre of mass does. It was held
    until its centre of mass passed, a frame with its whole footprint 3.4 mm past the edge
    and nothing under it; it leaves in the frame its footprint's point nearest its centre
    of mass (the foot's back edge) passes the edge."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    doc["parts"][0]["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.05, 0.05, 0.02], "pose": {"position": [0, 0, -0.01]}},
        {"type": "box", "size": [0.05, 0.1, 0.02], "pose": {"position": [0, 0.05, 0.01]}}]}
    records, off, _ = _slide(doc)
    assert len(off) == 1
    before, leaving = (next(r for r in records if r.frame == k) for k in (off[0] - 1, off[0]))
    back = 0.025  # the foot's back edge, part frame (its centre of mass at y = +0.0333)
    assert _in_base(before).position[1] + back > -0.15 > _in_base(leaving).position[1] + back
    assert _in_base(leaving).position[1] + 0.0333 > -0.15  # its centre of mass still over it


def test_a_u_shaped_part_is_not_held_by_a_rib_under_its_centre_of_mass():
    """A review: the U (legs 5 mm wide at x = +-22.5 mm) with both legs over open slots and
    a rib under its notch right under its centre of mass (x -3-3 mm), which it never
    touches, was held by the rib and slid 22 frames touching nothing. Its own faces do not
    cover its centre of mass, so the rib under it is not asked: it leaves as it starts to
    slide, as over the ribs beside its centre of mass."""
    y = (-0.15, 0.13)
    doc = _u_doc((-0.15, -0.03, *y), (0.03, 0.15, *y), (-0.003, 0.003, *y))
    records, off, _ = _slide(doc)
    changes = [(r.frame, e.cause) for r in records for e in r.events if hasattr(e, "to_mode")]
    started = next(f for f, c in changes if c == "static_friction_exceeded")
    assert off == [started]


def test_a_triangle_wound_either_way_covers_its_inside_and_its_edges_measure_outside():
    """``distance_to_pieces`` by closed forms: a triangle listed clockwise covers its inside
    as one listed counter-clockwise does (a part's faces on a plane face away from it), and
    a point beside an edge is that edge's perpendicular distance from it, not a corner's."""
    none = np.zeros((0, 2, 2))
    ccw = np.array([[(0.0, 0.0), (0.02, 0.0), (0.0, 0.02)]])
    cw = ccw[:, ::-1]
    for tri in (ccw, cw):
        assert support.distance_to_pieces((0.005, 0.005), tri, none) == 0.0
        assert support.distance_to_pieces((0.01, -0.004), tri, none) == \
            pytest.approx(0.004, abs=1e-15)                                  # below edge ab
        assert support.distance_to_pieces((-0.003, 0.01), tri, none) == \
            pytest.approx(0.003, abs=1e-15)                                  # left of edge ca
        assert support.distance_to_pieces((0.02, 0.02), tri, none) == \
            pytest.approx(math.sqrt(2) * 0.01, abs=1e-15)                    # past the long edge


def _leaves_as_its_hull_passes_the_edge(doc: dict, far: float) -> None:
    """On the plain plate a part held by the hull of its footprint slides off its far edge
    (y = -0.15) as the block does: it starts to slide and stays on, its bottom on the
    plate's top (z = 0.03 in the base frame), and leaves once, in the frame where the
    footprint's point nearest its centre of mass (``far`` past it along -y, part frame)
    passes the edge, not as it starts to slide."""
    records, off, sliding = _slide(doc)
    changes = [(r.frame, e.cause) for r in records for e in r.events if hasattr(e, "to_mode")]
    started = next(f for f, c in changes if c == "static_friction_exceeded")
    assert len(off) == 1 and off[0] > started
    assert len(sliding) >= 15
    for r in sliding:
        assert _in_base(r).position[2] == pytest.approx(0.03, abs=1e-9)
    before, leaving = (next(r for r in records if r.frame == k) for k in (off[0] - 1, off[0]))
    assert _in_base(before).position[1] + far > -0.15 > _in_base(leaving).position[1] + far


def test_a_u_shaped_part_on_a_plain_plate_is_held_by_its_legs():
    """The U whose centre of mass is over its notch (its own faces do not cover it), its
    legs wholly on a plain plate: the hull of its legs' contact holds it, and it slides
    off the far edge as the block does (the notch must not make it leave at once)."""
    doc = _u_doc((-0.15, 0.15, -0.15, 0.13))
    _leaves_as_its_hull_passes_the_edge(doc, 0.0)


def test_a_part_overhanging_its_footprint_by_half_a_millimetre_is_held_on_a_plate():
    """An L whose centre of mass is only ~0.53 mm past its footprint (a foot 50 mm square,
    an arm 122 mm long over it from x = -25 mm: centre of mass at x = 36 * 122 / 172 mm =
    25.53 mm): held on a plain plate as a larger overhang is (the stand-in for its centre
    of mass is the footprint's edge, on its own faces), sliding to the plate's far edge."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    doc["parts"][0]["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.05, 0.05, 0.02], "pose": {"position": [0, 0, -0.01]}},
        {"type": "box", "size": [0.122, 0.05, 0.02], "pose": {"position": [0.036, 0, 0.01]}}]}
    _leaves_as_its_hull_passes_the_edge(doc, 0.0)


def test_an_l_whose_arm_clears_the_plate_by_a_millimetre_stands_on_its_foot():
    """An L whose arm (75 mm long, beside its foot) hangs 1 mm above the plate, ten
    contact tolerances (0.1 mm) clear: only the foot's vertices are its footprint, so its
    centre of mass (x = 71250 * 62.5 / 121250 mm = 36.7 mm) overhangs it and the foot's
    edge stands for it; on a plain plate it slides to the far edge as the block does."""
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    doc["parts"][0]["shape"] = {"type": "compound", "children": [
        {"type": "box", "size": [0.05, 0.05, 0.02], "pose": {"position": [0, 0, -0.01]}},
        {"type": "box", "size": [0.075, 0.05, 0.019],
         "pose": {"position": [0.0625, 0, -0.0095]}}]}
    _leaves_as_its_hull_passes_the_edge(doc, 0.0)


def _tilted(doc: dict, q) -> dict:
    """The part described in a frame turned by ``q`` (its shape's children and its plane
    constraint's part side turned by ``q``, its starting pose by the inverse): the same
    solid in the same place, only its own frame's axes differ."""
    doc = copy.deepcopy(doc)
    part = doc["parts"][0]
    for child in part["shape"]["children"]:
        pose = child.get("pose", {})
        child["pose"] = {"position": list(sp.quat_rotate(q, tuple(pose.get("position",
                                                                     (0, 0, 0))))),
                         "xyzw": list(q)}
    side = part["assembly"]["constraints"][0]["part"]
    side["point"], side["normal"] = (list(sp.quat_rotate(q, tuple(side[k])))
                                    for k in ("point", "normal"))
    part["pose"]["xyzw"] = list(sp.quat_conj(q))
    return doc


def test_an_overhanging_part_described_in_a_tilted_frame_slides_over_the_groove_alike():
    """The L over a groove under its arm (above), its mesh and constraint given in a frame
    turned 30 degrees about x and 20 about y (a CAD export's axes): the stand-in for its
    centre of mass lies in its plane whatever the part's axes, so it slides as the upright
    L does, the same changes in the same frames, the same places to round-off."""
    doc = _grooved(_l_part(json.loads((RECORDINGS / "plane_block_edge.json").read_text())),
                   0.028, 0.040)
    q = sp.quat_mul(sp.quat_axis_angle((1, 0, 0), math.radians(30)),
                    sp.quat_axis_angle((0, 1, 0), math.radians(20)))
    upright, upright_off, _ = _slide(doc)
    tilted, off, _ = _slide(_tilted(doc, q))
    assert off == upright_off and len(off) == 1
    assert [(r.frame, e.cause) for r in tilted for e in r.events if hasattr(e, "to_mode")] \
        == [(r.frame, e.cause) for r in upright for e in r.events if hasattr(e, "to_mode")]
    for a, b in zip(upright, tilted):
        if a.frame > off[0]:
            break
        assert np.allclose(a.parts[0].position, b.parts[0].position, rtol=0, atol=1e-8)


def test_a_hull_of_one_point_is_that_point():
    """A part meeting the plane at one corner (a cone's tip, a tilted box's corner): its
    hull is that point, at the point's distance, and that point is the nearest."""
    d, x, y = support.nearest_in_hull((0.03, 0.04), np.array([(0.0, 0.0)]))
    assert (d, x, y) == pytest.approx((0.05, 0.0, 0.0), abs=1e-15)
    assert support.distance_outside((0.0, 0.0), np.array([(0.0, 0.0)])) == 0.0
