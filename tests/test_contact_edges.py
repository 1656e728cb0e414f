"""Contact at the edges of the method: skimming a surface, landing on the base part."""

from __future__ import annotations

import json

from conftest import RECORDINGS, run_records, session_doc, table


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


def test_a_part_dropped_onto_the_base_stops_on_it_not_through_it():
    # The block is let go 5 cm above the plate, too far to snap onto its plane constraint.
    doc = _plane_block_wall(**{"tracker/devices/right_hand/2/position/2": 1.032})
    records = run_records(doc)
    assert ("INHAND", "INSPACE", "released") in _transitions(records)
    assert ("INSPACE", "STATIC", "hit_base_part") in _transitions(records)
    contact = [e for r in records for e in r.events if e.kind == "ContactMade"]
    assert contact[0].other == "plate_with_wall"
    # Resting on the plate top (z 0.96) with its bottom face, within the tolerance.
    bottom = records[-1].parts[0].position[2] - 0.02
    assert 0.96 <= bottom <= 0.96 + 1e-4


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
