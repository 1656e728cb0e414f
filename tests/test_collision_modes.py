"""The coplanar / coaxial collision modes of paper section 6, and stopping at contact."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from _onbase import plate_scene
from vade_replay import constraints as cn
from vade_replay import session as session_mod
from vade_replay import spatial as sp
from vade_replay.collision import CheckMode, CollisionWorld
from vade_replay.replay import simulate

RECORDINGS = Path(__file__).resolve().parent.parent / "recordings"
TOL = 1e-4


def _sleeve_world():
    s = session_mod.load(RECORDINGS / "shaft_slide_blocked.json")
    scene = s.build_scene()
    return scene, CollisionWorld(scene), scene.parts[0].assembly.mates[0]


def test_sleeve_on_shaft_modes():
    scene, world, mate = _sleeve_world()
    on_shaft = cn.recognise(mate, sp.Pose((0.0, 0.0, 0.08)))
    # Equal-diameter coaxial fit: the plain check reports it, SKIP_COAXIAL ignores it.
    assert world.base_distance("sleeve", 0, on_shaft, CheckMode.NOCARE_COPLANAR) <= TOL
    assert world.base_distance("sleeve", 0, on_shaft, CheckMode.SKIP_COAXIAL) > 0.01
    assert world.base_distance("sleeve", 0, on_shaft, CheckMode.KEEP_COPLANAR) <= TOL
    # Past the shaft's end (top at z = 0.12): KEEP no longer touches.
    off = sp.Pose((0.0, 0.0, 0.12 + 0.015 + 0.002))
    assert world.base_distance("sleeve", 0, off, CheckMode.KEEP_COPLANAR) > TOL
    # Down on the block (top at z = 0.02): SKIP_COAXIAL sees the block.
    down = sp.Pose((0.0, 0.0, 0.035))
    assert world.base_distance("sleeve", 0, down, CheckMode.SKIP_COAXIAL) <= TOL


def test_a_sleeve_leaving_its_shaft_passes_the_shaft_and_not_the_block():
    """``surfaces_within``: the base's surfaces a part touches as it leaves the base, which
    its flight passes until they separate (``Flight.grace``). The sleeve just off the
    shaft's top (its bore's bottom at the end, z 0.12) touches the shaft's side and its
    end, every face of them within the shaft's radius, and no face of the block; without
    them the base is the block, whose top (z 0.02) the sleeve's bottom (0.015 below its
    centre) is the closed-form distance from, down along the shaft, where the whole base
    is at 0."""
    scene, world, _ = _sleeve_world()
    grace = world.surfaces_within("sleeve", sp.Pose((0.0, 0.0, 0.135)), 2.0 * TOL)
    faces = np.concatenate([world._surfaces()[i].faces for i in grace])
    corners = scene.base.vertices[scene.base.faces[faces]]
    assert len(faces) == 64 + 32  # the side (in a few surfaces) and the end's fan
    assert np.hypot(corners[..., 0], corners[..., 1]).max() <= 0.01 + 1e-12
    assert corners[..., 2].min() >= 0.02 - 1e-12
    for z in (0.135, 0.1, 0.08, 0.0351):
        pose = sp.Pose((0.0, 0.0, z))
        assert world.distance_to_base("sleeve", pose) <= TOL
        assert world.distance_to_base("sleeve", pose, grace) == pytest.approx(
            z - 0.015 - 0.02, abs=1e-12)
    # Nothing touched, nothing passed: the whole base.
    assert world.surfaces_within("sleeve", sp.Pose((0.0, 0.0, 0.2)), 2.0 * TOL) == ()


@pytest.mark.parametrize("max_edge", [None, 0.02, 0.005])
def test_the_base_in_surfaces_whatever_its_tessellation(max_edge):
    """``base_surfaces``: faces joined at folds under 30 degrees whose normals stay within
    30 degrees of their first are one surface, however finely cut: the block with its
    shaft is the block's six faces, the shaft's two ends, and its side in a few surfaces,
    also cut into triangles of at most 20 or 5 mm (up to ~9,000 faces)."""
    import trimesh

    from vade_replay.collision import base_surfaces
    scene, _, _ = _sleeve_world()
    vertices, faces = scene.base.vertices, scene.base.faces
    if max_edge is not None:
        vertices, faces = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=max_edge)
        assert len(faces) > 2 * len(scene.base.faces)
    labels = base_surfaces(np.asarray(vertices), np.asarray(faces))
    sides = 0
    # Each label is its surface's least face, and each surface's faces share one normal or
    # make the shaft's side (normals across the shaft, within its radius: a subdivided
    # chord's midpoint lies inside the circle).
    for label in np.unique(labels):
        group = np.flatnonzero(labels == label)
        assert group.min() == label
        tri = np.asarray(vertices)[np.asarray(faces)[group]]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.linalg.norm(n, axis=1)[:, None]
        flat = np.all(np.abs(n - n[0]) < 1e-9)
        side = np.all(np.abs(n[:, 2]) < 1e-9) \
            and np.all(np.hypot(tri[..., 0], tri[..., 1]) <= 0.01 + 1e-9)
        assert flat or side
        assert np.all(n @ n[0] >= math.cos(math.radians(30.0)) - 1e-12)
        sides += bool(side and not flat)
    assert len(np.unique(labels)) - sides == 6 + 2 and 6 <= sides <= 12


def test_block_on_plate_modes():
    scene = plate_scene(wall=True)
    world = CollisionWorld(scene)
    middle = sp.Pose((0.0, 0.0, 0.04))
    lift = (0.0, 0.0, 2.0 * TOL)
    assert world.base_distance("cube", 0, middle, CheckMode.NOCARE_COPLANAR) <= TOL
    assert world.base_distance("cube", 0, middle, CheckMode.SKIP_COPLANAR, lift=lift) > 0.5
    assert world.base_distance("cube", 0, middle, CheckMode.KEEP_COPLANAR) <= TOL
    assert world.support_distance("cube", 0, (0.0, 0.0, 0.02)) <= TOL
    assert world.support_distance("cube", 0, (0.0, -1.01, 0.02)) > TOL
    # Near the wall (its face at y = 0.98): SKIP_COPLANAR measures the gap to it.
    near = sp.Pose((0.0, 0.98 - 0.02 - 0.003, 0.04))
    assert world.base_distance("cube", 0, near, CheckMode.SKIP_COPLANAR, lift=lift) == \
        pytest.approx(0.003, abs=1e-9)


def test_blocked_parts_stop_at_contact_not_inside_and_not_short():
    for name, mode, lift in (("plane_block_wall", CheckMode.SKIP_COPLANAR, 2.0 * TOL),
                             ("shaft_slide_blocked", CheckMode.SKIP_COAXIAL, 0.0)):
        s = session_mod.load(RECORDINGS / f"{name}.json")
        scene = s.build_scene()
        world = CollisionWorld(scene)
        last = None
        for record in simulate(scene, s.tracker_frames(), collision=world):
            last = record
        part, base = last.parts[0], last.base
        assert part.mode == "ONBASESTATIC"
        base_pose = sp.Pose(base.position, base.rotation_xyzw)
        rel = base_pose.inverse().compose(sp.Pose(part.position, part.rotation_xyzw))
        mate = scene.parts[0].assembly.mates[0]
        up = sp.scale(mate.base_dirs[0], lift) if mode is CheckMode.SKIP_COPLANAR else sp.ZERO3
        d = world.base_distance(part.name, 0, rel, mode, lift=up)
        assert 0.5 * TOL - 1e-9 <= d <= TOL + 1e-9, (name, d)


def test_feature_geometry_is_built_once_per_constraint_when_first_asked_for():
    scene, world, mate = _sleeve_world()
    assert len(mate.base_feature_faces) > 0 and len(mate.part_feature_faces) > 0
    assert not mate.base_feature_faces.flags.writeable
    fresh = CollisionWorld(scene)
    assert fresh._mates == {} and fresh._whole_obj is None  # nothing built up front
    first = fresh._mate("sleeve", 0)
    assert fresh._mate("sleeve", 0) is first and set(fresh._mates) == {("sleeve", 0)}
    # The SKIP checks' rest is built with it; the feature faces' models and the whole base
    # only when a check asks for them (a part that only turns on its shaft never does),
    # once, and the whole base is the one model the other checks share.
    assert first.base_rest is not None
    assert fresh._whole_obj is None and not first._features_built
    part_model, base_obj = first.part_feature(), first.base_feature()
    assert part_model is not None and base_obj is not None and first._features_built
    assert first.part_feature() is part_model and first.base_feature() is base_obj
    _, other, _, _ = fresh._models("sleeve", first, CheckMode.NOCARE_COPLANAR)
    assert other is fresh._whole() and fresh._whole_obj is other
    with pytest.raises(KeyError):
        fresh._mate("sleeve", 1)  # the sleeve has one constraint


def test_radial_extent_of_triangles_against_closed_forms():
    """A face's least and greatest distance from an axis (z through the origin), of the
    triangle, not its corners: a fan triangle of a disc reaches the axis (0); an annulus's
    triangle comes to its inner chord, r cos(pi / n); a wall of a bore lies between the
    chord and the corners; a triangle off to one side, to its nearest edge; a triangle
    along the axis (its shadow a segment) to the segment."""
    n, r, big = 32, 5.0, 12.0
    a0, a1 = 0.0, 2.0 * math.pi / n
    ring = [(r * math.cos(a), r * math.sin(a)) for a in (a0, a1)]
    outer = [(big * math.cos(a), big * math.sin(a)) for a in (a0, a1)]
    vertices = np.array([
        (0.0, 0.0, 0.0), (*ring[0], 0.0), (*ring[1], 0.0),          # disc fan
        (*outer[0], 0.0),                                            # annulus
        (*ring[0], 1.0), (*ring[1], 1.0),                            # bore wall
        (3.0, 4.0, 0.0), (6.0, 8.0, 0.0), (3.0, 4.0, 2.0),           # off to one side
        (1.0, -1.0, 0.0), (1.0, 1.0, 5.0), (1.0, 3.0, 0.0)])         # across x = 1
    faces = np.array([(0, 1, 2), (1, 3, 2), (1, 2, 5), (6, 7, 8), (9, 10, 11)])
    least, most = cn.radial_extent(vertices, faces, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    chord = r * math.cos(math.pi / n)
    assert least[0] == 0.0 and most[0] == pytest.approx(r, abs=1e-12)
    assert least[1] == pytest.approx(chord, abs=1e-12) and most[1] == pytest.approx(big)
    assert least[2] == pytest.approx(chord, abs=1e-12) and most[2] == pytest.approx(r)
    assert least[3] == pytest.approx(5.0) and most[3] == pytest.approx(10.0)
    assert least[4] == pytest.approx(1.0) and most[4] == pytest.approx(math.hypot(1, 3))
    # Along another axis: the same faces about x through (0, 0, 0) by a rotation.
    turn = sp.quat_from_euler_deg(0.0, 90.0, 0.0)
    moved = np.array([sp.quat_rotate(turn, tuple(v)) for v in vertices.tolist()])
    axis = sp.quat_rotate(turn, (0.0, 0.0, 1.0))
    least2, most2 = cn.radial_extent(moved, faces, (0.0, 0.0, 0.0), axis)
    assert np.allclose(least2, least, atol=1e-12) and np.allclose(most2, most, atol=1e-12)


def _pin_and_bore(pin_radius: float):
    """A 32-gon pin and a boss with a 5 mm bore on a plate, as trimesh builds them, and
    how many of the base's faces are the boss's (they come first)."""
    import trimesh
    pin = trimesh.creation.cylinder(radius=pin_radius, height=0.04, sections=32)
    boss = trimesh.creation.annulus(r_min=0.005, r_max=0.012, height=0.02, sections=32)
    boss.apply_translation((0.0, 0.0, 0.015))
    plate = trimesh.creation.box((0.12, 0.08, 0.01))
    base = trimesh.util.concatenate([boss, plate])
    return pin.vertices, pin.faces, base.vertices, base.faces, len(boss.faces)


@pytest.mark.parametrize("pin_radius, fits", [(0.005, True), (0.00495, True),
                                              (0.0049, True), (0.0048, False),
                                              (0.0053, False)])
def test_radial_fits_leave_out_the_rim_within_the_tolerance_and_nothing_else(pin_radius,
                                                                             fits):
    """The base faces a pin never meets: its bore's rim (the boss's top, whose inner chords
    are 4.976 mm from the axis) while the pin is no wider than that plus the tolerance (0.1
    mm) and no narrower than that less it; never the plate under the bore (it crosses the
    axis), and nothing for a pin 0.3 mm too wide (a collision) or 0.18 mm clear (the rim
    is farther than the tolerance anyway)."""
    pv, pf, bv, bf, boss = _pin_and_bore(pin_radius)
    # As a constraint of radius 5 mm builds it: the base without the bore's wall.
    wall = cn.axis_feature_faces(bv, bf, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.005, TOL)
    rest = np.setdiff1d(np.arange(len(bf)), wall)
    groups = cn.radial_fits(pv, pf, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), bv, bf,
                            (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), rest, TOL)
    if not fits:
        assert groups == []
        return
    (part_faces, skipped), = groups
    assert sorted(part_faces.tolist()) == list(range(len(pf)))  # every face of the pin
    least, _ = cn.radial_extent(bv, bf[skipped], (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    # Triangles with two corners on the inner ring come to its chord; with one, to it.
    chord = 0.005 * math.cos(math.pi / 32)
    assert np.all(np.isclose(least, chord, rtol=0, atol=1e-12)
                  | np.isclose(least, 0.005, rtol=0, atol=1e-12))
    # The boss's top and bottom annuli: every one of their triangles, and only those (not
    # its outer wall, 12 mm out, nor its bore's wall, which SKIP_COAXIAL leaves out anyway).
    radial = np.hypot(bv[:, 0], bv[:, 1])
    outer_wall = np.all(np.isclose(radial[bf], 0.012), axis=1)
    annuli = [i for i in range(boss) if i not in set(wall.tolist()) and not outer_wall[i]]
    assert len(annuli) == 4 * 32
    assert sorted(skipped.tolist()) == annuli


def test_radial_extent_takes_a_polygons_sides_as_the_circle_they_stand_for():
    """With ``arcs``, an edge between two corners on one ring of a cylinder or circle cut
    into a polygon counts at the corners' distance (an annulus's inner chord at 5 mm, not
    4.976 mm), and a wall's diagonal too; a flat face's edge beside the axis, whose two
    corners are a ring of two, keeps its exact distance."""
    import trimesh
    boss = trimesh.creation.annulus(r_min=0.005, r_max=0.012, height=0.02, sections=32)
    least, most = cn.radial_extent(boss.vertices, boss.faces, (0, 0, 0), (0, 0, 1), True)
    inner = np.isclose(least, 0.005, rtol=0, atol=1e-12)
    outer = np.isclose(least, 0.012, rtol=0, atol=1e-12)
    # The bore's wall and the two annuli (2 x 32 triangles each) at 5 mm, the outside at 12.
    assert np.all(inner | outer) and inner.sum() == 6 * 32 and outer.sum() == 2 * 32
    exact, _ = cn.radial_extent(boss.vertices, boss.faces, (0, 0, 0), (0, 0, 1))
    assert exact.min() == pytest.approx(0.005 * math.cos(math.pi / 32), abs=1e-12)
    # A box beside the axis: its near face 40 mm out, 4 mm wide; exact either way.
    box = trimesh.creation.box((0.004, 0.004, 0.004))
    box.apply_translation((0.042, 0.0, 0.0))
    near, _ = cn.radial_extent(box.vertices, box.faces, (0, 0, 0), (0, 0, 1), True)
    assert near.min() == pytest.approx(0.040, abs=1e-12)
