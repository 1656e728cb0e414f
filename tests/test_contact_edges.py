"""Contact at the edges of the method: skimming a surface, landing on the base part."""

from __future__ import annotations

import json
import math

import pytest

from conftest import RECORDINGS, run_records, session_doc, table
from vade_replay import spatial as sp


def _transitions(records):
    return [(e.from_mode, e.to_mode, e.cause) for r in records for e in r.events
            if e.kind == "ModeChanged"]


def test_a_part_skimming_the_table_is_not_stopped_in_mid_air():
    # 5 m/s parallel to the table, 0.15 mm above it (tolerance 0.1 mm), no gravity: it must
    # fly the whole length, however many small advancement steps that takes.
    z = 0.74 + 0.04 + 0.00015
    part = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
            "density": 2700, "pose": {"position": [-0.5, 0.0, z]}}
    doc = session_doc(parts=[part], physics={"gravity_scale_free": 0.0}, duration_s=0.6,
                      right_hand=[{"t": 0.0, "position": [-0.5, 0.0, z], "grip": False},
                                  {"t": 0.05, "grip": True},
                                  {"t": 0.2, "position": [-0.5, 0.0, z]},
                                  {"t": 0.3, "position": [0.0, 0.0, z], "grip": False},
                                  {"t": 0.4, "position": [0.5, 0.0, z]}])
    records = run_records(doc)
    assert ("INSPACE", "STATIC", "hit_environment") not in _transitions(records)
    assert records[-1].parts[0].position[0] > 1.4


def _plane_block_wall(**edits):
    doc = json.loads((RECORDINGS / "plane_block_wall.json").read_text())
    doc["environment"] = [table()]
    for path, value in edits.items():
        target = doc
        keys = path.split("/")
        for key in keys[:-1]:
            target = target[int(key)] if key.isdigit() else target[key]
        target[int(keys[-1]) if keys[-1].isdigit() else keys[-1]] = value
    return doc


def _dropped_block(landing: str = "rests") -> dict:
    """The block let go 5 cm above the plate, too far to snap onto its plane constraint;
    the base then tilts (15 deg, 30 deg). With ``landing`` rests (the paper's rule) it
    lands on the plate as on any face, on no constraint."""
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position/2": 1.032})
    doc.setdefault("physics", {})["landing"] = landing
    return doc


def test_a_part_dropped_onto_its_plane_lands_on_the_constraint_and_slides_when_tilted():
    """``physics.landing: constraints`` (the default): the block lands on its plane
    constraint, at rest, and slides once the base tilts past the friction angle (0.3:
    16.7 deg; the base goes to 30), into the wall. On no constraint (rests) it would ride
    with the base without sliding."""
    transitions = _transitions(run_records(_dropped_block("constraints")))
    assert transitions[1:] == [("INHAND", "INSPACE", "released"),
                               ("INSPACE", "ONBASESTATIC", "landed_on_constraint"),
                               ("ONBASESTATIC", "ONBASESLIDE", "static_friction_exceeded"),
                               ("ONBASESLIDE", "ONBASESTATIC", "blocked_by_base")]


def test_a_part_dropped_onto_the_base_lands_on_it_and_rides_with_it():
    # The base tilts (15 deg, 30 deg) and, in the second run, turns over.
    doc = _dropped_block()
    records = run_records(doc)
    assert ("INHAND", "INSPACE", "released") in _transitions(records)
    assert ("INSPACE", "ONBASESTATIC", "landed_on_base") in _transitions(records)
    contact = [e for r in records for e in r.events if e.kind == "ContactMade"]
    assert contact[0].other == "plate_with_wall" and contact[0].cause == "hit_base_part"
    landed = next(r.frame for r in records for e in r.events if e.cause == "landed_on_base")
    # Lying on the plate top (z 0.01 in base axes) with its bottom face, within the tolerance,
    # and fixed relative to the base from then on, while the base tilts.
    rel = []
    for r in records[landed:]:
        base = sp.Pose(r.base.position, r.base.rotation_xyzw)
        part = sp.Pose(r.parts[0].position, r.parts[0].rotation_xyzw)
        rel.append(base.inverse().compose(part))
    assert 0.01 <= rel[0].position[2] - 0.02 <= 0.01 + 1e-4
    for later in rel:
        assert sp.norm(sp.sub(later.position, rel[0].position)) < 1e-12
    assert records[-1].parts[0].mode == "ONBASESTATIC"

    # Turned over (120 deg): gravity pulls it off, and it falls to the table.
    doc["tracker"]["devices"]["left_hand"].append({"t": 3.5, "euler_deg": [-120, 0, 0]})
    transitions = _transitions(run_records(doc))
    assert ("ONBASESTATIC", "INSPACE", "gravity_lifts_off") in transitions
    assert transitions[-1] == ("INSPACE", "STATIC", "hit_environment")


def test_a_block_sliding_along_a_wall_is_not_blocked_by_it():
    # Released 0.15 mm from the wall, the base tilted so that it slides parallel to it.
    left = [{"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [0, 0, 0], "grip": True},
            {"t": 1.4, "euler_deg": [0, 0, 0]}, {"t": 2.0, "euler_deg": [0, 30, 0]}]
    doc = _plane_block_wall(**{"tracker/devices/left_hand": left,
                               "tracker/devices/right_hand/2/position/1": 0.30485,
                               "tracker/devices/right_hand/2/position/2": 0.98})
    causes = [c for _, _, c in _transitions(run_records(doc))]
    assert "blocked_by_base" not in causes
    assert "slid_off_base" in causes


def test_a_part_put_down_on_the_base_rides_with_it():
    # No constraint on this block: let go resting on the plate (0.05 mm above it), then the
    # user carries the base 0.5 m sideways. The block goes along, it does not hang in the air.
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position/2": 0.98005})
    del doc["parts"][0]["assembly"]
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [0, 0, 0], "grip": True},
        {"t": 1.5, "position": [0.0, 0.2, 0.95]}, {"t": 2.5, "position": [0.5, 0.2, 0.95]}]
    records = run_records(doc)
    assert ("INHAND", "ONBASESTATIC", "released_touching_base") in _transitions(records)
    start, end = records[70], records[-1]
    moved = sp.sub(end.parts[0].position, start.parts[0].position)
    base_moved = sp.sub(end.base.position, start.base.position)
    assert sp.norm(sp.sub(moved, base_moved)) < 1e-12 and base_moved[0] > 0.49


@pytest.mark.parametrize("depth_mm", [0.0, 6.0])
def test_a_part_let_go_overlapping_the_base_is_warned_of_with_how_deep(tmp_path, depth_mm):
    """An engineer's trial: a part let go overlapping the base (deeper than the move out of
    a flat face takes it) rides on the base so, and nothing said so. Let go resting on the
    plate (0.05 mm above it) there is no warning; let go with its bottom 6 mm into the
    plate's top, the recording warns of it, with the depth: its bottom face 6 mm under the
    plate's top (closed form; the plate's and block's faces are flat, no tessellation)."""
    from conftest import make_session
    from vade_replay.recording import Recording
    from vade_replay.replay import record, replay
    top = 0.98005 - depth_mm / 1000.0 - 0.00005 * (depth_mm > 0)
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position/2": top})
    del doc["parts"][0]["assembly"]
    out = tmp_path / "let_go.mcap"
    summary = record(make_session(doc), out)
    assert summary.transitions_by_edge.get("INHAND->ONBASESTATIC") == 1
    said = [w for w in summary.warnings if "inside the base part" in w]
    if depth_mm == 0.0:
        assert said == []
        return
    (warning,) = said
    assert warning.startswith("frame ") and "block was let go about 6 mm inside the base " \
        "part (plate_with_wall)" in warning and "released_touching_base" in warning
    # The depth itself, to the closed form, at the poses after the release frame.
    import re
    from vade_replay import replay as rp
    from vade_replay.collision import CollisionWorld
    from vade_replay.spatial import Pose
    frame = int(re.match(r"frame (\d+)", warning).group(1))
    scene = make_session(doc).build_scene()
    recorded = Recording(out)
    (after,) = [rp.recorded_record(f) for f in recorded.frames() if f.inputs.frame == frame]
    poses = (Pose(after.parts[0].position, after.parts[0].rotation_xyzw),
             Pose(after.base.position, after.base.rotation_xyzw))
    depth = rp._depth_inside(CollisionWorld(scene), scene.parts[0], scene.base, base=True,
                             poses=poses)
    assert abs(depth - depth_mm / 1000.0) < 1e-6  # (fcl's point probe: ~1e-9)
    # A replay repeats it (kept in the recording), and matches.
    again = replay(Recording(out))
    assert again.match and warning in again.recorded_warnings


@pytest.mark.parametrize("where, position", [
    ("beside the plate", [-0.17505, 0.2, 0.95]),   # 0.05 mm from its side face
    ("under the plate", [0.0, 0.2, 0.91995]),      # 0.05 mm below it
])
def test_a_face_that_cannot_hold_the_part_does_not(where, position):
    # Let go touching the base where gravity does not press it onto the face: it falls.
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position": position})
    del doc["parts"][0]["assembly"]
    transitions = _transitions(run_records(doc))
    assert ("INHAND", "INSPACE", "released") in transitions, where
    assert not any(to == "ONBASESTATIC" for _, to, _ in transitions), where
    assert transitions[-1] == ("INSPACE", "STATIC", "hit_environment"), where


def test_a_part_resting_on_a_tilted_base_stays_until_the_face_turns_over():
    # Landed on the top face; the base tilts to 70 degrees: the face still holds it up.
    doc = _dropped_block()
    doc["tracker"]["devices"]["left_hand"].append({"t": 3.9, "euler_deg": [-70, 0, 0]})
    transitions = _transitions(run_records(doc))
    assert ("INSPACE", "ONBASESTATIC", "landed_on_base") in transitions
    assert transitions[-1] == ("INSPACE", "ONBASESTATIC", "landed_on_base")


@pytest.mark.parametrize("grace", ["touched", "whole_base"])
def test_a_part_let_go_against_a_wall_falls_along_it_onto_the_plate(grace):
    """Let go at rest 0.05 mm from the wall's inner face, its bottom 20 mm above the plate:
    the wall cannot hold it, so it falls along the wall, never more than 0.05 mm from it.
    The base does not stop a part until the two have separated once (a part leaving the
    base is still touching it); with ``flight_grace`` touched (the default) that grace is
    only for the surfaces it touched as it left, here the wall's (and its top, flush with
    the block's), so the plate stops it. With
    whole_base (before 2026-11-23) never clear of the wall, it fell through the plate to
    the table."""
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position": [0.0, 0.30495, 1.0]})
    del doc["parts"][0]["assembly"]
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [0, 0, 0], "grip": True}]
    doc.setdefault("physics", {})["flight_grace"] = grace
    records = run_records(doc)
    transitions = _transitions(records)
    assert ("INHAND", "INSPACE", "released") in transitions
    released = next(r.frame for r in records for e in r.events if e.cause == "released")
    if grace == "whole_base":
        assert transitions[-1] == ("INSPACE", "STATIC", "hit_environment")
        assert records[-1].parts[0].position[2] < 0.77  # on the table, through the plate
        return
    assert transitions[-1] == ("INSPACE", "ONBASESTATIC", "landed_on_base")
    (contact,) = [e for r in records for e in r.events if e.kind == "ContactMade"]
    assert contact.other == "plate_with_wall" and contact.cause == "hit_base_part"
    # Free fall from rest under the scaled gravity, from its bottom at z 0.98 to within
    # the contact tolerance (0.1 mm) of the plate's top at z 0.96.
    g = 0.25 * 9.80665
    t_release = records[released].time_ns * 1e-9
    earliest, latest = (math.sqrt(2.0 * (0.02 - gap) / g) for gap in (1e-4, 0.0))
    assert earliest - 1e-9 <= contact.time_ns * 1e-9 - t_release <= latest + 1e-9
    for r in records[released:]:
        x, y, z = r.parts[0].position
        assert z - 0.02 >= 0.96 - 1e-12                # never into the plate
        assert 0.33 - 1e-4 <= y + 0.025 <= 0.33        # along the wall, never into it
    assert 0.96 <= records[-1].parts[0].position[2] - 0.02 <= 0.96 + 1e-4


_CORNER_BASE_AT = (0.0, 0.0, 1.1)


def _corner_session(roll: float, pitch: float, constraints=None, table_z: float = 0.72,
                    duration_s: float = 1.8) -> dict:
    """A fixed plate with a wall along its +y edge, tilted by ``roll`` and ``pitch``
    (degrees), and a block (with ``constraints``) carried by the right hand to rest
    exactly in the corner, bottom on the plate and side on the wall, and let go there."""
    q = sp.quat_from_euler_deg(roll, pitch, 0.0)
    corner = (-0.3, 0.105, 0.03)  # the block's centre: bottom on z 0.01, side on y 0.13
    at = sp.add(_CORNER_BASE_AT, sp.quat_rotate(q, corner))
    block = {"name": "block", "shape": {"type": "box", "size": [0.05, 0.05, 0.04]},
             "density": 2700, "pose": {"position": [0.5, -0.3, 0.76]}}
    if constraints:
        block["assembly"] = {"constraints": constraints}
    doc = session_doc(
        parts=[block], duration_s=duration_s,
        right_hand=[{"t": 0, "position": [0.5, -0.3, 0.76], "grip": False},
                    {"t": 0.2, "grip": True},
                    {"t": 0.8, "position": list(at), "euler_deg": [roll, pitch, 0]},
                    {"t": 1.2, "grip": False}, {"t": 1.4, "position": [0.3, -0.5, 1.3]}],
        base={"name": "plate_with_wall", "fixed": True,
              "pose": {"position": list(_CORNER_BASE_AT), "euler_deg": [roll, pitch, 0]},
              "shape": {"type": "compound", "children": [
                  {"type": "box", "size": [1.0, 0.3, 0.02]},
                  {"type": "box", "size": [1.0, 0.02, 0.06],
                   "pose": {"position": [0, 0.14, 0.04]}}]}})
    doc["environment"] = [table(size=(2.0, 2.0, 0.04), z=table_z)]
    return doc


@pytest.mark.parametrize("roll, pitch", [(20, 5), (35, 8), (5, 2)])
def test_a_block_let_go_in_the_corner_of_a_plate_and_a_leaning_wall_rests_there(roll, pitch):
    """A physics audit: a fixed plate with a wall along one edge, tilted so that the wall
    leans over the plate, and a block let go at rest touching both (its bottom on the
    plate, its side on the wall). Which face is nearest is round-off's choice; where it
    was the wall's, which cannot hold the block up, the block flew, passed the plate's top
    as a surface it touched as it left, and came to rest on the plate's bottom face, 19.9
    mm inside the 20 mm plate (5 of 15 tilts). The plate's face, touched too, holds it:
    it rests there, bottom on the plate's top, for the rest of the run."""
    doc = _corner_session(float(roll), float(pitch))
    records = run_records(doc)
    base_at, q = _CORNER_BASE_AT, sp.quat_from_euler_deg(float(roll), float(pitch), 0.0)
    assert _transitions(records)[-1] == ("INHAND", "ONBASESTATIC", "released_touching_base")
    released = next(r.frame for r in records for e in r.events
                    if e.cause == "released_touching_base")
    base = sp.Pose(base_at, q)
    for r in records[released:]:
        part = r.parts[0]
        assert part.mode == "ONBASESTATIC"
        local = base.inverse().compose(sp.Pose(part.position, part.rotation_xyzw)).position
        assert abs(local[2] - 0.03) < 1e-9 and abs(local[1] - 0.105) < 1e-9, local


def test_a_part_let_go_against_a_wall_of_two_stacked_boxes_passes_the_seam():
    """A review: the wall made of two boxes stacked (a seam at z 0.99, the lower box's top
    inside the wall, its edge flush with the wall's face), the block let go 0.5 mm above
    the seam. Falling along the wall it meets the seam's edge, whose direction (from an
    edge, not a face) leans up: it used to land on it and hang on the wall. Leaving the
    base, a part lands only on a face, so it is nudged off the seam and lands on the plate;
    with whole_base it fell through the plate."""
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position": [0.0, 0.30495, 1.0105]})
    del doc["parts"][0]["assembly"]
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [0, 0, 0], "grip": True}]
    children = doc["base"]["shape"]["children"]
    children[1] = {"type": "box", "size": [0.3, 0.02, 0.03],
                   "pose": {"position": [0.0, 0.14, 0.025]}}
    children.append({"type": "box", "size": [0.3, 0.02, 0.03],
                     "pose": {"position": [0.0, 0.14, 0.055]}})
    records = run_records(doc)
    assert _transitions(records)[-1] == ("INSPACE", "ONBASESTATIC", "landed_on_base")
    x, y, z = records[-1].parts[0].position
    assert 0.96 <= z - 0.02 <= 0.96 + 1e-4            # on the plate
    assert 0.33 - 0.01 <= y + 0.025 <= 0.33            # nudged less than 10 mm off the wall


def test_a_block_sliding_off_a_finely_meshed_plate_falls_as_off_a_coarse_one():
    """A review: ``plane_block_edge`` with its base the same geometry as a mesh of
    triangles at most 5 mm across (~60,000). The flight passes the surfaces it touched as
    it left, whole: a grace of the triangles it touched let the next ones of the plate's top
    hold it up 7 mm beyond the edge. It falls to the table, as off the coarse plate, within
    0.1 mm of where that one does."""
    import trimesh

    from conftest import make_session
    doc = json.loads((RECORDINGS / "plane_block_edge.json").read_text())
    coarse = run_records(doc)
    scene = make_session(doc).build_scene()
    vertices, faces = trimesh.remesh.subdivide_to_size(scene.base.vertices, scene.base.faces,
                                                       max_edge=0.005)
    assert len(faces) > 50_000
    doc["base"]["shape"] = {"type": "mesh", "file": "base.stl"}
    fine = run_records(doc, {"base.stl": trimesh.Trimesh(vertices, faces).export(
        file_type="stl")})
    assert _transitions(fine) == _transitions(coarse)
    assert _transitions(fine)[-1] == ("INSPACE", "STATIC", "hit_environment")
    assert math.dist(fine[-1].parts[0].position, coarse[-1].parts[0].position) < 1e-4


def test_a_part_thrown_past_the_table_is_said_to_fall_for_ever(tmp_path):
    """A researcher's trial: a part thrown past the table falls for ever (there is no
    floor), flying to the end, and the study heard only "never placed". vade-record warns
    of it, with how far past everything it is, and a replay repeats it."""
    from conftest import run_cli
    doc = json.loads((RECORDINGS / "throw_and_catch.json").read_text())
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [0.15, -0.25, 1.0], "grip": False},
        {"t": 0.3, "position": [0.0, 0.0, 0.78]}, {"t": 0.4, "grip": True},
        {"t": 0.8, "position": [0.1, 0.0, 0.85]},
        {"t": 1.0, "position": [-0.5, 0.0, 1.15], "grip": False},
        {"t": 1.3, "position": [0.1, 0.0, 1.3]}]
    (tmp_path / "s.json").write_text(json.dumps(doc))
    result = run_cli("vade-record", str(tmp_path / "s.json"), "-o", str(tmp_path / "r.mcap"))
    assert result.returncode == 0, result.stderr
    (warning,) = [w for w in result.stderr.splitlines() if "still falling" in w]
    assert warning.startswith(f"warning: {tmp_path / 's.json'}: cylinder is still falling at "
                              "the end (t = 3.000 s), ")
    assert warning.endswith("m past everything in the scene: there is no floor")
    assert "when recorded: cylinder is still falling" in run_cli(
        "vade-replay", str(tmp_path / "r.mcap")).stderr
    # The shipped throw is caught: nothing said.
    assert "still falling" not in run_cli("vade-record", str(RECORDINGS / "throw_and_catch.json"),
                                          "-o", str(tmp_path / "t.mcap")).stderr


def _block_along_a_wall_to_a_rib(sweep: str | None = None, obstacle: str | None = "rib",
                                 split: bool = False) -> dict:
    """A slab 6 mm thick let go on the plate 0.05 mm from the wall (within the contact
    tolerance: in contact with it every frame), the base tilted 45 degrees about y so that
    it slides along the wall, toward a rib 1 mm thick across its way at x 0.12 (base axes)
    which it reaches at ~0.9 m/s: 15 mm a frame, more than the slab and the rib together.
    ``obstacle`` "stop": a stop 10 mm thick there instead (its face at x 0.1195 too); None:
    nothing, the slab slides off the plate's end. ``split``: the wall is two boxes, flush,
    their seam at x 0.05."""
    doc = _plane_block_wall()
    doc["parts"][0]["shape"]["size"] = [0.006, 0.05, 0.04]
    children = doc["base"]["shape"]["children"]
    if obstacle == "rib":
        children.append({"type": "box", "size": [0.001, 0.03, 0.02],
                         "pose": {"position": [0.12, 0.115, 0.02]}})
    elif obstacle == "stop":
        children.append({"type": "box", "size": [0.01, 0.03, 0.02],
                         "pose": {"position": [0.1245, 0.115, 0.02]}})
    if split:
        children[1] = {"type": "box", "size": [0.2, 0.02, 0.06],
                       "pose": {"position": [-0.05, 0.14, 0.04]}}
        children.append({"type": "box", "size": [0.1, 0.02, 0.06],
                         "pose": {"position": [0.1, 0.14, 0.04]}})
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [0, 0, 0], "grip": True},
        {"t": 1.4, "euler_deg": [0, 0, 0]}, {"t": 2.0, "euler_deg": [0, 45, 0]}]
    doc["tracker"]["devices"]["right_hand"][2]["position"] = [0.0, 0.30495, 0.98]
    doc["tracker"]["duration_s"] = 3.0
    if sweep is not None:
        doc["physics"] = {"contact_sweep": sweep}
    return doc


@pytest.mark.parametrize("obstacle", ["rib", "stop"])
def test_a_block_sliding_along_a_wall_is_stopped_by_a_rib_across_its_way(obstacle):
    """A move that starts in contact (the slab touches the wall it slides along) used to be
    checked at the frame's end alone: a slab moving more than its thickness and the rib's
    in a frame passed through the rib and slid off the plate, and one whose frame ended
    inside a thick stop was stopped where the frame began, 8.3 mm short. ``contact_sweep:
    path`` steps it against the base less the wall it touches: blocked at the obstacle, its
    face within the contact tolerance of the obstacle's (x 0.1195), never inside it;
    ``frame_end`` keeps the old behaviour."""
    records = run_records(_block_along_a_wall_to_a_rib(obstacle=obstacle))
    assert [c for _, _, c in _transitions(records)][-2:] == ["static_friction_exceeded",
                                                             "blocked_by_base"]
    for r in records[60:]:  # let go at frame 60
        base = sp.Pose(r.base.position, r.base.rotation_xyzw)
        rel = base.inverse().compose(sp.Pose(r.parts[0].position, r.parts[0].rotation_xyzw))
        assert rel.position[0] + 0.003 <= 0.1195  # never into the obstacle
        assert 0.12995 - 1e-12 <= rel.position[1] + 0.025 <= 0.13  # along the wall
    gap = 0.1195 - (rel.position[0] + 0.003)
    assert 0.0 <= gap <= 1e-4
    before = _transitions(run_records(_block_along_a_wall_to_a_rib("frame_end", obstacle)))
    if obstacle == "rib":
        assert "slid_off_base" in [c for _, _, c in before]
    else:
        assert before == _transitions(records)  # blocked too, but a frame short (8.3 mm)


@pytest.mark.parametrize("split", [False, True])
def test_a_block_sliding_along_a_wall_slides_off_its_end(split):
    """A review of ``contact_sweep: path``: a surface met along the way at the distance the
    slab keeps from the wall (the wall's end face as the slab passes it, the second box of
    a wall built of two, flush) was taken for an obstacle, and the slab was blocked there
    for good. Met but not moved into (a tolerance of travel further is no nearer than half
    the tolerance), it is moved along: the slab slides off the plate's end as under
    ``frame_end``, with the same frames."""
    ours = run_records(_block_along_a_wall_to_a_rib(obstacle=None, split=split))
    assert "slid_off_base" in [c for _, _, c in _transitions(ours)]
    theirs = run_records(_block_along_a_wall_to_a_rib("frame_end", None, split))
    assert [r.parts for r in ours] == [r.parts for r in theirs]


def test_a_corner_constraint_the_base_leans_off_says_why_the_part_was_not_put_on_it():
    """A physics audit: a block with a ``planes`` constraint (a plate and a wall) let go
    exactly in the corner of a base leaning away from the wall (roll 20, pitch 25 deg):
    gravity pulls it off the wall, so it is not put onto the corner, and the miss read
    "released 0 mm and 0 deg off corner (tolerances 5 mm, 10 deg)", which says nothing of
    why. It says so now."""
    from vade_replay.replay import describe_miss, release_misses
    from conftest import make_session
    corner = [{"type": "planes", "name": "corner",
               "part": [{"point": [0, 0, -0.02], "normal": [0, 0, -1]},
                        {"point": [0, 0.025, 0], "normal": [0, 1, 0]}],
               "base": [{"point": [0, 0, 0.01], "normal": [0, 0, 1]},
                        {"point": [0, 0.13, 0], "normal": [0, -1, 0]}]}]
    # The wall's side raised (roll 20): gravity pulls the block off the wall.
    doc = _corner_session(20.0, 25.0, corner, table_z=0.5, duration_s=1.5)
    records = run_records(doc)
    scene = make_session(doc).build_scene()
    released = next(r for r in records for e in r.events if e.kind == "PartReleased")
    (miss,) = release_misses(scene, released, records[0].time_ns)
    assert miss["pulled_off"] is True and miss["nearest_constraint"] == "corner"
    assert describe_miss(miss).endswith(
        "off corner, where gravity pulls it off a face of it (the base leans so that it does "
        "not press the part onto each) (tolerances 5 mm, 10 deg): released_touching_base")
    # Leaning towards the wall, it is put onto the corner: no miss.
    records = run_records(_corner_session(-20.0, 25.0, corner, table_z=0.5, duration_s=1.5))
    assert any(e.cause == "released_on_constraint" for r in records for e in r.events)


def _pin_let_go_moving_across_its_bore(radius_mm: float, speed: float, depth_mm: float,
                                       constraint: bool = False) -> dict:
    """``test_shaft._pin_in_bore``'s pin (with no constraint unless ``constraint``) carried
    into the bore's mouth ``depth_mm`` deep, touching the bore's -y side (0.05 mm off it),
    and let go moving +y at ``speed`` m/s: across the bore's clearance into its far side."""
    from test_shaft import _pin_in_bore
    doc = _pin_in_bore(radius_mm)
    if not constraint:
        del doc["parts"][0]["assembly"]
    y0 = 200 - (5.0 - radius_mm) + 0.05
    z = 950 + 25 - depth_mm + 20
    doc["tracker"]["duration_s"] = 1.4
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [250, 0, 760], "grip": False}, {"t": 0.3, "grip": True},
        {"t": 0.6, "position": [30, y0 - speed * 300, z + 30]},
        {"t": 0.7, "position": [30, y0 - speed * 300, z]},
        {"t": 0.8, "position": [30, y0 - speed * 200, z]},
        {"t": 1.0, "position": [30, y0, z], "grip": False},
        {"t": 1.1, "position": [30, y0 + speed * 100, z + 20]}]
    return doc


def _deepest_into_the_boss(records, radius: float) -> float:
    """How far (m) any point of the pin's flank below the bore's mouth (z 25 mm on the
    bracket, whose hand is still at (0, 0.2, 0.95)) lies beyond the bore's 5 mm radius
    about its axis (x 30 mm, y 0): into the boss, from the release on."""
    deepest = 0.0
    for r in records:
        pin = r.parts[0]
        if pin.mode in ("INHAND", "STATIC"):
            continue
        on_base = sp.Pose((0.0, 0.2, 0.95)).inverse().compose(
            sp.Pose(pin.position, pin.rotation_xyzw))
        for k in range(64):
            a = 2.0 * math.pi * k / 64
            for z in (-0.02, -0.015, -0.01, -0.005, 0.0):
                x, y, h = on_base.apply((radius * math.cos(a), radius * math.sin(a), z))
                if h < 0.025:
                    deepest = max(deepest, math.hypot(x - 0.03, y) - 0.005)
    return deepest


@pytest.mark.parametrize("radius_mm, speed, depth_mm", [
    (4.9, 0.02, 1.0), (4.9, 0.1, 5.0), (4.95, 0.05, 0.5), (4.95, 0.1, 1.0)])
def test_a_pin_let_go_moving_across_its_bore_is_stopped_by_the_far_wall(radius_mm, speed,
                                                                        depth_mm):
    """An engineer's trial: a pin that left its bore touching one side of it passed the
    bore's wall, one surface, on the other side too (the flight passed every surface it
    touched as it left until it was 0.2 mm clear of the base, which a pin in a bore with
    0.1 mm of clearance never is), and rested 6 mm off the bore's axis, through the boss's
    wall. A surface a part leaves at a gap is met at a tenth of that gap: the far side stops the
    pin, which loses its speed into the wall (and any turning into it), falls down the bore
    and lies on the plate at its bottom, upright, within the clearance of the axis."""
    records = run_records(_pin_let_go_moving_across_its_bore(radius_mm, speed, depth_mm))
    assert _transitions(records)[-2:] == [("INHAND", "INSPACE", "released"),
                                          ("INSPACE", "ONBASESTATIC", "landed_on_base")]
    assert "hit_base_part" in [e.cause for r in records for e in r.events]
    # The pin's flank never more than the contact tolerance into the boss (a 32-gon's
    # flats are 0.024 mm inside the 5 mm circle, so the bound is the circle's).
    assert _deepest_into_the_boss(records, radius_mm * 1e-3) <= 1e-4
    pin = records[-1].parts[0]
    on_base = sp.Pose((0.0, 0.2, 0.95)).inverse().compose(
        sp.Pose(pin.position, pin.rotation_xyzw))
    x, y, z = on_base.position
    assert 0.005 <= z - 0.02 <= 0.005 + 1e-4             # its end on the plate, z 5 mm
    assert math.hypot(x - 0.03, y) <= (5.0 - radius_mm) * 1e-3 + 1e-4
    assert sp.quat_angle_between(on_base.rotation, sp.IDENTITY_QUAT) < 1e-3


def test_a_surface_left_at_distance_zero_is_passed_as_before():
    """A nominal fit (the sleeve of ``shaft_slide_off`` on its shaft, radius equal) leaves
    its surface at distance 0, which fcl cannot tell from overlap: it is passed until the
    part is clear (``step._grace``), so the sleeve falls off the shaft's end to the table."""
    doc = json.loads((RECORDINGS / "shaft_slide_off.json").read_text())
    records = run_records(doc)
    assert _transitions(records)[-1] == ("INSPACE", "STATIC", "hit_environment")


def test_a_graze_takes_out_only_the_motion_into_the_face():
    """``step._graze`` against its defining properties, for a box of three unequal moments
    at random poses, velocities, faces, touching points and face velocities: afterwards the
    touching point does not move into the face, relative to it (to 1e-12 m/s); the
    velocity changed only along the normal and the angular velocity only about the
    inertia's image of ``r x n`` (the least turning impulse); with the face still, the
    kinetic energy did not rise; a part whose touching point is not moving into the face
    keeps its turning, however its turning alone would carry the point (a review: a block
    thrown off a face lost all its spin); and one not moving into it at all is left as it
    was."""
    import random

    from conftest import make_session
    from vade_replay import step
    block = {"name": "block", "shape": {"type": "box", "size": [0.1, 0.05, 0.02]},
             "density": 2700, "pose": {"position": [0.3, 0.0, 0.78]}}
    body = make_session(session_doc(parts=[block], duration_s=0.1, right_hand=[
        {"t": 0.0, "position": [0.0, 0.0, 1.0]}])).build_scene().parts[0]
    rng = random.Random(7)

    def unit():
        v = [rng.gauss(0.0, 1.0) for _ in range(3)]
        return sp.normalize((v[0], v[1], v[2]))

    def energy(pose, v, w):
        q = sp.quat_mul(pose.rotation, body.part_from_principal)
        w_p = sp.quat_rotate(sp.quat_conj(q), w)
        return 0.5 * body.mass_kg * sp.dot(v, v) + 0.5 * sum(
            m * x * x for m, x in zip(body.principal_moments, w_p))

    changed = kept_turning = 0
    for k in range(600):
        base = sp.Pose(tuple(rng.uniform(-1, 1) for _ in range(3)),
                       sp.quat_normalize(tuple(rng.gauss(0, 1) for _ in range(4))))
        pose = sp.Pose(tuple(rng.uniform(-1, 1) for _ in range(3)),
                       sp.quat_normalize(tuple(rng.gauss(0, 1) for _ in range(4))))
        normal = unit()                                   # base axes
        corner = tuple(rng.choice((-1, 1)) * h for h in (0.05, 0.025, 0.01))
        point = base.inverse().apply(pose.apply(corner))  # base axes, on the part
        v = tuple(rng.uniform(-1, 1) for _ in range(3))
        w = tuple(rng.uniform(-5, 5) for _ in range(3))
        v_face = sp.ZERO3 if k % 2 else tuple(rng.uniform(-0.5, 0.5) for _ in range(3))
        v2, w2 = step._graze(body, base, pose, normal, point, v, w, v_face)
        n = sp.quat_rotate(base.rotation, normal)
        r = sp.sub(pose.apply(corner), pose.apply(body.center_of_mass))
        relative = sp.sub(v, v_face)
        before = sp.dot(sp.add(relative, sp.cross(w, r)), n)
        after = sp.dot(sp.add(sp.sub(v2, v_face), sp.cross(w2, r)), n)
        if sp.dot(relative, n) >= 0.0 and before >= 0.0:
            assert (v2, w2) == (v, w)
            kept_turning += sp.dot(w, sp.cross(r, n)) < 0.0
            continue
        changed += 1
        assert after >= -1e-12
        dv = sp.sub(v2, v)
        assert sp.norm(sp.cross(dv, n)) <= 1e-12 * (1.0 + sp.norm(dv))
        q = sp.quat_mul(pose.rotation, body.part_from_principal)
        a = sp.quat_rotate(sp.quat_conj(q), sp.cross(r, n))
        axis = sp.quat_rotate(q, tuple(x / m for x, m in zip(a, body.principal_moments)))
        dw = sp.sub(w2, w)
        assert sp.norm(sp.cross(dw, axis)) <= 1e-9 * sp.norm(axis) * (1.0 + sp.norm(dw))
        if v_face == sp.ZERO3:
            assert energy(pose, v2, w2) <= energy(pose, v, w) * (1.0 + 1e-12)
    assert changed > 200 and kept_turning > 20


@pytest.mark.parametrize("tilt_deg, turn_deg_s, y, z", [
    (0.5, 120.0, 199.8757, 985.0420), (0.3, 60.0, 199.9453, 985.0254),
    (-0.5, -120.0, 200.1375, 984.9565)])
def test_a_pin_let_go_turning_in_its_bore_falls_down_it_never_into_its_wall(tilt_deg,
                                                                         turn_deg_s, y, z):
    """A contact battery (a helper's, 2026-12-07): ``_pin_in_bore``'s 4.9 mm pin with no
    constraint let go 10 mm down the bore, tilted ``tilt_deg`` and turning at
    ``turn_deg_s`` about x, its lower end swinging into the wall (the hand at ``y``, ``z``
    mm). Passing the surfaces it touched as it left, it turned on to 3-11 degrees and
    rested 0.7-2.9 mm through the wall. Now the wall stops the swing: the pin comes to rest
    in the bore within half a second, never deeper in the boss than the contact tolerance
    and the two 32-gons' flats allow (0.1 + 0.024 + 0.024 mm), either on the plate at the
    bore's bottom or wedged where its tilt lets it go no further down: its width across
    the bore at the mouth, 2 r cos(tilt) + depth sin(tilt), the bore's 10 mm (no contact
    force in flight turns it upright, as one would a frictionless pin; with friction a
    tilted pin jams so)."""
    from test_shaft import _pin_in_bore
    doc = _pin_in_bore(4.9)
    del doc["parts"][0]["assembly"]
    doc["tracker"]["duration_s"] = 1.8
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [250, 0, 760], "grip": False}, {"t": 0.2, "grip": True},
        {"t": 0.85, "position": [30.0, y, z], "euler_deg": [tilt_deg - 0.15 * turn_deg_s, 0, 0]},
        {"t": 1.0, "position": [30.0, y, z], "euler_deg": [tilt_deg, 0, 0], "grip": False},
        {"t": 1.03, "euler_deg": [tilt_deg + 0.03 * turn_deg_s, 0, 0]},
        {"t": 1.3, "position": [150, 0, 1200]}]
    records = run_records(doc)
    assert _transitions(records)[-2:] == [("INHAND", "INSPACE", "released"),
                                          ("INSPACE", "ONBASESTATIC", "landed_on_base")]
    released = next(r for r in records if r.parts[0].mode == "INSPACE")
    rested = next(r for r in records if r.parts[0].mode == "ONBASESTATIC")
    assert (rested.time_ns - released.time_ns) * 1e-9 < 0.5
    pin = records[-1].parts[0]
    on_base = sp.Pose((0.0, 0.2, 0.95)).inverse().compose(
        sp.Pose(pin.position, pin.rotation_xyzw))
    assert _deepest_into_the_boss(records, 4.9e-3) <= 1.48e-4
    lowest = min(on_base.apply((4.9e-3 * math.cos(a), 4.9e-3 * math.sin(a), -0.02))[2]
                 for a in (2.0 * math.pi * k / 64 for k in range(64)))
    assert 0.005 - 1e-9 <= lowest < 0.025                       # in the bore
    if lowest > 0.005 + 1e-4:                                   # not on the plate: wedged
        tilt = sp.quat_angle_between(on_base.rotation, sp.IDENTITY_QUAT)
        width = 9.8e-3 * math.cos(tilt) + (0.025 - lowest) * math.sin(tilt)
        assert width >= 10e-3 - 2 * 1.48e-4, (tilt, lowest, width)


def _block_by_a_plate(duration_s: float, carried: list) -> dict:
    """A 20 mm block picked up off the table (0.6 m down) by the right hand, then
    ``carried`` (its later keyframes); a 400 x 400 x 10 mm plate for the base, posed by
    the left hand's keyframes the test adds; gravity 9.81 (the free flight's 0.25 of it)."""
    return session_doc(
        parts=[{"name": "block", "shape": {"type": "box", "size": [0.02, 0.02, 0.02]},
                "density": 2700, "pose": {"position": [0.25, 0.0, 0.76]}}],
        duration_s=duration_s, physics={"gravity": [0, 0, -9.81]},
        environment=[table(size=(1.2, 0.8, 0.04), z=0.6)],
        base={"name": "plate", "shape": {"type": "box", "size": [0.4, 0.4, 0.01]}},
        right_hand=[{"t": 0.0, "position": [0.25, 0.0, 0.76], "grip": False},
                    {"t": 0.1, "grip": True}, *carried])


def test_a_part_pressed_onto_a_face_too_steep_to_hold_it_slides_down_it_as_in_closed_form():
    """A review: a plate held at 87 degrees (too steep to hold a part: its normal's upward
    part, 0.052, is under 0.1), a block let go 0.05 mm off it, gravity pressing it onto
    the face. Each meeting halved the gap it was met at, and after ten it passed the face
    whole: the block came to rest 10 mm inside the plate. The gap it first left the face
    at is kept, and the block is backed out to it at each meeting: it slides down the face,
    never into it nor more than 0.1 mm off it, as a frictionless block does, s = g' t^2 / 2
    along the face with g' the free-flight gravity's part along it, to 0.1 mm (the rest of
    a frame is flown from each meeting; it used to wait, up to a frame behind)."""
    tilt = math.radians(87.0)
    q = sp.quat_from_rotvec((tilt, 0.0, 0.0))
    hand = (0.0, 0.3, 1.0)
    at = sp.add(hand, sp.quat_rotate(q, (0.0, 0.15, 0.005 + 0.01 + 5e-5)))
    doc = _block_by_a_plate(1.2, [
        {"t": 0.4, "position": list(at), "euler_deg": [87.0, 0, 0]},
        {"t": 0.6, "position": list(at), "euler_deg": [87.0, 0, 0], "grip": False},
        {"t": 0.7, "position": [0.25, 0.0, 0.9]}])
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": list(hand), "euler_deg": [87.0, 0, 0], "grip": True}]
    records = run_records(doc)
    plate = sp.Pose(hand, q)
    released = next(r for r in records if r.parts[0].mode == "INSPACE")
    start = plate.inverse().apply(released.parts[0].position)
    g_along = 0.25 * 9.81 * math.sin(tilt)
    met = 0
    for r in records[released.frame:]:
        block = r.parts[0]
        local = plate.inverse().compose(sp.Pose(block.position, block.rotation_xyzw))
        lowest = min(local.apply((sx * 0.01, sy * 0.01, sz * 0.01))[2]
                     for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)) - 0.005
        assert 0.0 <= lowest <= 1e-4, (r.frame, lowest)
        met += any(e.cause == "hit_base_part" for e in r.events)
        if block.mode != "INSPACE" or local.position[1] < -0.15:
            break
        t = (r.time_ns - released.time_ns) * 1e-9
        slid = start[1] - local.position[1]
        assert slid == pytest.approx(0.5 * g_along * t * t, abs=1e-4), (r.frame, t, slid)
    assert met > 10


@pytest.mark.parametrize("gap_mm, away_mm_s", [(5e-5, 5.0), (5e-5, 20.0), (0.3, 5.0)])
def test_a_wall_driven_into_a_falling_block_pushes_it_never_passes_into_it(gap_mm, away_mm_s):
    """Two reviews: a block let go ``gap_mm`` off a vertical plate held in the left hand,
    moving away from it at ``away_mm_s``, falls along it; then the plate is driven 20 mm
    into it. The plate passed into the block: 2.4-11 mm when a graze left the block where
    it met the plate until the next frame, which the plate had moved on into; 7.9-9.9 mm
    when the block had been let go touching the plate (a surface left at distance 0 is
    passed), whether or not it had got clear of it since. The rest of a frame is flown
    from a graze, a surface left touching is met once the block has been off it, and a
    surface met anew after the block got clear takes its new gap: the plate pushes the
    block, never more than the contact tolerance into it."""
    tilt = math.radians(90.0)
    q = sp.quat_from_rotvec((tilt, 0.0, 0.0))
    hand = (0.0, 0.3, 1.0)
    n = sp.quat_rotate(q, (0.0, 0.0, 1.0))
    at = sp.add(hand, sp.quat_rotate(q, (0.0, 0.15, 0.015 + gap_mm * 1e-3)))
    pre = sp.sub(at, sp.scale(n, away_mm_s * 1e-4))
    plate_at = [{"t": 0, "position": list(hand), "euler_deg": [90, 0, 0], "grip": True},
                {"t": 0.62, "position": list(hand), "euler_deg": [90, 0, 0]}]
    for t, push in ((0.75, 0.002), (0.85, 0.006), (1.0, 0.02)):
        plate_at.append({"t": t, "position": [hand[0], hand[1] - push, hand[2]],
                         "euler_deg": [90, 0, 0]})
    doc = _block_by_a_plate(1.0, [
        {"t": 0.4, "position": [pre[0], pre[1] - 0.03, pre[2]], "euler_deg": [90, 0, 0]},
        {"t": 0.5, "position": list(pre), "euler_deg": [90, 0, 0]},
        {"t": 0.6, "position": list(at), "euler_deg": [90, 0, 0], "grip": False},
        {"t": 0.7, "position": [0.25, 0.0, 1.2]}])
    doc["tracker"]["devices"]["left_hand"] = plate_at
    records = run_records(doc)
    assert "hit_base_part" in [e.cause for r in records for e in r.events]
    for r in records:
        block = r.parts[0]
        if block.mode in ("STATIC", "INHAND"):
            continue
        plate = sp.Pose(r.base.position, r.base.rotation_xyzw)
        local = plate.inverse().compose(sp.Pose(block.position, block.rotation_xyzw))
        lowest = min(local.apply((sx * 0.01, sy * 0.01, sz * 0.01))[2]
                     for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)) - 0.005
        assert lowest >= -1e-4, (r.frame, block.mode, lowest)


def test_a_passed_surface_is_met_at_a_tenth_of_its_gap_and_never_farther_than_the_tolerance():
    """``step._met_at``: a surface a part left at a gap is met at a tenth of it; one left
    touching (under a thousandth of the contact tolerance) is passed (0); and a gap raised
    by a part that went far from the surface (5 mm) is met no farther than the tolerance,
    as every other face is: at a tenth, it would have stopped 0.5 mm short of the face."""
    from conftest import make_session
    from vade_replay import step
    from vade_replay.collision import CollisionWorld
    from vade_replay.frames import TrackerFrame
    doc = json.loads((RECORDINGS / "plane_block_wall.json").read_text())
    for tol in (1e-4, 1e-5):
        doc.setdefault("physics", {})["contact_tolerance"] = tol
        scene = make_session(doc).build_scene()
        f = step._Frame(scene, CollisionWorld(scene), TrackerFrame(0, 0, ()), 0, [])
        assert step._met_at(f, 1.5 * tol) == pytest.approx(0.15 * tol, rel=1e-15)
        assert step._met_at(f, 0.9e-3 * tol) == 0.0
        assert step._met_at(f, 1.0e-3 * tol) == pytest.approx(1e-4 * tol, rel=1e-15)
        assert step._met_at(f, 5e-3) == tol


def test_a_block_let_go_inside_a_wall_is_moved_out_and_falls_to_the_plate():
    """A contact battery's (its ``2_block_wall_noise_seed9``): the hand's tracker noise put a
    block 0.69 mm into the base's wall as it let go, 20 mm above the plate; overlapping, no
    face told which way was out, and it rested there, held up by the wall. Let go inside
    one flat face (no deeper than 20 tolerances), it is moved out along that face's normal
    to a tenth of the tolerance from it, then let go as any block touching a wall: it falls
    along the wall and rests on the plate. Here 0.5 mm into the wall's inner face (base y
    0.13, the block's half width 25 mm), its top 0.5 mm above the wall's top, so that it is
    in the wall's top face too: out through the side, where it is least deep."""
    import sys
    sys.path.insert(0, str(RECORDINGS.parent / "tests"))
    import _contact_battery as cb
    doc = cb.block_wall(gap_m=-0.0005)
    for keyframe in doc["tracker"]["devices"]["right_hand"][2:4]:
        keyframe["position"][2] += 0.0005  # its top 0.5 mm above the wall's (base z 0.07)
    records = run_records(doc)
    tol = 1e-4
    released = next(r for r in records if any(e.kind == "PartReleased" for e in r.events))
    (event,) = [e for e in released.events if e.kind == "PartReleased"]
    assert event.cause == "released"  # flies: not "released_touching_base", held by the wall
    base = released.base
    block = released.parts[0]
    in_base = sp.Pose(tuple(base.position), tuple(base.rotation_xyzw)).inverse().compose(
        sp.Pose(tuple(block.position), tuple(block.rotation_xyzw)))
    # Its face 0.1 tolerance off the wall's (y 0.13 - 0.025 = 0.105 its centre at most).
    assert in_base.position[1] == pytest.approx(0.13 - 0.025 - 0.1 * tol, abs=1e-9)
    last = records[-1].parts[0]
    assert last.mode == "ONBASESTATIC"
    o = cb.measure(doc, records)
    assert o.max_pen_base <= tol and o.held_up and o.gap <= 2 * tol, o
    # The plate's top at base z 0.01: the block's bottom (half height 20 mm) rests on it.
    assert o.in_base[2, 3] == pytest.approx(0.01 + 0.02, abs=2 * tol)


def test_a_part_let_go_inside_the_base_is_moved_no_farther_than_out_and_never_through():
    """A review of the move out of a flat face: (1) a block turned 45 degrees across the
    plate's top edge, 0.5 mm into it, was moved 0.95 mm up (the depth read off a distance
    overestimates where the part reaches past the face's edge) and rested hovering 0.45 mm
    over the edge: it is stepped back to the face. (2) A 1.5 mm sheet let go 1.3 mm into a
    1 mm plate from above (its centre of mass below the plate's top) was moved out
    through the plate's underside, least deep, and fell to the table: a face the centre of
    mass is inside of is no way out (it rests where it is, as before the move)."""
    import sys
    sys.path.insert(0, str(RECORDINGS.parent / "tests"))
    import numpy as np

    import _contact_battery as cb
    tol, a = 1e-4, 0.0005
    doc = cb.block_wall()
    turn = cb.euler_deg_matrix((0, 45, 0))
    # Its face toward the plate's top edge (facing down and -x), the edge a under it.
    face, half = next((turn @ np.array(n, float), h) for n, h in (
        ((1, 0, 0), 0.025), ((-1, 0, 0), 0.025), ((0, 0, 1), 0.02), ((0, 0, -1), 0.02))
        if (turn @ np.array(n, float))[0] < -0.5 and (turn @ np.array(n, float))[2] < -0.5)
    centre = np.array([0.15, 0.0, 0.01 - a]) - face * half  # base axes
    hand = doc["tracker"]["devices"]["right_hand"]
    for keyframe in hand[2:4]:
        keyframe["position"] = (centre + [0.0, 0.2, 0.95]).tolist()
        keyframe["euler_deg"] = [0, 45, 0]
    records = run_records(doc)
    released = next(r for r in records if any(e.kind == "PartReleased" for e in r.events))
    z = released.parts[0].position[2] - 0.95
    # Out, and no farther than within a fifth of the tolerance of the edge (0.95 mm before).
    assert a < z - centre[2] < a + 0.3 * tol
    o = cb.measure(doc, records)
    assert o.max_pen_base <= tol and o.gap <= 2 * tol, o
    # (2) The thin plate and the sheet.
    doc = cb.block_wall()
    doc["base"]["shape"] = {"type": "box", "size": [0.3, 0.3, 0.001]}  # base z +-0.5 mm
    doc["parts"][0]["shape"] = {"type": "box", "size": [0.05, 0.05, 0.0015]}
    hand = doc["tracker"]["devices"]["right_hand"]
    for keyframe in hand[2:4]:
        keyframe["position"] = [0.0, 0.2, 0.95 + 0.0005 + 0.00075 - 0.0013]
    records = run_records(doc)
    assert records[-1].parts[0].mode == "ONBASESTATIC"  # not on the table, 200 mm below
    assert records[-1].parts[0].position[2] == pytest.approx(0.95 - 0.00005, abs=1e-6)
