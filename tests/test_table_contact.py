"""Parts stop at the table: at contact, never through it, however thin or fast."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import make_session, run_records, session_doc, table
from vade_replay.collision import CollisionWorld


def _dropped(*, thickness: float, rate_hz: int, release_speed: float):
    """A peg thrown straight down at the table: released 0.42 m above it at ``release_speed``."""
    part = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
            "density": 2700, "pose": {"position": [0.0, 0.0, 2.0]}}
    top = 0.74
    z_release = 1.2
    doc = session_doc(
        parts=[part], environment=[table(size=(1.2, 0.8, thickness), z=top - thickness / 2)],
        rate_hz=rate_hz, duration_s=2.0,
        right_hand=[{"t": 0.0, "position": [0.0, 0.0, 2.0], "grip": False},
                    {"t": 0.1, "grip": True},
                    {"t": 0.6 - 0.8 / release_speed, "position": [0.0, 0.0, 2.0]},
                    {"t": 0.6, "position": [0.0, 0.0, z_release], "grip": False}])
    return doc, top


@pytest.mark.parametrize("thickness, rate_hz, speed", [
    (0.04, 60, 2.0),
    (0.001, 60, 8.0),    # a 1 mm table, 8 m/s: 13 cm a frame
    (0.001, 10, 8.0),    # and 10 Hz: 80 cm a frame
])
def test_part_stops_on_top_of_the_table(thickness, rate_hz, speed):
    doc, top = _dropped(thickness=thickness, rate_hz=rate_hz, release_speed=speed)
    records = run_records(doc)
    modes = [r.parts[0].mode for r in records]
    assert "INSPACE" in modes and modes[-1] == "STATIC"
    final = records[-1].parts[0]
    # Bottom face of the peg (half height 0.04) rests on the top, within the tolerance.
    gap = final.position[2] - 0.04 - top
    assert 0.0 <= gap <= 1e-4
    session = make_session(doc)
    scene = session.build_scene()
    world = CollisionWorld(scene)
    from vade_replay import spatial as sp
    d, _ = world.distance_to_environment("peg", sp.Pose(final.position, final.rotation_xyzw),
                                         (0,))
    assert 0.0 <= d <= 1e-4
    contact = [e for r in records for e in r.events if e.kind == "ContactMade"]
    assert len(contact) == 1 and contact[0].other == "table"


def test_no_queries_for_a_part_far_from_everything():
    part = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
            "density": 2700, "pose": {"position": [0.0, 0.0, 3.0]}}
    doc = session_doc(parts=[part], duration_s=1.0, physics={"gravity_scale_free": 0.0},
                      right_hand=[{"t": 0.0, "position": [0.0, 0.0, 3.0], "grip": False},
                                  {"t": 0.1, "grip": True}, {"t": 0.2, "grip": False}])
    s = make_session(doc)
    scene = s.build_scene()
    world = CollisionWorld(scene)
    from vade_replay.replay import simulate
    records = list(simulate(scene, s.tracker_frames(), collision=world))
    assert records[-1].parts[0].mode == "INSPACE"
    assert world.stats["fcl_distance_queries"] == 0
    assert world.stats["bounding_tests"] > 0
    # No gravity, let go at rest: it stays where it was, to the release fit's round-off
    # (a test audit: np.allclose's default let it drift 3e-5 m).
    assert np.allclose(records[-1].parts[0].position, (0.0, 0.0, 3.0), rtol=0.0, atol=1e-12)
    assert all(max(map(abs, r.parts[0].linear_velocity)) < 1e-12 for r in records
               if r.parts[0].mode == "INSPACE")
