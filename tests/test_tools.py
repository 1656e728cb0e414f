"""Tools (ONTOOL): a part too heavy for a hand is lifted by a tool, a tracked device of its
own, follows it rigidly, and is let go as a hand lets go (here: detached in free space, it
falls to the table along the closed-form parabola)."""

from __future__ import annotations

import json
import math

import pytest

from conftest import (G_FREE, RECORDINGS, assert_falls_from_rest, make_session, run_cli,
                      run_records, session_doc)
from vade_replay.errors import SessionError

CRATE = {"name": "crate", "shape": {"type": "box", "size": [0.2, 0.2, 0.2]}, "density": 2000,
         "pose": {"position": [0.0, 0.0, 0.84]}}  # 16 kg, on the table (top at 0.74)
HOOK_UP_Z = 1.35


def _hook(release_t=1.2):
    """Down to the crate's top, attach, lift it 0.4 m, hold still, let go at release_t."""
    return [{"t": 0.0, "position": [0.0, 0.0, 0.95], "grip": False},
            {"t": 0.2, "grip": True},
            {"t": 0.8, "position": [0.0, 0.0, HOOK_UP_Z]},
            {"t": release_t, "grip": False},
            {"t": 1.8, "position": [0.3, 0.0, HOOK_UP_Z]}]


def _doc(*, parts=(CRATE,), right_hand=None, hook=None, max_mass_kg=30.0, duration_s=2.0):
    doc = session_doc(parts=list(parts), duration_s=duration_s,
                      right_hand=right_hand or [{"t": 0.0, "position": [0.5, 0.3, 1.0],
                                                 "grip": False}],
                      tools=[{"name": "hook", "max_mass_kg": max_mass_kg}])
    doc["tracker"]["devices"]["hook"] = hook or _hook()
    return doc


def _transitions(records):
    return [(r.frame, e.from_mode, e.to_mode, e.cause) for r in records for e in r.events
            if e.kind == "ModeChanged"]


def test_a_tool_lifts_a_part_too_heavy_for_a_hand_and_carries_it_rigidly():
    hand = [{"t": 0.0, "position": [0.05, 0.05, 0.95], "grip": False},
            {"t": 0.1, "grip": True}, {"t": 0.15, "grip": False},
            {"t": 0.3, "position": [0.5, 0.3, 1.0]}]
    records = run_records(_doc(right_hand=hand))
    refused = [e for r in records for e in r.events if e.kind == "GrabRefused"]
    assert [(e.part, e.cause, e.hand) for e in refused] == [
        ("crate", "too_heavy_for_two_hands", "right_hand")]  # 16 kg: more than two hands lift
    grabbed = [(r.frame, e.cause, e.hand) for r in records for e in r.events
               if e.kind == "PartGrabbed"]
    assert grabbed == [(12, "attached_to_tool", "hook")]  # the grip closes at t = 0.2 s
    on_tool = [r for r in records if r.parts[0].mode == "ONTOOL"]
    assert len(on_tool) == 60  # t = 0.2 s up to the release at 1.2 s
    for r in on_tool:
        # Rigidly under the hook: the offset it was attached at (0.11 m below), exactly.
        hook = r.inputs.device("hook").position
        assert r.parts[0].position == pytest.approx((hook[0], hook[1], hook[2] - 0.11),
                                                     abs=1e-12)
        assert r.parts[0].rotation_xyzw == (0.0, 0.0, 0.0, 1.0)


def test_a_part_detached_in_space_falls_along_the_parabola_to_the_table():
    records = run_records(_doc())
    transitions = _transitions(records)
    assert [t[1:] for t in transitions] == [
        ("STATIC", "ONTOOL", "attached_to_tool"),
        ("ONTOOL", "INSPACE", "detached_from_tool"),
        ("INSPACE", "STATIC", "hit_environment")]
    released = [e for r in records for e in r.events if e.kind == "PartReleased"]
    assert [(e.cause, e.hand) for e in released] == [("detached_from_tool", "hook")]
    # Still for 0.4 s before it let go: it leaves at rest (the release-velocity fit of a
    # still device), and falls z(t) = z0 - g t^2 / 2 from 0.4 m above its resting height.
    assert max(abs(v) for v in released[0].linear_velocity) < 1e-12
    t0_ns = transitions[1][0] * 10**9 // 60
    z0 = HOOK_UP_Z - 0.11
    assert_falls_from_rest(records, transitions[1][0], z0)
    # It stops on the table (top at 0.74: the crate's centre at 0.84) in the frame the
    # parabola reaches it.
    landed_ns = transitions[2][0] * 10**9 // 60
    t_fall = math.sqrt(2 * (z0 - 0.84) / G_FREE)
    assert 0.0 <= landed_ns * 1e-9 - (t0_ns * 1e-9 + t_fall) < 1.0 / 60.0
    assert records[-1].parts[0].position[2] == pytest.approx(0.84, abs=2e-4)


def test_a_tool_refuses_a_part_heavier_than_it_lifts():
    records = run_records(_doc(max_mass_kg=10.0))
    refused = [(e.part, e.cause, e.hand) for r in records for e in r.events
               if e.kind == "GrabRefused"]
    assert refused == [("crate", "too_heavy_for_tool", "hook")]
    assert not _transitions(records)
    assert records[-1].parts[0].position == (0.0, 0.0, 0.84)


def test_a_hand_hands_a_part_over_to_a_tool_and_cannot_take_it_back():
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
           "density": 2700, "pose": {"position": [0.0, 0.0, 0.78]}}  # 0.35 kg
    hand = [{"t": 0.0, "position": [0.0, 0.0, 0.79], "grip": False},
            {"t": 0.1, "grip": True},
            {"t": 0.5, "position": [0.0, 0.0, 1.0]},
            {"t": 0.8, "grip": False},  # the tool has it by now: nothing to let go
            {"t": 0.9, "position": [0.0, 0.0, 1.1]},
            {"t": 1.0, "grip": True}]   # on the part on the tool (inside its box): refused
    hook = [{"t": 0.0, "position": [0.3, 0.0, 1.2], "grip": False},
            {"t": 0.5, "position": [0.0, 0.0, 1.05]},
            {"t": 0.6, "grip": True},
            {"t": 1.2, "position": [0.0, 0.0, 1.25]}]
    records = run_records(_doc(parts=[peg], right_hand=hand, hook=hook, duration_s=1.5))
    assert [t[1:] for t in _transitions(records)] == [
        ("STATIC", "INHAND", "grabbed"), ("INHAND", "ONTOOL", "attached_to_tool")]
    assert not [e for r in records for e in r.events if e.kind == "PartReleased"]
    refused = [(r.frame, e.part, e.cause, e.hand) for r in records for e in r.events
               if e.kind == "GrabRefused"]
    assert refused == [(60, "peg", "held_by_tool", "right_hand")]
    at = records[60]
    hand = at.inputs.device("right_hand").position
    assert abs(at.parts[0].position[2] - hand[2]) < 0.04  # the hand is at the peg
    last = records[-1]
    assert last.parts[0].mode == "ONTOOL"
    assert last.parts[0].position[2] == pytest.approx(1.25 - (1.05 - 1.0) - 0.01, abs=1e-9)


@pytest.mark.parametrize("tool", ["atool", "ztool"])  # named before and after right_hand
def test_a_tool_and_a_hand_closing_on_a_part_in_one_frame_give_it_to_the_tool(tool):
    """Within a frame the tools act before the hands, whatever they are called."""
    peg = {"name": "peg", "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
           "density": 2700, "pose": {"position": [0.0, 0.0, 0.78]}}
    hand = [{"t": 0.0, "position": [0.0, 0.01, 0.8], "grip": False}, {"t": 0.2, "grip": True}]
    hook = [{"t": 0.0, "position": [0.0, -0.01, 0.8], "grip": False}, {"t": 0.2, "grip": True}]
    doc = _doc(parts=[peg], right_hand=hand, hook=hook, duration_s=0.5)
    doc["tools"][0]["name"] = tool
    doc["tracker"]["devices"][tool] = doc["tracker"]["devices"].pop("hook")
    records = run_records(doc)
    assert [t[1:] for t in _transitions(records)] == [("STATIC", "ONTOOL", "attached_to_tool")]
    events = [(e.kind, e.cause, e.hand) for r in records for e in r.events
              if e.kind in ("PartGrabbed", "GrabRefused")]
    assert events == [("PartGrabbed", "attached_to_tool", tool),
                      ("GrabRefused", "held_by_tool", "right_hand")]


def test_the_hoist_golden_places_a_heavy_ring_with_a_tool():
    from vade_replay.recording import Recording
    from vade_replay.replay import recorded_records
    records = list(recorded_records(Recording(RECORDINGS / "hoist_placed.mcap")))
    assert [t[1:] for t in _transitions(records)] == [
        ("STATIC", "ONTOOL", "attached_to_tool"),
        ("ONTOOL", "ONBASESLIDE", "released_on_constraint"),
        ("ONBASESLIDE", "PLACED", "reached_final_pose")]
    refused = [(e.cause, e.hand) for r in records for e in r.events if e.kind == "GrabRefused"]
    assert refused == [("too_heavy_for_two_hands", "right_hand")]  # 20 kg


def test_a_device_that_is_neither_a_hand_nor_a_tool_is_named():
    doc = _doc()
    doc["tracker"]["devices"]["crane"] = doc["tracker"]["devices"].pop("hook")
    with pytest.raises(SessionError) as info:
        list(make_session(doc).tracker_frames())
    assert info.value.field == "tracker.devices.crane" and "tools" in str(info.value)


@pytest.mark.parametrize("name", ["right_hand", "head", "crate", "table", "hook"])
def test_a_tool_cannot_take_a_name_in_use(tmp_path, name):
    doc = _doc()
    doc["tools"] = [{"name": "hook", "max_mass_kg": 30.0}, {"name": name, "max_mass_kg": 5.0}]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    result = run_cli("vade-record", str(path), "-o", str(tmp_path / "bad.mcap"))
    assert result.returncode == 2
    assert "tools[1].name" in result.stderr and "taken" in result.stderr


def test_a_tool_in_a_csv_tracker_log():
    rows = ["time,device,x,y,z,q0,q1,q2,q3,grip"]
    for n in range(121):
        t = n / 60
        z = 0.95 if t < 0.5 else 0.95 + (t - 0.5)
        rows.append(f"{t:.6f},hook,0,0,{z:.6f},1,0,0,0,{1 if t >= 0.2 else 0}")
    doc = _doc()
    doc["tracker"] = {"csv": "log.csv", "csv_quaternion_order": "wxyz"}
    records = run_records(doc, {"log.csv": "\n".join(rows).encode()})
    assert [t[1:] for t in _transitions(records)] == [("STATIC", "ONTOOL", "attached_to_tool")]
    # Attached 0.11 m under the hook, which rose from 0.95 m at 1 m/s after t = 0.5 s.
    assert records[-1].parts[0].position[2] == pytest.approx(0.95 + 1.5 - 0.11, abs=1e-12)
    rows.append("2.1,crane,0,0,1,1,0,0,0,0")
    with pytest.raises(SessionError, match="crane"):
        run_records(doc, {"log.csv": "\n".join(rows).encode()})


def test_a_what_if_with_a_weaker_tool_names_where_the_lift_fails(tmp_path):
    """``--set tools.hoist.max_mass_kg=10``: the recorded inputs replayed with a 10 kg hoist
    cannot lift the 20 kg ring; the report names the frame where it would have attached it,
    and the analysis counts the refusal. Exit 0: a what-if's difference is its answer."""
    result = run_cli("vade-replay", str(RECORDINGS / "hoist_placed.mcap"), "--json",
                     "--set", "tools.hoist.max_mass_kg=10")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["overrides"] == {"tools.hoist.max_mass_kg": 10}
    assert summary["first_divergence"]["frame"] == 48
    assert summary["analysis"]["refused_grabs"] == {"too_heavy_for_two_hands": 1,
                                                    "too_heavy_for_tool": 1}
    assert summary["analysis"]["parts"]["ring"]["time_in_state_s"] == {"STATIC": 4.0}
    assert summary["analysis"]["parts"]["ring"]["tool_grabs"] == 0
    # And one that changes nothing the session does: the same run, to the bit.
    same = run_cli("vade-replay", str(RECORDINGS / "hoist_placed.mcap"), "--json",
                   "--set", "tools.hoist.max_mass_kg=25")
    assert json.loads(same.stdout)["first_divergence"] is None
    ring = json.loads(same.stdout)["analysis"]["parts"]["ring"]
    assert (ring["grabs"], ring["tool_grabs"], ring["two_hand_grabs"]) == (1, 1, 0)


def test_a_what_ifs_table_rows_name_its_changes(tmp_path):
    """In ``--csv``, a what-if's rows carry its changes (a plain replay's are empty)."""
    import csv
    table = tmp_path / "t.csv"
    golden = str(RECORDINGS / "hoist_placed.mcap")
    result = run_cli("vade-replay", golden, "--csv", str(table), "--set",
                     "tools.hoist.max_mass_kg=10", "--set", "physics.gravity_scale_free=0.3")
    assert result.returncode == 0, result.stderr
    (row,) = list(csv.DictReader(table.open(newline="")))
    assert row["overrides"] == "physics.gravity_scale_free=0.3; tools.hoist.max_mass_kg=10"
    assert row["match"] == "False"
    assert run_cli("vade-replay", golden, "--csv", str(table)).returncode == 0
    (row,) = list(csv.DictReader(table.open(newline="")))
    assert row["overrides"] == "" and row["match"] == "True"


@pytest.mark.parametrize("key, value, field", [
    ("tools.crane.max_mass_kg", "10", "tools.crane.max_mass_kg"),  # no such tool
    ("tools.hoist.colour", "10", "tools[0].colour"),               # no such field
    ("tools.hoist.name", "crane", "tools.hoist.name"),             # the device's name
    ("tools.hoist.grab_radius", "-1", "tools[0].grab_radius"),     # not a positive number
    ("tools.hoist.max_mass_kg", "1e400", "tools.hoist.max_mass_kg"),  # not finite
    ("tools.hoist.", "1", "tools.hoist."),                         # no field
    ("tools..max_mass_kg", "1", "tools..max_mass_kg"),             # no tool
    ("tools.hoist.a.b", "1", "tools.hoist.a.b"),                   # a field of a field
])
def test_a_what_if_of_a_tool_that_names_nothing_is_refused(key, value, field):
    result = run_cli("vade-replay", str(RECORDINGS / "hoist_placed.mcap"), "--set",
                     f"{key}={value}")
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and field in result.stderr
    assert result.stderr.count("\n") == 1
