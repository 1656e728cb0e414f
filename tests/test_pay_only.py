"""A scene pays only for what it needs, and the savings change no result.

Each shortcut (resting parts skipped, snapshots and their text reused, a held slide not
integrated, a part turning inside its envelope not queried) is checked twice: the counters
show the work is gone, and turning the shortcut off gives the same frames bit for bit.
"""

from __future__ import annotations

import json

import pytest

from conftest import RECORDINGS, make_session
from vade_replay import step as step_module
from vade_replay.bench.sessions import three_part_session
from vade_replay.collision import CollisionWorld
from vade_replay.recording import Recording
from vade_replay.replay import simulate
from vade_replay.session import load


def _run(session):
    scene = session.build_scene()
    world = CollisionWorld(scene)
    records = list(simulate(scene, session.tracker_frames(), collision=world))
    return records, world.stats


def _values(records):
    return [(r.frame, r.base, tuple(r.parts), r.events) for r in records]


def _moving_part(resting: int, duration: float = 6.0):
    return make_session(three_part_session(duration, static_parts=resting, gear=False, box=False))


def test_resting_parts_cost_no_queries_and_no_integration():
    alone, alone_stats = _run(_moving_part(0))
    crowd, crowd_stats = _run(_moving_part(60))
    # The cylinder's story is the same among 60 resting boxes ...
    assert [r.parts[0] for r in alone] == [r.parts[0] for r in crowd]
    # ... and costs the same work: grabbing looks at each box once through a bounding
    # sphere, and nothing else ever looks at them.
    for key in ("fcl_distance_queries", "integrator_steps", "closed_form_evals"):
        assert crowd_stats[key] == alone_stats[key], key
    grabs = sum(1 for r in alone for e in r.events if e.kind == "PartGrabbed")
    assert grabs >= 2
    assert crowd_stats["bounding_tests"] == alone_stats["bounding_tests"] + 60 * grabs
    # The boxes never moved and their snapshots are the very same objects frame to frame.
    assert all(crowd[i].parts[5] is crowd[i + 1].parts[5] for i in range(len(crowd) - 1))
    assert crowd[-1].parts[5].mode == "STATIC"


def test_reused_snapshots_equal_snapshots_made_afresh(monkeypatch):
    session = _moving_part(8)
    reused, _ = _run(session)
    monkeypatch.setattr(step_module, "_REUSE_SNAPSHOTS", False)
    fresh, _ = _run(session)
    assert _values(reused) == _values(fresh)

    def shared(records):  # snapshots carried over from the frame before, as objects
        return sum(a is b for r0, r1 in zip(records, records[1:])
                   for a, b in zip(r0.parts, r1.parts))
    assert shared(reused) > 0 and shared(fresh) == 0
    # A base held in a moving hand, with a part turning on it and one placed: the world
    # velocities (physics ``velocities``) too (a review: they were the relative ones where
    # snapshots were made afresh).
    gear = make_session(three_part_session(4.0))
    monkeypatch.setattr(step_module, "_REUSE_SNAPSHOTS", True)
    reused, _ = _run(gear)
    assert any(r.base.angular_velocity != (0.0, 0.0, 0.0) for r in reused)
    monkeypatch.setattr(step_module, "_REUSE_SNAPSHOTS", False)
    fresh, _ = _run(gear)
    assert _values(reused) == _values(fresh)


def test_a_resting_part_among_many_can_be_grabbed():
    doc = three_part_session(3.0, static_parts=30, gear=False, box=False)
    # Reach for the box in the middle of the grid instead of the cylinder.
    target = doc["parts"][16]
    x, y, z = target["pose"]["position"]
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [x, y, z + 0.01], "grip": False}, {"t": 0.5, "grip": True},
        {"t": 1.0, "position": [x, y, z + 0.2]}]
    records, _ = _run(make_session(doc))
    grabbed = [e.part for r in records for e in r.events if e.kind == "PartGrabbed"]
    assert grabbed == [target["name"]]
    moved = next(p for p in records[-1].parts if p.name == target["name"])
    assert moved.mode == "INHAND" and moved.position[2] > z + 0.15


def test_a_slide_held_by_static_friction_is_not_integrated_and_changes_nothing(monkeypatch):
    session = load(RECORDINGS / "gear_pendulum.json")
    fast, fast_stats = _run(session)
    monkeypatch.setattr(step_module, "_STATIC_HOLD", False)
    slow, slow_stats = _run(session)
    assert _values(fast) == _values(slow)
    assert fast_stats["closed_form_evals"] == 0 < slow_stats["closed_form_evals"]


def test_turning_against_the_base_inside_the_envelope_needs_one_query_a_frame(monkeypatch):
    session = load(RECORDINGS / "gear_tilted_shaft.json")
    fast, fast_stats = _run(session)
    monkeypatch.setattr(step_module, "_INSIDE_ENVELOPE", False)
    slow, slow_stats = _run(session)
    assert _values(fast) == _values(slow)
    # Resting against the stand while it swings: the start distance is still asked for
    # (a part that has turned away from the stand is not in contact), the end's is not.
    turning_frames = sum(1 for r in fast if r.parts[0].mode == "ONBASESLIDE")
    assert fast_stats["fcl_distance_queries"] <= turning_frames
    assert fast_stats["fcl_distance_queries"] * 1.8 < slow_stats["fcl_distance_queries"]


def test_a_part_lying_flat_against_the_base_is_asked_by_its_witness_pair(monkeypatch):
    """The gear swings while its face lies flat against the stand: hundreds of its
    triangles at one distance, which no bounding volume prunes. The pair of triangles that
    last touched answers "still in contact?" instead, and the frames are the same."""
    from vade_replay import collision as collision_module
    session = load(RECORDINGS / "gear_tilted_shaft.json")
    fast, fast_stats = _run(session)
    monkeypatch.setattr(collision_module, "_WITNESS_PAIRS", False)
    slow, slow_stats = _run(session)
    assert _values(fast) == _values(slow)
    assert slow_stats["witness_tests"] == 0
    # Every question is still asked, nearly all of them of one pair of triangles: more
    # than four in five (188 of 215; a question the pair does not answer may ask fcl twice,
    # the gear's bulk and its faces that never meet the shaft's end: coaxial_fit radial).
    assert fast_stats["witness_tests"] + fast_stats["fcl_distance_queries"] \
        >= slow_stats["fcl_distance_queries"]
    assert fast_stats["witness_tests"] > 4 * fast_stats["fcl_distance_queries"]
    assert fast_stats["fcl_distance_queries"] * 5 < slow_stats["fcl_distance_queries"]


def test_the_witness_pair_answers_as_the_whole_meshes_do():
    """``base_distance_within`` against ``base_distance``, the gear posed along a path that
    comes flat against the stand, swings there, backs off across the tolerance and comes in
    again, tilted: within the tolerance both or neither, and any answer outside it exact."""
    import math

    from vade_replay import spatial as sp
    from vade_replay.collision import CheckMode
    scene = load(RECORDINGS / "gear_tilted_shaft.json").build_scene()
    world = CollisionWorld(scene)
    tol = scene.physics.contact_tolerance
    # The gear on the shaft (base x), its face 0.005 m from its frame: at x = 0.005 + g its
    # face is g from the stand's face, at any angle about the shaft.
    on_shaft = (0.5, 0.5, 0.5, 0.5)
    path = [(0.005 + g, a, 0.0) for g in (3 * tol, 1.5 * tol, 0.9 * tol, 0.59 * tol)
            for a in (0.0, 0.1)]
    path += [(0.005 + 0.59 * tol, 0.02 * k, 0.0) for k in range(60)]       # swinging flat
    path += [(0.005 + g * tol, 1.0, 0.0) for g in (0.99, 0.999999, 1.0, 1.000001, 1.01, 2.0)]
    path += [(0.005 + 0.5 * tol, 1.3, tilt) for tilt in (0.0, 1e-3, 2e-3, 5e-3, 1e-2)]
    # Around the shaft just in and just out of the tolerance: the witness triangle leaves the
    # stand's triangle it was found over.
    path += [(0.005 + g * tol, 0.5 * k, 0.0) for k in range(13) for g in (0.9, 2.0)]
    within = 0
    for x, angle, tilt in path:
        turn = sp.quat_mul(sp.quat_unit_axis_angle((1.0, 0.0, 0.0), angle),
                           sp.quat_unit_axis_angle((0.0, 0.0, 1.0), tilt))
        rel = sp.Pose((x, 0.0, 0.0), sp.quat_normalize(sp.quat_mul(turn, on_shaft)))
        exact = world.base_distance("gear", 0, rel, CheckMode.SKIP_COAXIAL)
        answer = world.base_distance_within("gear", 0, rel, CheckMode.SKIP_COAXIAL, tol)
        assert (answer <= tol) == (exact <= tol), (x, angle, tilt, exact, answer)
        assert answer <= tol or answer == exact
        assert answer >= exact or math.isclose(answer, exact, abs_tol=1e-15)
        within += exact <= tol
    # The witness answered most of the swing without the whole meshes.
    assert world.stats["witness_tests"] > 50 and within > 60


def _pin_near_the_teeth(angle_deg: float, gap_m: float) -> dict:
    """gear_pendulum with a 4 mm pin on the stand, ``gap_m`` outside the gear's tooth tips:
    the envelope (a cylinder at the tip radius) is within the contact tolerance of the pin,
    while the gear, released with a groove facing it, is not yet."""
    import copy
    import math
    doc = copy.deepcopy(json.loads((RECORDINGS / "gear_pendulum.json").read_text()))
    r = 0.04 + gap_m + 0.002
    a = math.radians(angle_deg)
    doc["base"]["shape"]["children"].append(
        {"type": "box", "size": [0.004, 0.004, 0.004],
         "pose": {"position": [0.12, r * math.cos(a), r * math.sin(a)],
                  "euler_deg": [angle_deg, 0, 0]}})
    return doc


@pytest.mark.parametrize("physics, blocks", [
    ({"coaxial_fit": "faces", "passing_contact": "block"}, True),
    ({"coaxial_fit": "faces", "passing_contact": "pass"}, False),
    ({}, False)])
@pytest.mark.parametrize("angle", [15, 180])
def test_a_tooth_turning_into_a_pin_within_tolerance_is_blocked(monkeypatch, angle, physics,
                                                                blocks):
    """The envelope shortcut must not skip a contact: a part not touching the base at the
    frame's start is checked along its path, and a tooth coming within the tolerance of a
    pin blocks the swing (found by a review: an earlier rule skipped it). That is with the
    pin met as before 2026-11-23 (``coaxial_fit: faces``, ``passing_contact: block``); with
    ``pass`` the tips, which pass the pin 0.07 mm clear, are not stopped by it, nor by
    default (``coaxial_fit: radial``: the tips are no farther than 40 mm from the shaft
    and the pin no nearer than 40.07 mm, so they never meet), and the shortcut must not
    change either."""
    doc = _pin_near_the_teeth(angle, 7e-5)
    doc.setdefault("physics", {}).update(physics)
    session = make_session(doc)
    fast, _ = _run(session)
    monkeypatch.setattr(step_module, "_INSIDE_ENVELOPE", False)
    slow, _ = _run(session)
    assert _values(fast) == _values(slow)
    blocked = [e for r in fast for e in r.events
               if e.kind == "ContactMade" and e.cause == "blocked_by_base"]
    assert bool(blocked) is blocks


@pytest.mark.parametrize("angle", [15, 180])
def test_a_tooth_turning_into_a_pin_in_its_way_is_blocked(monkeypatch, angle):
    """The pin 0.5 mm inside the teeth's tip circle: a tooth moves into it, passing or not,
    and the shortcut finds it too."""
    session = make_session(_pin_near_the_teeth(angle, -5e-4))
    fast, _ = _run(session)
    monkeypatch.setattr(step_module, "_INSIDE_ENVELOPE", False)
    slow, _ = _run(session)
    assert _values(fast) == _values(slow)
    assert [e for r in fast for e in r.events
            if e.kind == "ContactMade" and e.cause == "blocked_by_base"]


@pytest.mark.parametrize("name", ["gear_pendulum", "throw_and_catch", "plane_block_edge"])
def test_the_replay_summary_reports_the_counters(name):
    from vade_replay.replay import replay
    counters = replay(Recording(RECORDINGS / f"{name}.mcap")).counters
    assert set(counters) == {"fcl_distance_queries", "bounding_tests", "witness_tests",
                             "integrator_steps", "closed_form_evals"}
    assert all(isinstance(v, int) and v >= 0 for v in counters.values())
    assert counters["integrator_steps"] + counters["closed_form_evals"] > 0
    json.dumps(counters)


def test_a_state_copied_with_other_parts_works_out_which_are_awake():
    """``dataclasses.replace(state, parts=...)`` keeps the old awake set; the step must not
    trust it for the new parts (a thrown part would be frozen in the air)."""
    from dataclasses import replace

    from conftest import session_doc
    from vade_replay.dynamics import free
    from vade_replay.modes import Mode
    from vade_replay.state import PartState
    from vade_replay.step import initial_state, step

    doc = session_doc(parts=[{"name": "b", "shape": {"type": "box", "size": [.05, .05, .05]},
                              "density": 1000, "pose": {"position": [0, 0, 1.2]}}],
                      right_hand=[{"t": 0, "position": [1, 1, 1.5], "grip": False}],
                      duration_s=0.5)
    session = make_session(doc)
    scene = session.build_scene()
    world = CollisionWorld(scene)
    frames = list(session.tracker_frames())
    state = initial_state(scene, time_ns=frames[0].time_ns)
    assert state.awake_parts() == ()  # the box starts STATIC: nothing looks at it
    body, part = scene.parts[0], state.parts[0]
    flight = free.start(t_ns=frames[0].time_ns, cm=part.pose.apply(body.center_of_mass),
                        velocity=(0.0, 0.0, 1.0), omega_world=(0.0, 0.0, 0.0),
                        world_from_part=part.pose, part_from_principal=body.part_from_principal,
                        principal_moments=body.principal_moments)
    thrown = PartState(part.name, Mode.INSPACE, part.pose, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0),
                       flight)
    state = replace(state, parts=(thrown,))
    for inputs in frames[1:20]:
        state, _ = step(scene, world, state, inputs)
    # 19 frames at 60 Hz up at 1 m/s under a quarter of g: the closed form.
    t = (frames[19].time_ns - frames[0].time_ns) * 1e-9
    assert state.parts[0].pose.position[2] == pytest.approx(1.2 + t - 0.5 * 9.8 * 0.25 * t * t,
                                                            abs=1e-12)


def test_a_shapes_key_keeps_apart_what_json_keeps_apart():
    from vade_replay.scene import _shape_key
    keys = [_shape_key([{"size": v}]) for v in
            (None, float("inf"), float("-inf"), 1, 1.0, 2**70, "1")]
    assert len(set(keys)) == len(keys)
    assert _shape_key([{"b": 1, "a": [0.5]}]) == _shape_key([{"a": [0.5], "b": 1}])


@pytest.mark.parametrize("reuse", [True, False])
def test_the_steppers_kept_lists_give_what_fresh_copies_give(reuse, monkeypatch):
    """``Stepper`` works each frame in two lists kept from the frame before (the parts'
    states and their snapshots), where ``step`` and ``frame_record`` called alone copy the
    last frame's: the same states and records, frame by frame, as values and as objects
    (a resting part's snapshot is the one of the frame before either way)."""
    from vade_replay.replay import Stepper
    from vade_replay.step import frame_record, initial_state, step

    monkeypatch.setattr(step_module, "_REUSE_SNAPSHOTS", reuse)

    for doc in (three_part_session(4.0),  # base in a moving hand, parts onto it and placed
                three_part_session(4.0, static_parts=12, gear=False, box=False)):
        session = make_session(doc)
        scene = session.build_scene()
        stepper = Stepper(scene, CollisionWorld(scene))
        world = CollisionWorld(scene)
        state, previous, last_kept = None, None, None
        modes, shared = set(), 0
        for inputs in session.tracker_frames():
            kept = stepper(inputs)
            if state is None:
                state = initial_state(scene, time_ns=inputs.time_ns)
            state, events = step(scene, world, state, inputs)
            record = frame_record(scene, state, inputs, events,
                                  previous=previous if reuse else None)
            assert _values([kept]) == _values([record]), inputs.frame
            assert stepper.state.parts == state.parts
            if previous is not None:
                same = [a is b for a, b in zip(kept.parts, last_kept.parts)]
                assert same == [a is b for a, b in zip(record.parts, previous[1].parts)]
                shared += sum(same)
            previous, last_kept = (state, record), kept
            modes.update(p.mode for p in record.parts)
        assert {"INHAND", "STATIC"} <= modes and (shared > 0) == reuse


def test_parts_made_alike_share_their_geometry_and_nothing_else():
    """Parts whose documents differ only in placement (name, pose, colour) share one mesh,
    its mass properties and its bounding box, built once; a part of another size or
    density gets its own, the same as it would alone."""
    doc = three_part_session(1.0, static_parts=6, gear=False, box=False)
    doc["parts"][-1]["density"] = 2000               # heavier than its neighbours
    doc["parts"][-2]["shape"]["size"] = [0.02, 0.02, 0.03]  # taller
    scene = make_session(doc).build_scene()
    boxes = [scene.part(f"resting_{i:03d}") for i in range(6)]
    alike, taller, heavier = boxes[:4], boxes[4], boxes[5]
    # (A bounding box is a tuple of floats, rebuilt at each read in the compiled build:
    # equal, not the same object.)
    assert all(b.vertices is alike[0].vertices and b.faces is alike[0].faces
               and (b.bbox_min, b.bbox_max) == (alike[0].bbox_min, alike[0].bbox_max)
               for b in alike)
    assert len({b.initial_pose.position for b in alike}) == 4
    assert taller.vertices is not alike[0].vertices
    assert taller.bbox_max[2] == pytest.approx(0.015, abs=1e-12)
    assert alike[0].bbox_max[2] == pytest.approx(0.01, abs=1e-12)
    assert heavier.vertices is not alike[0].vertices
    # A 2 cm cube: 8 g at 1000 kg/m^3, 16 g at 2000 (closed form, to round-off).
    assert alike[0].mass_kg == pytest.approx(0.008, rel=1e-9)
    assert heavier.mass_kg == pytest.approx(0.016, rel=1e-9)
    alone = make_session({**doc, "parts": [doc["parts"][-1]]}).build_scene().parts[0]
    assert (alone.mass_kg, alone.inertia_cm, alone.bbox_min, alone.reach_from_origin) == \
        (heavier.mass_kg, heavier.inertia_cm, heavier.bbox_min, heavier.reach_from_origin)
