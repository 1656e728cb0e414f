"""The scene warnings' approach along an axis constraint (``replay._depth_into_base``) on
finely cut meshes: a CAD user's trial, two 100k-face meshes (a peg in a bored boss, 0.2 mm
radial clearance), took ~66 s to record, ~65 s of it this check, each ~0.2 mm step past the
bore's rim a whole-mesh fcl query. It now steps to the faces a move along the axis can
meet and asks the rim, lying radially apart, once; the warnings are those of the approach
as it was (kept here as the reference)."""

from __future__ import annotations

import math

import pytest

from vade_replay import replay
from vade_replay import spatial as sp
from vade_replay.collision import SKIP_COAXIAL, SKIP_COPLANAR, CollisionWorld

from conftest import make_session


def _reference_depth(collision, part, k, mate, pose, reach, passes=None, tol=0.0):
    """``_depth_into_base`` as it was: every step the part's whole SKIP check's distance."""
    mode = SKIP_COAXIAL if mate.kind == "axis" else SKIP_COPLANAR
    axis = mate.base_dirs[0]
    if collision.base_distance(part, k, pose, mode) == math.inf:
        return 0.0
    far = collision.base_radius + math.sqrt(sp.dot(pose.position, pose.position)) + reach \
        + 0.01
    short = []
    for sign in ((1.0, -1.0) if mate.kind == "axis" else (1.0,)):
        s, nearest = far, math.inf
        for _ in range(replay._APPROACH_STEPS):
            moved = replay.Pose(tuple(p + sign * s * a for p, a in zip(pose.position, axis)),
                                pose.rotation)
            d = collision.base_distance(part, k, moved, mode)
            if d <= replay._APPROACH_TOL_M or s <= 0.0:
                break
            if s > replay._PASSING_FAR_M:
                nearest = min(nearest, d)
            s = max(0.0, s - d)
        short.append(max(s, 0.0))
        if passes is not None and s <= replay._INSIDE_BASE_M:
            passes.append(nearest)
    return min(short)


def _bracket(files: dict, name: str, physics: dict, children: list, part: str,
             base_point: list, final: list):
    """A session (mm) of a bracket (a 10 mm plate and ``children``) and a mesh part
    ``part`` (``{part}.stl`` or ``.ply`` in ``files``) on an axis along z through
    ``base_point``, to be placed at ``final``; the part let go beside it."""
    base = {"name": "bracket", "shape": {"type": "compound", "children": [
        {"type": "box", "size": [120, 80, 10]}, *children]}}
    return _session_on_an_axis(name, base, part, files, 5, base_point, final, physics,
                               constraint=f"{part}_in_bore",
                               shape=next(f for f in files if f.startswith(part + ".")))


def _peg_in_boss(peg_sections: int, bore_sections: int, physics: dict | None = None,
                 final_z: float = 25.0):
    """The trial's shape: a bracket (a 10 mm plate, and on it a boss with a 5 mm bore, 20 mm
    deep, a mesh file) and a 4.8 mm peg 40 mm long (a mesh file), both cut into many
    sections and written as 32-bit STL (the fit lands just under 0.2 mm, twice the default
    contact tolerance, as the trial's did); the final pose on the plate (z 25 mm)."""
    import trimesh
    files = {
        "boss.stl": trimesh.creation.annulus(r_min=5, r_max=12, height=20,
                                             sections=bore_sections).export(file_type="stl"),
        "peg.stl": trimesh.creation.cylinder(radius=4.8, height=40,
                                             sections=peg_sections).export(file_type="stl")}
    return _bracket(files, "peg_in_boss", {"gravity": [0, 0, -9810], **(physics or {})},
                    [{"type": "mesh", "file": "boss.stl", "pose": {"position": [30, 0, 15]}}],
                    "peg", [30, 0, 15], [30, 0, final_z])


def _warnings(session, depth=None) -> tuple[list[str], list[float], int]:
    """The scene warnings, what each approach passed, and the fcl queries the approaches
    asked; with ``depth`` as ``_depth_into_base``."""
    scene = session.build_scene()
    collision = CollisionWorld(scene)
    asked = replay._depth_into_base
    passed: list[float] = []
    queries = [0]

    def traced(*args):
        # (scene_warnings puts the counters back as they were: counted here.)
        before, count = len(args[6]), collision.stats["fcl_distance_queries"]
        result = (depth or asked)(*args)
        passed.extend(args[6][before:])
        queries[0] += collision.stats["fcl_distance_queries"] - count
        return result
    replay._depth_into_base = traced
    try:
        warnings = replay.scene_warnings(scene, collision, session.doc)
    finally:
        replay._depth_into_base = asked
    return warnings, passed, queries[0]


@pytest.mark.parametrize("physics, final_z, said", [
    ({}, 25.0, ""),                        # the trial: no warning, turned approaches run
    ({"coaxial_fit": "faces", "contact_tolerance": 0.25}, 25.0, "passes the base 0.2 mm"),
    ({"contact_tolerance": 0.25}, 25.0, ""),  # the rim in a radial fit's pair of queries
    ({"contact_tolerance": 0.3}, 25.0, ""),   # over 0.25 mm: more of the rim apart
    ({"contact_tolerance": 0.0999}, 25.0, ""),  # the rim at twice the tolerance and more
    ({}, 21.3, "about 3.7 mm into the base"),
])
def test_the_approach_warns_as_the_whole_mesh_steps_did(physics, final_z, said):
    """A 320-section peg in a 160-section bore (1,280 faces each), 0.2 mm clear: the
    scene warnings, and what each approach passed, are those of the approach that measured
    every step to the whole check, from a fraction of its fcl queries."""
    session = _peg_in_boss(320, 160, physics, final_z)
    warnings, passed, asked = _warnings(session)
    reference, reference_passed, reference_asked = _warnings(session, _reference_depth)
    assert warnings == reference
    assert (said in " ".join(warnings)) if said else not any(
        "passes the base" in w or "into the base" in w for w in warnings)
    tol = session.build_scene().physics.contact_tolerance
    assert len(passed) == len(reference_passed)
    for new, old in zip(passed, reference_passed):
        # The rim asked beside the part: the same distance; what is farther than twice the
        # tolerance may be sampled elsewhere on the way (only its side of 2 tol is read).
        assert new == pytest.approx(old, rel=1e-9) or min(new, old) >= 2.0 * tol
    if final_z == 25.0 and "coaxial_fit" in physics or not physics:
        assert reference_asked > 10 * asked


def test_a_100k_face_peg_in_its_bore_asks_a_few_fcl_queries():
    """The trial's size (100,000 faces each, the peg 25,000 sections, the bore 12,500): the
    check asks a few dozen fcl queries in all (the four approaches, each both ways), where
    the whole-mesh steps asked ~100 each way past the rim (~50 ms to ~1 s each at this size:
    minutes). The pass is the rim's, just under twice the tolerance (0.2 mm in 32 bits)."""
    session = _peg_in_boss(25_000, 12_500)
    warnings, passed, asked = _warnings(session)
    assert len(session.build_scene().base.faces) == 100_012
    assert not any("passes the base" in w or "into the base" in w for w in warnings)
    assert len(passed) == 4 and all(1.9999e-4 < p < 2e-4 for p in passed)
    assert asked < 40


def _warnings_and_fallbacks(session):
    """``_warnings`` of ``session``, and how many ways were approached as before, every step
    to the whole check (calls of ``replay._approach``)."""
    whole = replay._approach
    ways = [0]

    def counted(*args):
        ways[0] += 1
        return whole(*args)
    replay._approach = counted
    try:
        return _warnings(session), ways[0]
    finally:
        replay._approach = whole


@pytest.mark.parametrize("radius_mm", [4.9, 4.95])
def test_a_coarse_rim_whose_bound_leaves_the_warning_open_is_approached_as_before(radius_mm):
    """The 32-gon pin and bore of ``test_shaft`` (``coaxial_fit: faces``): the rim's radial
    gap is its chord's, up to 0.024 mm under what the pin passes at some turns, and a
    printed digit lies between: those ways are approached as before, every step to the
    whole check (``replay._approach``), and the warning is the reference's."""
    from test_shaft import _pin_in_bore
    doc = _pin_in_bore(radius_mm)
    doc["physics"]["coaxial_fit"] = "faces"
    session = make_session(doc)
    (warnings, passed, _), ways = _warnings_and_fallbacks(session)
    reference, reference_passed, _ = _warnings(session, _reference_depth)
    assert warnings == reference and passed == reference_passed
    assert any("passes the base" in w for w in warnings)
    assert ways > 0


def _stepped_pin_in_counterbore(tol_mm: float):
    """A pin (r 4.8, 20 mm) with a shoulder (r 6, 10 mm) seated on the step of a bore (r 5,
    20 mm) with a counterbore (r 6.15, 10 mm), 64-gons: the counterbore lies radially apart
    from the part, 0.15 mm (its chord 0.143 mm), its floor beside the shoulder only in the
    last 2 mm of the way."""
    import numpy as np
    import trimesh

    def rev(profile):
        mesh = trimesh.creation.revolve(np.array(profile, float), sections=64)
        if mesh.volume < 0:
            mesh.invert()
        return mesh.export(file_type="ply")
    files = {"pin.ply": rev([(0, -20), (4.8, -20), (4.8, 0), (6, 0), (6, 10), (0, 10),
                             (0, -20)]),
             "bore.ply": rev([(5, 5), (12, 5), (12, 25), (5, 25), (5, 5)]),
             "counterbore.ply": rev([(6.15, 25), (12, 25), (12, 35), (6.15, 35), (6.15, 25)])}
    return _bracket(files, "stepped", {"gravity": [0, 0, -9810], "contact_tolerance": tol_mm},
                    [{"type": "mesh", "file": "bore.ply"},
                     {"type": "mesh", "file": "counterbore.ply"}],
                    "pin", [0, 0, 15], [0, 0, 25])


@pytest.mark.parametrize("tol_mm, ways", [(0.1, 0), (0.145, 2)])
def test_a_counterbore_whose_floor_is_beside_the_shoulder_only_at_the_end(tol_mm, ways):
    """The passing face nearest by the bound, the counterbore's floor, is beside the part
    only within 2 mm of the final pose: its wall is asked instead, not the whole way
    approached again (all four ways were, ~1.8 times the reference's queries). At 0.145 mm
    the tolerance lies between the chord's gap and what is met at two turns: those fall back."""
    session = _stepped_pin_in_counterbore(tol_mm)
    (warnings, passed, asked), fallbacks = _warnings_and_fallbacks(session)
    reference, reference_passed, reference_asked = _warnings(session, _reference_depth)
    assert warnings == reference
    assert fallbacks == ways
    if ways == 0:
        assert asked < reference_asked


def _peg_under_a_guide_ring(physics: dict):
    """A 4.8 mm peg 8 mm long placed at z 15 mm (11 to 19 mm), under a guide ring (a 5 mm
    bore 2 mm deep at z 25 to 27 mm, a mesh file), nothing else round it: its way in from
    above passes the ring 0.2 mm clear 6 mm and more above where it ends."""
    import trimesh
    files = {
        "ring.stl": trimesh.creation.annulus(r_min=5, r_max=12, height=2,
                                             sections=160).export(file_type="stl"),
        "peg.stl": trimesh.creation.cylinder(radius=4.8, height=8,
                                             sections=320).export(file_type="stl")}
    return _bracket(files, "peg_under_ring", {"gravity": [0, 0, -9810], **physics},
                    [{"type": "mesh", "file": "ring.stl", "pose": {"position": [30, 0, 26]}}],
                    "peg", [30, 0, 15], [30, 0, 15])


@pytest.mark.parametrize("physics, said", [
    ({"coaxial_fit": "faces", "contact_tolerance": 0.25}, "passes the base 0.2 mm"),
    ({"coaxial_fit": "faces"}, ""),
])
def test_a_guide_ring_passed_well_above_the_final_pose_is_warned_of(physics, said):
    """The ring lies axially past the peg's span at its final pose (6 mm above it): the
    bound on what the way passes sweeps the part over the whole way, so the ring is met
    (0.2 mm clear, under a 0.25 mm tolerance: warned of, as by the whole-mesh steps; under
    twice 0.1 mm: no warning) and no way is told by its axial gap at the final pose."""
    session = _peg_under_a_guide_ring(physics)
    (warnings, passed, asked), fallbacks = _warnings_and_fallbacks(session)
    reference, reference_passed, reference_asked = _warnings(session, _reference_depth)
    assert warnings == reference
    assert fallbacks == 0 and asked < reference_asked  # the ring asked beside the peg
    assert (said in " ".join(warnings)) if said else not any(
        "passes the base" in w for w in warnings)
    assert min(passed) == pytest.approx(min(reference_passed), rel=1e-6)
    assert 1.9e-4 < min(passed) < 2e-4



@pytest.mark.parametrize("low_mm, high_mm, alike", [
    (0.05, 0.05, True),      # one value
    (0.0511, 0.0514, True),  # under tol, the same two printed digits (0.051)
    (0.051, 0.056, False),   # under tol, printed 0.051 and 0.056 differ
    (0.05, 0.15, False),     # tol between: warned of or not
    (0.15, 0.25, False),     # twice tol between: turned approaches run or not
    (0.12, 0.19, True),      # between tol and twice tol: neither warned nor run differently
    (0.25, 3.0, True),       # past twice tol: nothing told
])
def test_a_range_of_passing_distances_is_told_alike_only_with_no_limit_or_digit_inside(
        low_mm, high_mm, alike):
    """``_told_alike`` by what ``scene_warnings`` reads of a passing distance (tol 0.1 mm):
    under twice tol the turned approaches run, under tol it is warned of with two digits."""
    assert replay._told_alike(low_mm * 1e-3, high_mm * 1e-3, 1e-4) is alike


def test_the_passed_distance_is_open_where_no_part_face_comes_beside_the_ring():
    """``passed_distance`` on the guide ring: over the whole way down the ring is asked
    beside the peg (its bound no more than the distance met, both its 0.2 mm clearance);
    over a stretch of the way too short to bring the peg up beside it (the first 1 mm of
    the 6 mm), no face is asked and the distance is NaN (``_passed`` then falls back)."""
    session = _peg_under_a_guide_ring({"coaxial_fit": "faces", "contact_tolerance": 0.25})
    scene = session.build_scene()
    collision = CollisionWorld(scene)
    body = scene.parts[0]
    mate = body.assembly.mates[0]
    pose = sp.Pose((0.03, 0.0, 0.015), (0.0, 0.0, 0.0, 1.0))
    axis = mate.base_dirs[0]
    split = collision.axial_split(body.name, 0, pose, replay._APART_M, 5e-4)
    assert split.passing
    bound, met = collision.passed_distance(body.name, split, pose, axis, 0.002, 0.1, 0.01)
    assert 1.9e-4 < bound <= met < 2e-4
    bound, met = collision.passed_distance(body.name, split, pose, axis, 0.0, 0.001, 0.01)
    assert 5e-3 < bound < 0.01 and math.isnan(met)


def test_an_approach_with_nothing_met_beside_the_passing_faces_is_not_told():
    """``_passed``: where ``passed_distance`` met nothing beside the passing faces (NaN),
    the way is left open (None: approached as before), not told by the bound alone."""
    class Collision:
        def passed_distance(self, *args):
            return 1e-5, math.nan
    split = type("Split", (), {"passing": [object()]})()
    assert replay._passed(Collision(), "peg", split, None, (0, 0, 1), 1.0, 0.1, 1e-4) is None


def _revolved(profile, sections: int = 256) -> bytes:
    """A PLY of ``profile`` ((r, z) mm, a closed outline) turned about z, facing out."""
    import numpy as np
    import trimesh
    mesh = trimesh.creation.revolve(np.array(profile, float), sections=sections)
    if mesh.volume < 0:
        mesh.invert()
    return mesh.export(file_type="ply")


def _session_on_an_axis(name: str, base: dict, part: str, files: dict, radius: float,
                        base_point: list, final: list, physics: dict, *,
                        constraint: str | None = None, shape: str | None = None):
    """A session (mm) of the base ``base`` and the mesh part ``part`` (``{part}.ply``, or
    the file ``shape``) on an axis along z through ``base_point`` (``radius``; named
    ``{part}_on_axis``, or ``constraint``), to be placed at ``final``; the part let go
    beside it."""
    doc = {
        "format": "vade-session/1", "name": name, "units": "mm",
        "physics": physics, "base": base,
        "parts": [{"name": part, "density": 7800, "pose": {"position": [250, 0, 760]},
                   "shape": {"type": "mesh", "file": shape or f"{part}.ply"},
                   "assembly": {"constraints": [{
                       "type": "axis", "name": constraint or f"{part}_on_axis",
                       "radius": radius,
                       "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
                       "base": {"point": base_point, "direction": [0, 0, 1]}}],
                       "final_pose": {"position": final},
                       "final_tolerance": {"distance": 1, "angle_deg": 180}}}],
        "environment": [{"name": "table", "shape": {"type": "box", "size": [1200, 800, 40]},
                         "pose": {"position": [0, 0, 720]}}],
        "tracker": {"rate_hz": 60, "duration_s": 0.1, "devices": {
            "left_hand": [{"t": 0, "position": [0, 200, 950], "grip": True}],
            "right_hand": [{"t": 0.0, "position": [250, 0, 760], "grip": False}]}}}
    return make_session(doc, files)


def test_a_spacer_down_a_long_journal_inside_its_bore_is_not_stopped_short():
    """A spacer (bore r 5.6 mm, 256-gon) on a stepped shaft: its constraint's radius the
    shaft's 5 mm end, below it a journal of r 5.57 mm, 200 mm long, on a plate; the spacer
    placed on the plate. The journal lies radially inside the spacer's bore, 0.03 mm
    clear (its chord's gap: 5.6 cos(pi/256) - 5.57 mm), over twice the contact tolerance
    (0.01 mm): it is never met and nothing is warned of but the bore outside the radius.
    Measured to the journal the way down would step 0.03 mm at a time and run out of
    steps (5,000) some 50 mm above the plate: "about 20 mm into the base", as the
    whole-mesh steps of the reference said (after ~24 s)."""
    files = {"shaft.ply": _revolved([(0, 0), (5.57, 0), (5.57, 200), (5, 200), (5, 220),
                                     (0, 220), (0, 0)]),
             "spacer.ply": _revolved([(5.6, 0), (8, 0), (8, 10), (5.6, 10), (5.6, 0)])}
    base = {"name": "bracket", "shape": {"type": "compound", "children": [
        {"type": "box", "size": [120, 80, 10]},
        {"type": "mesh", "file": "shaft.ply", "pose": {"position": [0, 0, 5]}}]}}
    session = _session_on_an_axis("spacer_on_journal", base, "spacer", files, 5,
                                  [0, 0, 5], [0, 0, 5],
                                  {"gravity": [0, 0, -9810], "contact_tolerance": 0.01})
    (warnings, passed, asked), fallbacks = _warnings_and_fallbacks(session)
    assert not any("into the base" in w or "passes the base" in w for w in warnings), warnings
    assert any("no face of spacer lies within" in w for w in warnings)
    assert fallbacks == 0 and asked < 20
    # What the way down passed: the journal, by its radial gap (closed form, m; the PLY's
    # 32-bit vertices to a nanometre).
    gap = (5.6 * math.cos(math.pi / 256) - 5.57) * 1e-3
    assert passed == [pytest.approx(gap, abs=1e-9)]


def _shouldered_pin_from_below(counterbore_mm: float):
    """A housing (z 0 to 20 mm, 256-gons) with a bore of r 5 mm and, at its bottom, a
    counterbore of r 6.05 mm ``counterbore_mm`` deep; a pin (a shank of r 4.5 mm, 15 mm
    long, on a shoulder of r 6 mm, 5 mm long) pushed up into it from below, its shoulder
    on the counterbore's floor (``coaxial_fit: faces``, contact tolerance 0.1 mm). From
    above the shoulder cannot pass the bore: only the way up gets there, and the shoulder
    is beside the counterbore's wall (0.05 mm clear) over its last ``counterbore_mm``."""
    d = counterbore_mm
    files = {"pin.ply": _revolved([(0, -5), (6, -5), (6, 0), (4.5, 0), (4.5, 15), (0, 15),
                                   (0, -5)]),
             "housing.ply": _revolved([(6.05, 0), (20, 0), (20, 20), (5, 20), (5, d),
                                       (6.05, d), (6.05, 0)])}
    base = {"name": "housing", "shape": {"type": "mesh", "file": "housing.ply"}}
    return _session_on_an_axis("pin_from_below", base, "pin", files, 5, [0, 0, 0],
                               [0, 0, d], {"gravity": [0, 0, -9810], "coaxial_fit": "faces"})


@pytest.mark.parametrize("counterbore_mm, said", [
    (0.8, ""),      # beside the shoulder only in the last 0.8 mm: arriving, not passing
    (1.9, ""),      # within 2 mm of the pose still
    (2.5, "passes the base 0.05 mm clear"),  # 0.5 mm of it passed more than 2 mm away
])
def test_a_counterbore_met_from_below_only_near_the_pose_is_not_passed(counterbore_mm,
                                                                        said):
    """The way up from the axis's negative end reads what it passes more than 2 mm from
    the final pose, as the way down does: a counterbore met only within 2 mm of it (the
    shoulder's seat, 0.05 mm clear) is arriving, not a rim passed, and no "passes the
    base" (with "it is blocked there") is warned of; deeper, it is. The reference's
    warnings, each way stepped to the whole check."""
    session = _shouldered_pin_from_below(counterbore_mm)
    warnings, passed, _ = _warnings(session)
    reference, reference_passed, _ = _warnings(session, _reference_depth)
    assert warnings == reference
    assert (said in " ".join(warnings)) if said else not any(
        "passes the base" in w or "into the base" in w for w in warnings)
    assert len(passed) == len(reference_passed)
    if not said:
        # Only the way up got there, passing nothing within twice the tolerance (no turned
        # approaches ran).
        assert len(passed) == 1 and passed[0] >= 2e-4


def test_a_guide_ring_just_below_the_final_pose_is_not_approached_again():
    """The guide ring's peg placed 1 mm above the ring (a 5 mm bore 2 mm deep on the plate;
    the peg 0.2 mm inside its radius, ``coaxial_fit: faces``, contact tolerance 0.25 mm):
    the way down never brings the peg beside the ring, and more than 2 mm from the pose
    it is 3 mm above it, so the bound on what the way passes, its radial and axial gaps
    together (3 mm), is over twice the tolerance and nothing is asked of fcl for it. With
    the radial gap alone (0.2 mm) the ring would be asked where no part face comes beside
    it and the way approached again, every step to the whole check (the cost a 100k-face
    mesh pays in minutes); the warnings are the reference's either way."""
    import trimesh
    files = {
        "ring.stl": trimesh.creation.annulus(r_min=5, r_max=12, height=2,
                                             sections=160).export(file_type="stl"),
        "peg.stl": trimesh.creation.cylinder(radius=4.8, height=8,
                                             sections=320).export(file_type="stl")}
    session = _bracket(files, "peg_over_ring",
                       {"gravity": [0, 0, -9810], "coaxial_fit": "faces",
                        "contact_tolerance": 0.25},
                       [{"type": "mesh", "file": "ring.stl", "pose": {"position": [30, 0, 6]}}],
                       "peg", [30, 0, 15], [30, 0, 12])
    (warnings, passed, asked), fallbacks = _warnings_and_fallbacks(session)
    reference, reference_passed, reference_asked = _warnings(session, _reference_depth)
    assert warnings == reference
    assert not any("passes the base" in w or "into the base" in w for w in warnings)
    assert fallbacks == 0 and asked < reference_asked
    assert len(passed) == 1 and passed[0] >= 5e-4
