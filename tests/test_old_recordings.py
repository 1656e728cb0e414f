"""A recording made under physics defaults that have changed since: the replay says what
changed and how to replay it as it was made, and those options do replay it bit for bit.

``data/shaft_slide_off_before_analytic4.mcap`` is the golden as it was recorded before the
sliding default became ``analytic4`` with located onsets (commit b037763): a real old file,
made by the code of the commit before it, not one made to look old. With one change to that
code: the principal axes found by ``spatial.symmetric_eigen``, as today's code finds them.
The first file's came from numpy's ``eigh`` (LAPACK), whose kernel OpenBLAS chooses by the
CPU, so it replayed as recorded only where OpenBLAS chose the kernel it was made with
(SkylakeX); re-made so, on 2026-12-02, it replays as recorded under every kernel.
"""

from __future__ import annotations

import json
from pathlib import Path

from conftest import RECORDINGS, run_cli
from mcap_edit import copy_recording
from vade_replay.recording import Recording
from vade_replay.replay import as_made, replay

OLD = Path(__file__).resolve().parent / "data" / "shaft_slide_off_before_analytic4.mcap"


def test_an_old_recording_names_the_changed_defaults_and_replays_with_them():
    summary = replay(Recording(OLD))
    assert not summary.match
    changed = summary.physics_changed
    assert changed["slide_integrator"] == {"recorded": "analytic", "now": "analytic4"}
    # Keys the old file does not have are what came before them.
    assert changed["slide_onset"] == {"recorded": "sub_step", "now": "located"}
    assert changed["slide_off"] == {"recorded": "frame_end", "now": "located"}
    assert changed["final_pose_check"] == {"recorded": "frame_end", "now": "path"}
    assert changed["block_cut"] == {"recorded": "both", "now": "blamed"}
    assert changed["block_event"] == {"recorded": "always", "now": "first"}
    assert changed["flight_grace"] == {"recorded": "whole_base", "now": "touched"}
    assert changed["environment_contact"] == {"recorded": "flying", "now": "every_part"}
    assert changed["coaxial_fit"] == {"recorded": "faces", "now": "radial"}
    assert changed["landing"] == {"recorded": "rests", "now": "constraints"}
    assert changed["contact_sweep"] == {"recorded": "frame_end", "now": "path"}
    assert changed["velocities"] == {"recorded": "relative", "now": "world"}
    assert changed["snap_velocity"] == {"recorded": "zero", "now": "along_constraint"}
    assert changed["release_velocity"] == {"recorded": "window_fit",
                                           "now": "window_fit_corners"}
    assert changed["release_point"] == {"recorded": "cm", "now": "grip"}
    assert changed["release_span_s"] == {"recorded": 0.0, "now": 0.1}
    assert changed["slide_step_s"] == {"recorded": 1 / 180, "now": 1 / 60}
    # Before two hands lifted anything, they lifted what one hand lifts.
    assert changed["two_hand_max_mass_kg"] == {"recorded": 5.0, "now": 15.0}
    assert set(changed) == {"slide_integrator", "slide_onset", "slide_off", "slide_step_s",
                            "final_pose_check", "block_cut", "block_event", "flight_grace",
                            "release_velocity", "coaxial_fit", "landing", "contact_sweep",
                            "velocities", "snap_velocity", "two_hand_max_mass_kg",
                            "release_point", "release_span_s", "environment_contact"}
    # analytic brings its own 1/180 s, so the step need not be set.
    again = replay(Recording(OLD), as_recorded=True)
    assert again.match, again.first_divergence
    assert again.as_recorded == {"block_cut": "both", "block_event": "always",
                                 "coaxial_fit": "faces", "contact_sweep": "frame_end",
                                 "environment_contact": "flying",
                                 "final_pose_check": "frame_end", "flight_grace": "whole_base",
                                 "landing": "rests", "release_point": "cm",
                                 "release_span_s": 0.0, "release_velocity": "window_fit",
                                 "slide_integrator": "analytic", "slide_off": "frame_end",
                                 "slide_onset": "sub_step", "snap_velocity": "zero",
                                 "two_hand_max_mass_kg": 5.0, "velocities": "relative"}
    assert again.physics_changed == {}  # restored, so no longer a changed default


def test_the_cli_says_so_beside_the_divergence(tmp_path):
    result = run_cli("vade-replay", str(OLD))
    assert result.returncode == 1
    lines = result.stdout.splitlines()
    assert lines[0].startswith("DIVERGED: first divergence at frame")
    assert lines[1].startswith("note: this recording was made with other physics defaults")
    assert lines[1].endswith(f"to replay it as it was made: vade-replay {OLD} --as-recorded")
    many = run_cli("vade-replay", str(OLD), str(RECORDINGS / "gear_pendulum.mcap"))
    assert ("(made with other physics defaults: block_cut, block_event, coaxial_fit, "
            "contact_sweep, environment_contact, final_pose_check, flight_grace, landing, "
            "release_point, "
            "release_span_s, release_velocity, "
            "slide_integrator, slide_off, "
            "slide_onset, slide_step_s, snap_velocity, two_hand_max_mass_kg, velocities; "
            f"vade-replay {OLD} --as-recorded replays it with them)") in many.stdout
    # What it says works: the recording reproduces, bit for bit, exit 0.
    as_made = run_cli("vade-replay", str(OLD), "--as-recorded")
    assert as_made.returncode == 0 and as_made.stdout.startswith(
        "as recorded (block_cut='both', block_event='always', coaxial_fit='faces', "
        "contact_sweep='frame_end', environment_contact='flying', "
        "final_pose_check='frame_end', flight_grace='whole_base', landing='rests', "
        "release_point='cm', release_span_s=0.0, release_velocity='window_fit', "
        "slide_integrator='analytic', slide_off='frame_end', slide_onset='sub_step', "
        "snap_velocity='zero', "
        "two_hand_max_mass_kg=5.0, velocities='relative'): match: 241 frames")
    as_json = run_cli("vade-replay", str(OLD), "--json")
    assert json.loads(as_json.stdout)["physics_changed"]["slide_integrator"]["now"] == "analytic4"


def test_recordings_of_this_version_and_what_ifs_report_no_changed_default(tmp_path):
    path = RECORDINGS / "plane_block_wall.mcap"
    physics = Recording(path).metadata["physics"]
    # The sub-steps in effect are recorded, not only the fields (None: "the default").
    assert json.loads(physics["slide_step_s"]) == 1 / 60
    assert json.loads(physics["turn_step_s"]) == 1 / 120
    assert replay(Recording(path)).physics_changed == {}
    what_if = replay(Recording(path), overrides={"physics.friction_dynamic": "0.25",
                                                 "physics.slide_integrator": "analytic"})
    assert not what_if.match and what_if.physics_changed == {}


def test_a_sub_step_changed_alone_is_set_as_its_bound(tmp_path):
    """A recording whose default sub-step differs from today's, its integrator not: the
    options set the step itself."""
    old = tmp_path / "old_step.mcap"

    def older(name: str, values: dict) -> dict:
        if name == "physics":
            values = {**values, "slide_step_s": json.dumps(1 / 240)}
        return values
    copy_recording(RECORDINGS / "plane_block_wall.mcap", old, lambda t, i, d: d,
                   edit_metadata=older)
    changed = replay(Recording(old)).physics_changed
    assert changed == {"slide_step_s": {"recorded": 1 / 240, "now": 1 / 60}}
    session, restored = as_made(Recording(old))
    assert restored == {"slide_max_step_s": 1 / 240}
    assert session.build_scene().physics.slide_step_s == 1 / 240


def test_an_old_recordings_own_sub_steps_are_the_ones_it_ran_with(tmp_path):
    """Without ``*_step_s`` metadata the step in effect was the recording's own bound, else
    the shared one (1/240 s by default before 9e8e766), else the default of the time."""
    def as_old(extra: dict):
        def older(name: str, values: dict) -> dict:
            if name != "physics":
                return values
            values = {k: v for k, v in values.items() if k not in ("slide_step_s",
                                                                     "turn_step_s")}
            return {**values, "slide_integrator": '"analytic"', "slide_onset": '"sub_step"',
                    "slide_off": '"frame_end"', **{k: json.dumps(v) for k, v in extra.items()}}
        path = tmp_path / f"old_{len(list(tmp_path.iterdir()))}.mcap"
        copy_recording(RECORDINGS / "plane_block_wall.mcap", path, lambda t, i, d: d,
                       edit_metadata=older)
        shared_paths.append(path)
        return replay(Recording(path)).physics_changed
    shared_paths: list[Path] = []
    own = as_old({"slide_max_step_s": 0.01})
    assert own["slide_step_s"] == {"recorded": 0.01, "now": 1 / 60}
    shared = as_old({"onbase_max_step_s": 1 / 240})
    assert shared["slide_step_s"]["recorded"] == 1 / 240
    assert shared["turn_step_s"] == {"recorded": 1 / 240, "now": 1 / 120}
    _, restored = as_made(Recording(shared_paths[-1]))
    # The shared bound brings both steps back; nothing more is set.
    assert restored["onbase_max_step_s"] == 1 / 240
    assert "slide_max_step_s" not in restored and "turn_max_step_s" not in restored
    plain = as_old({})
    assert plain["slide_step_s"]["recorded"] == 1 / 180 and "turn_step_s" not in plain


def test_lengths_are_restored_in_metres_whatever_the_sessions_unit(tmp_path):
    """The metadata holds lengths in metres; a session in mm restores them as they were,
    to the bit (an option in the session's units would have gone through 1e-3 and back)."""
    from test_session import _scaled

    from vade_replay import session as session_mod
    from vade_replay.replay import record
    doc = _scaled(json.loads((RECORDINGS / "drop_on_table.json").read_text()), 1000.0)
    doc["units"] = "mm"
    doc["physics"] = {"gravity": [0.0, 0.0, -9800.0]}
    made = tmp_path / "mm.mcap"
    record(session_mod.parse(json.dumps(doc).encode(), {}, source="mm.json"), made)

    def older(name: str, values: dict) -> dict:
        if name == "physics":
            values = {**values, "contact_tolerance": json.dumps(2e-4)}
        return values
    old = tmp_path / "old_mm.mcap"
    copy_recording(made, old, lambda t, i, d: d, edit_metadata=older)
    session, restored = as_made(Recording(old))
    assert restored == {"contact_tolerance": 2e-4}
    assert session.build_scene().physics.contact_tolerance == 2e-4


def test_vade_goldens_check_says_a_default_changed_since_a_golden_was_recorded(tmp_path):
    import shutil
    shutil.copy(RECORDINGS / "shaft_slide_off.json", tmp_path / "shaft_slide_off.json")
    shutil.copy(OLD, tmp_path / "shaft_slide_off.mcap")
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 1
    assert "DIVERGED first divergence at frame" in result.stdout
    assert ("recorded with other physics defaults: block_cut, block_event, coaxial_fit, "
            "contact_sweep, environment_contact, final_pose_check, flight_grace, landing, "
            "release_point, "
            "release_span_s, release_velocity, "
            "slide_integrator, slide_off, "
            "slide_onset, slide_step_s, snap_velocity, two_hand_max_mass_kg, velocities; "
            f"vade-replay {tmp_path / 'shaft_slide_off.mcap'} --as-recorded replays it with "
            "them; if the change is meant, re-record with vade-goldens") in result.stdout
    # With another golden beside it that matches: a count of both at the end.
    shutil.copy(RECORDINGS / "drop_on_table.json", tmp_path / "drop_on_table.json")
    shutil.copy(RECORDINGS / "drop_on_table.mcap", tmp_path / "drop_on_table.mcap")
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 1
    assert result.stdout.splitlines()[-1] == ("2 goldens: 1 match, 1 diverged, 0 stale, 0 "
                                              "could not be replayed")
    # A golden missing: named, the others still checked, and exit 2.
    shutil.copy(RECORDINGS / "tumbling_box.json", tmp_path / "tumbling_box.json")
    result = run_cli("vade-goldens", "--check", "--dir", str(tmp_path))
    assert result.returncode == 2 and "tumbling_box.mcap" in result.stderr
    assert f"(record it with vade-goldens --dir {tmp_path} tumbling_box)" in result.stderr
    assert result.stdout.splitlines()[-1] == ("3 goldens: 1 match, 1 diverged, 0 stale, 1 "
                                              "could not be replayed")



def test_as_recorded_keeps_a_constraints_own_friction_where_set_options_replaced_it(tmp_path):
    """From a developer's trial: a recording made when the default dynamic friction was
    0.25 and sliding ``analytic``, of a block whose constraint sets its own friction. The
    ``--set physics.friction_dynamic=0.25`` that used to be suggested is a what-if of every
    contact: it replaced the constraint's 0.3 and departed. ``--as-recorded`` restores the
    recorded values as defaults, so the constraint's own friction stands: a match, exit 0;
    the same with the default restored where it is used, and a diverging replay still
    exits 1."""
    from vade_replay import session as session_mod
    from vade_replay.replay import record
    doc = json.loads((RECORDINGS / "plane_block_wall.json").read_text())
    doc["physics"] = {"friction_dynamic": 0.25, "slide_integrator": "analytic"}
    made = tmp_path / "made.mcap"
    record(session_mod.parse(json.dumps(doc).encode(), {}, source="made.json"), made)
    del doc["physics"]  # the session left them to the defaults of the time
    old = tmp_path / "old.mcap"
    copy_recording(made, old, lambda t, i, d: d, edit_attachment=lambda name, data: json.dumps(
        doc).encode() if name == "session.json" else data)
    plain = replay(Recording(old))
    assert not plain.match and set(plain.physics_changed) == {
        "friction_dynamic", "slide_integrator", "slide_step_s"}
    suggested_before = replay(Recording(old), overrides={
        "physics.friction_dynamic": "0.25", "physics.slide_integrator": "analytic"})
    assert not suggested_before.match
    restored = replay(Recording(old), as_recorded=True)
    assert restored.match and restored.physics_changed == {}
    assert restored.as_recorded == {"friction_dynamic": 0.25, "slide_integrator": "analytic"}
    result = run_cli("vade-replay", str(old), "--as-recorded", "--json")
    assert result.returncode == 0 and json.loads(result.stdout)["match"] is True
    # A what-if on the physics it was made with: the recorded scheme stays, the changed
    # friction departs, and nothing else is named as a changed default.
    what_if = replay(Recording(old), as_recorded=True,
                     overrides={"parts.block.constraints.bottom_on_top.friction.dynamic": "0.1"})
    assert not what_if.match and what_if.physics_changed == {}
    assert what_if.as_recorded == {"friction_dynamic": 0.25, "slide_integrator": "analytic"}
    same = replay(Recording(old), as_recorded=True,
                  overrides={"physics.grab_radius": "0.05"})  # the default: no change
    assert same.match and same.physics_changed == {}
    # As recorded and still different (the recorded frames edited): exit 1, as any replay.
    edited = tmp_path / "edited.mcap"
    from mcap_edit import nudge_pose
    nudge_pose(old, edited, frame=170, axis=0, delta=1e-3)
    assert run_cli("vade-replay", str(edited), "--as-recorded").returncode == 1


def _made_with(tmp_path: Path, physics: dict, left: dict, name: str) -> Path:
    """plane_block_wall recorded with ``physics``, its session then rewritten to say only
    ``left``: as if the rest had been the defaults of the time it was made."""
    from vade_replay import session as session_mod
    from vade_replay.replay import record
    doc = json.loads((RECORDINGS / "plane_block_wall.json").read_text())
    doc["physics"] = physics
    made = tmp_path / f"{name}_made.mcap"
    record(session_mod.parse(json.dumps(doc).encode(), {}, source="made.json"), made)
    doc["physics"] = left
    old = tmp_path / f"{name}.mcap"
    copy_recording(made, old, lambda t, i, d: d, edit_attachment=lambda n, data: json.dumps(
        doc).encode() if n == "session.json" else data)
    return old


def test_as_recorded_restores_the_paper_models_schemes_and_sub_steps_and_changes_no_file(
        tmp_path):
    """From a review: under ``model: paper`` the recorded scheme must win over the paper's
    own default (it was applied after it and had no effect); a sub-step restored through
    its bound is no changed default in the summary; the Recording passed in is not changed
    (a later plain replay of it is plain); --rerun reviews the run as recorded."""
    old = _made_with(tmp_path, {"model": "paper", "slide_integrator": "analytic4"},
                     {"model": "paper"}, "paper")
    recording = Recording(old)
    assert not replay(recording).match
    restored = replay(recording, as_recorded=True)
    assert restored.match, restored.first_divergence
    assert restored.as_recorded["slide_integrator"] == "analytic4"
    assert restored.physics_changed == {}
    again = replay(recording)  # the same object, replayed plainly again
    assert not again.match and again.as_recorded is None
    step = _made_with(tmp_path, {"slide_max_step_s": 0.004}, {}, "step")
    summary = replay(Recording(step), as_recorded=True)
    assert summary.match and summary.as_recorded == {"slide_max_step_s": 0.004}
    assert summary.physics_changed == {}
    review = run_cli("vade-replay", str(old), "--as-recorded", "--rerun",
                     str(tmp_path / "review.rrd"))
    assert review.returncode == 0 and review.stdout.startswith("as recorded (")


def test_as_recorded_says_when_a_recording_holds_no_physics_to_restore(tmp_path):
    bare = tmp_path / "bare.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", bare, lambda t, i, d: d,
                   edit_metadata=lambda name, values: {} if name == "physics" else values)
    result = run_cli("vade-replay", str(bare), "--as-recorded")
    assert result.returncode == 0 and result.stdout.startswith("match")
    assert "--as-recorded: the recording holds no physics metadata" in result.stderr
    assert "what-if" not in result.stderr
