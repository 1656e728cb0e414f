"""The session analysis: time per state, grabs, drops, placement, from the events."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import RECORDINGS, run_cli
from vade_replay.recording import Recording
from vade_replay.replay import replay


def _t(frame: int) -> float:
    return (frame * 10**9 // 60) * 1e-9


def test_drop_on_table_in_numbers():
    analysis = replay(Recording(RECORDINGS / "drop_on_table.mcap")).to_dict()["analysis"]
    peg = analysis["parts"]["peg"]
    # Grabbed at frame 42, released at 84, on the table at 115, session ends at frame 150.
    assert peg["grabs"] == 1 and peg["releases"] == 1 and peg["drops"] == 1
    assert peg["catches"] == 0 and peg["placed_at_s"] is None
    times = peg["time_in_state_s"]
    assert times["INHAND"] == pytest.approx(_t(84) - _t(42), abs=1e-9)
    assert times["INSPACE"] == pytest.approx(_t(115) - _t(84), abs=1e-9)
    assert times["STATIC"] == pytest.approx(_t(42) + _t(150) - _t(115), abs=1e-9)
    assert sum(times.values()) == pytest.approx(2.5, abs=1e-9)


@pytest.mark.parametrize("golden", sorted(RECORDINGS.glob("*.mcap")), ids=lambda p: p.stem)
def test_counts_match_the_recorded_events(golden):
    recording = Recording(golden)
    summary = replay(recording).to_dict()
    from vade_replay.replay import recorded_records

    events = [e for f in recorded_records(recording) for e in f.events]
    # Every part of the session is analysed (a test audit: an empty analysis passed).
    assert set(summary["analysis"]["parts"]) == {p["name"] for p in
                                                 recording.session.doc["parts"]}
    for name, stats in summary["analysis"]["parts"].items():
        mine = [e for e in events if e.part == name]
        assert stats["grabs"] == sum(e.kind == "PartGrabbed" for e in mine)
        assert stats["releases"] == sum(e.kind == "PartReleased" for e in mine)
        assert stats["refused_grabs"] == sum(e.kind == "GrabRefused" for e in mine)
        placed = [e for e in mine if e.kind == "ModeChanged" and e.to_mode == "PLACED"]
        assert (stats["placed_at_s"] is None) == (not placed)
        assert sum(stats["time_in_state_s"].values()) == pytest.approx(summary["duration_s"],
                                                                     abs=1e-9)


def test_placement_time_and_refusals_reach_the_json():
    result = run_cli("vade-replay", str(RECORDINGS / "shaft_placed.mcap"), "--json")
    import json

    analysis = json.loads(result.stdout)["analysis"]
    (stats,) = analysis["parts"].values()
    assert stats["placed_at_s"] is not None and stats["placed_at_s"] > 0
    assert "PLACED" in stats["time_in_state_s"]


def test_every_statistic_of_a_part_is_reported():
    # ``as_dict`` lists the fields by hand (the compiled class has no ``__dict__``): a field
    # added to PartStats and not to it would silently drop out of every summary.
    from dataclasses import fields

    from vade_replay.analysis import PartStats
    stats = PartStats(grabs=2, placed_at_s=1.5, time_in_state_ns={"STATIC": 3_883_333_334})
    # Times are kept in whole nanoseconds and reported in seconds.
    assert list(stats.as_dict()) == [f.name.replace("_ns", "_s") for f in fields(PartStats)]
    assert stats.as_dict()["grabs"] == 2 and stats.as_dict()["placed_at_s"] == 1.5
    assert stats.as_dict()["time_in_state_s"] == {"STATIC": 3.883333334}


def test_a_studys_recordings_as_one_table(tmp_path):
    """``--csv``: a row per recording and part, the same numbers as ``--json``; a part's
    seconds in the seven states add up to the session's duration."""
    import csv
    import json

    from vade_replay.modes import Mode
    from vade_replay.replay import ANALYSIS_COLUMNS
    goldens = [str(RECORDINGS / f"{name}.mcap") for name in
               ("hoist_placed", "shaft_placed", "throw_and_catch")]
    table = tmp_path / "study" / "analysis.csv"
    result = run_cli("vade-replay", *goldens, "--json", "--csv", str(table))
    assert result.returncode == 0, result.stderr
    summaries = {s["recording"]: s for s in json.loads(result.stdout)}
    with open(table, newline="") as stream:
        reader = csv.DictReader(stream)
        assert tuple(reader.fieldnames) == ANALYSIS_COLUMNS
        rows = list(reader)
    assert [row["recording"] for row in rows] == goldens
    for row in rows:
        summary = summaries[row["recording"]]
        stats = summary["analysis"]["parts"][row["part"]]
        assert row["match"] == "True" and row["first_divergence_frame"] == ""
        assert int(row["frames"]) == summary["frames"]
        for key in ("grabs", "catches", "releases", "drops", "slid_off", "blocked",
                    "refused_grabs"):
            assert int(row[key]) == stats[key], key
        times = [float(row[f"s_{mode.value}"]) for mode in Mode]
        assert sum(times) == pytest.approx(summary["duration_s"], abs=1e-9)
        for mode in Mode:
            assert float(row[f"s_{mode.value}"]) == stats["time_in_state_s"].get(mode.value, 0.0)
            # Whole nanoseconds in seconds: no round-off of a sum of frames (3.88333333399).
            assert len(row[f"s_{mode.value}"].split(".")[-1]) <= 9
        # The run's mass of the part: its mesh's volume times its density, as the scene has it.
        golden = Recording(row["recording"])
        body = next(b for b in golden.session.build_scene().parts if b.name == row["part"])
        assert float(row["mass_kg"]) == pytest.approx(body.mass_kg, rel=1e-11)
        assert body.mass_kg > 0
        assert body.mass_kg == summary["masses_kg"][row["part"]]
    hoist = next(row for row in rows if row["session"] == "hoist_placed")
    assert (hoist["placed_at_s"], hoist["s_ONTOOL"], hoist["refused_grabs"],
            hoist["session_refused_grabs"], hoist["error"]) == ("3.4", "2.4", "1", "1", "")


def test_the_table_has_a_row_per_part_and_one_per_recording_that_failed(tmp_path):
    """Two parts: a row each, by name, both with the session's numbers. A file that is not a
    recording among the replayed ones is a row naming its error (exit 2)."""
    import csv

    from conftest import session_doc
    parts = [{"name": name, "shape": {"type": "box", "size": [0.04, 0.04, 0.08]},
              "density": 2700, "pose": {"position": [x, 0.0, 0.78]}}
             for name, x in (("zeta", 0.3), ("alpha", 0.0))]
    hand = [{"t": 0.0, "position": [0.0, 0.0, 0.79], "grip": False}, {"t": 0.2, "grip": True},
            {"t": 0.6, "position": [0.0, 0.0, 1.0]}, {"t": 0.8, "grip": False}]
    session = tmp_path / "two.json"
    session.write_text(__import__("json").dumps(
        session_doc(parts=parts, right_hand=hand, duration_s=1.5)))
    assert run_cli("vade-record", str(session), "-o", str(tmp_path / "two.mcap")).returncode == 0
    (tmp_path / "broken.mcap").write_bytes(b"not a recording")
    table = tmp_path / "t.csv"
    result = run_cli("vade-replay", str(tmp_path / "two.mcap"), str(tmp_path / "broken.mcap"),
                     "--csv", str(table))
    assert result.returncode == 2
    with open(table, newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert [(r["part"], r["error"] != "") for r in rows] == [
        ("alpha", False), ("zeta", False), ("", True)]
    alpha, zeta, broken = rows
    assert (alpha["grabs"], alpha["drops"], zeta["grabs"]) == ("1", "1", "0")
    assert float(zeta["s_STATIC"]) == float(zeta["duration_s"]) == 1.5
    assert broken["recording"].endswith("broken.mcap") and "MCAP" in broken["error"]


@pytest.mark.parametrize("clash", ["input", "-o", "--rerun"])
def test_the_table_never_overwrites_a_recording_or_another_output(tmp_path, clash):
    import shutil
    recording = tmp_path / "r.mcap"
    shutil.copy(RECORDINGS / "drop_on_table.mcap", recording)
    before = recording.read_bytes()
    other = tmp_path / "other"
    args = {"input": [], "-o": ["-o", str(other)], "--rerun": ["--rerun", str(other)]}[clash]
    table = recording if clash == "input" else other
    result = run_cli("vade-replay", str(recording), *args, "--csv", str(table))
    assert result.returncode == 2 and "--csv" in result.stderr
    assert recording.read_bytes() == before and not other.exists()


def test_a_table_that_cannot_be_written_is_named(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"),
                     "--csv", str(blocker / "analysis.csv"))
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and "analysis.csv" in result.stderr
    assert "Traceback" not in result.stderr


def _read_csv(path):
    import csv
    with open(path, newline="") as stream:
        reader = csv.DictReader(stream)
        return tuple(reader.fieldnames), list(reader)


def test_the_events_and_poses_of_a_run_as_tables(tmp_path):
    """``--events`` and ``--poses``: every event of the run, in order, with its frame's time;
    every frame's base and parts, whose numbers read back to the replayed floats bit for bit
    (here the recording's, since the replay matches)."""
    from vade_replay.recording import Recording
    from vade_replay.replay import EVENT_COLUMNS, POSE_COLUMNS, recorded_records
    golden = str(RECORDINGS / "hoist_placed.mcap")
    events, poses = tmp_path / "events.csv", tmp_path / "poses.csv"
    result = run_cli("vade-replay", golden, "--events", str(events), "--poses", str(poses))
    assert result.returncode == 0, result.stderr
    records = list(recorded_records(Recording(golden)))
    columns, rows = _read_csv(events)
    assert columns == EVENT_COLUMNS
    expected = [(r.frame, e) for r in records for e in r.events]
    assert [(int(row["frame"]), row["kind"], row["part"], row["cause"]) for row in rows] == [
        (frame, e.kind, e.part, e.cause) for frame, e in expected]
    for row, (frame, event) in zip(rows, expected):
        assert float(row["time_s"]) == (records[frame].time_ns - records[0].time_ns) / 1e9
        assert row["hand"] == getattr(event, "hand", "")
        if event.kind == "PartReleased":
            assert tuple(float(row[k]) for k in ("vx", "vy", "vz")) == event.linear_velocity
    assert [row["kind"] for row in rows].count("GrabRefused") == 1
    columns, rows = _read_csv(poses)
    assert columns == POSE_COLUMNS
    assert len(rows) == len(records) * 2  # the base and the ring, every frame
    for row in rows[::37]:
        record = records[int(row["frame"])]
        snap = record.base if row["part"] == record.base.name else record.parts[0]
        assert row["mode"] == snap.mode
        assert tuple(float(row[k]) for k in ("x", "y", "z")) == snap.position
        assert tuple(float(row[k]) for k in ("qx", "qy", "qz", "qw")) == snap.rotation_xyzw
        assert tuple(float(row[k]) for k in ("wx", "wy", "wz")) == snap.angular_velocity


def _damaged(tmp_path):
    """shaft_slide_off with bytes flipped half way: it fails after 120 frames."""
    data = bytearray((RECORDINGS / "shaft_slide_off.mcap").read_bytes())
    middle = len(data) // 2
    data[middle:middle + 40] = bytes(b ^ 0xFF for b in data[middle:middle + 40])
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    return damaged


def test_frame_tables_of_several_recordings_in_order_and_in_workers(tmp_path):
    """Several recordings: one header, each recording's rows in the order given, none for a
    file that could not be replayed (exit 2), also one that failed part-way through its
    rows; the same with ``--jobs 2``."""
    goldens = [str(RECORDINGS / f"{name}.mcap") for name in ("two_hand_placed", "drop_on_table")]
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not a recording")
    files = [goldens[0], str(bad), str(_damaged(tmp_path)), goldens[1]]
    out = {}
    for jobs in ("1", "2"):
        events, poses = tmp_path / f"e{jobs}.csv", tmp_path / f"p{jobs}.csv"
        result = run_cli("vade-replay", *files, "--jobs", jobs, "--events", str(events),
                         "--poses", str(poses), process=jobs == "2")
        assert result.returncode == 2 and "bad.mcap" in result.stderr
        out[jobs] = (events.read_text(), poses.read_text())
    assert out["1"] == out["2"]
    _, rows = _read_csv(tmp_path / "e1.csv")
    recordings = [row["recording"] for row in rows]
    assert recordings == sorted(recordings, key=goldens.index) and set(recordings) == set(goldens)
    _, rows = _read_csv(tmp_path / "p1.csv")
    assert len(rows) == 241 * 2 + 151  # two_hand_placed has a base; drop_on_table has none


def test_frame_tables_refuse_other_outputs_and_are_not_left_by_a_failed_run(tmp_path):
    golden = str(RECORDINGS / "drop_on_table.mcap")
    result = run_cli("vade-replay", golden, "--events", golden)
    assert result.returncode == 2 and "--events" in result.stderr and "refusing" in result.stderr
    table = str(tmp_path / "t.csv")
    result = run_cli("vade-replay", golden, "--csv", table, "--poses", table)
    assert result.returncode == 2 and "--poses" in result.stderr
    # A file damaged part-way: exit 2 naming it; no table of half a run (an existing one
    # is kept as it was), and the regenerated recording is kept only as .partial.
    damaged = _damaged(tmp_path)
    events, kept = tmp_path / "events.csv", tmp_path / "kept.csv"
    kept.write_text("recording,an older table\n")
    regenerated = tmp_path / "regenerated.mcap"
    result = run_cli("vade-replay", str(damaged), "--events", str(events), "--poses", str(kept),
                     "-o", str(regenerated))
    assert result.returncode == 2 and "damaged" in result.stderr
    assert "120 regenerated frames before it are kept in" in result.stderr
    assert not events.exists() and kept.read_text() == "recording,an older table\n"
    assert not regenerated.exists() and (tmp_path / "regenerated.mcap.partial").exists()
    partial = Recording(tmp_path / "regenerated.mcap.partial")
    assert len(list(partial.frames())) == 120 and partial.truncated
    assert partial.stopped.startswith(f"{damaged}: damaged after 120 complete frames")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "damaged.mcap", "kept.csv", "regenerated.mcap.partial"]  # no temporary table left


def test_a_table_that_cannot_be_written_stops_the_run_at_once(tmp_path):
    """A folder that cannot hold the table: exit 2 naming the option, before any replay. A
    table that fails while written (a full device behind a link): exit 2, one line, and
    the path is not removed."""
    goldens = [str(RECORDINGS / f"{name}.mcap") for name in ("drop_on_table", "hoist_placed")]
    result = run_cli("vade-replay", *goldens, "--events", "/proc/vade-table.csv")
    assert result.returncode == 2 and "--events" in result.stderr
    assert result.stdout == ""  # nothing replayed
    if Path("/dev/full").exists():
        link = tmp_path / "full.csv"
        link.symlink_to("/dev/full")
        for files in (goldens[:1], goldens):
            result = run_cli("vade-replay", *files, "--poses", str(link))
            assert result.returncode == 2, result.stderr
            assert "--poses" in result.stderr and "No space left" in result.stderr
            assert "Traceback" not in result.stderr
            assert link.is_symlink() and Path("/dev/full").is_char_device()


@pytest.mark.parametrize("name", sorted(p.stem for p in RECORDINGS.glob("*.mcap")))
def test_a_what_if_folds_the_recorded_frames_to_the_recordings_own_analysis(name):
    """A what-if also folds the recording's decoded frames: with a change that alters
    nothing, that analysis is the replay's, field for field, and no change is named."""
    path = RECORDINGS / f"{name}.mcap"
    plain = replay(Recording(path)).to_dict()
    assert "recorded_analysis" not in plain and "analysis_changes" not in plain
    # An override that changes nothing (the model every golden uses): the same run.
    same = replay(Recording(path), overrides={"physics.model": "general"})
    assert same.match and same.overrides
    summary = same.to_dict()
    assert summary["recorded_analysis"] == plain["analysis"] == summary["analysis"]
    assert summary["analysis_changes"] == []


def test_a_what_if_names_how_the_analysis_changed():
    """Would a 10 kg hoist have lifted the 20 kg ring? No: the comparison says what that
    did to the study's numbers, besides the frame where the runs part."""
    summary = replay(Recording(RECORDINGS / "hoist_placed.mcap"),
                     overrides={"tools.hoist.max_mass_kg": "10"}).to_dict()
    assert summary["analysis_changes"] == [
        "ring: grabs 1 -> 0, tool_grabs 1 -> 0, releases 1 -> 0, refused_grabs 1 -> 2, "
        "placed_at_s 3.4 s -> never, ONBASESLIDE 0.200 s -> 0.000 s, ONTOOL 2.400 s -> "
        "0.000 s, PLACED 0.600 s -> 0.000 s, STATIC 0.800 s -> 4.000 s",
        "refused grabs too_heavy_for_tool: 0 -> 1"]
    assert summary["recorded_analysis"]["parts"]["ring"]["placed_at_s"] == pytest.approx(3.4)
    result = run_cli("vade-replay", str(RECORDINGS / "hoist_placed.mcap"), "--set",
                     "tools.hoist.max_mass_kg=10")
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[-1].startswith("analysis: ring: grabs 1 -> 0")


def test_a_what_if_names_changed_seconds_in_a_state():
    """Stronger gravity in flight: the same counts, but the peg lands sooner; the
    comparison names the seconds moved between INSPACE and STATIC, not "unchanged"."""
    summary = replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                     overrides={"physics.gravity_scale_free": "1.0"}).to_dict()
    (change,) = summary["analysis_changes"]
    before = summary["recorded_analysis"]["parts"]["peg"]["time_in_state_s"]
    after = summary["analysis"]["parts"]["peg"]["time_in_state_s"]
    assert after["INSPACE"] < before["INSPACE"] - 0.1
    assert change == (f"peg: INSPACE {before['INSPACE']:.3f} s -> {after['INSPACE']:.3f} s, "
                      f"STATIC {before['STATIC']:.3f} s -> {after['STATIC']:.3f} s")


def test_a_what_if_on_a_recording_it_cannot_fully_read_goes_on_without_the_comparison(
        tmp_path):
    """A damaged /parts message: a plain replay names it as a divergence; a what-if still
    runs, and says why it has no comparison."""
    import json as json_
    from mcap_edit import copy_recording

    def drop_xyzw(topic, index, data):
        if topic == "/parts" and index == 60:
            doc = json_.loads(data)
            (doc["parts"][0] if doc["parts"] else doc["base"]).pop("xyzw")
            return json_.dumps(doc).encode()
        return data
    bad = tmp_path / "bad.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", bad, drop_xyzw)
    assert not replay(Recording(bad)).match
    summary = replay(Recording(bad), overrides={"physics.gravity_scale_free": "0.25"}).to_dict()
    assert summary["frames"] == 151 and "analysis_changes" not in summary
    assert any(w.startswith("no comparison with the recording's analysis or poses: its frame 60")
               for w in summary["warnings"])


def test_a_what_if_warns_only_of_what_its_changes_bring(tmp_path):
    """The recording's own slips were warned of when it was made; a what-if names only the
    ones its --set values bring."""
    import json as json_
    from vade_replay.session import load
    doc = json_.loads((RECORDINGS / "drop_on_table.json").read_text())
    doc["tracker"]["devices"]["right_hand"].append({"t": 99.0})
    path = tmp_path / "late.json"
    path.write_text(json_.dumps(doc))
    out = tmp_path / "late.mcap"
    from vade_replay.replay import record
    assert len(record(load(path), out).warnings) == 1
    assert replay(Recording(out), overrides={"physics.friction_static": "0.6"}).warnings == []
    (warning,) = replay(Recording(out), overrides={"physics.gravity": "[0, 0, -0.0098]"}).warnings
    assert warning.startswith("physics.gravity is 0.0098 m/s^2")


def test_a_what_if_of_a_parts_density_asks_would_it_still_be_lifted():
    """The 0.35 kg peg made 200 t/m^3 (25.6 kg, over both hands' 15 kg): refused at the
    grab, and it stays on the table; a density that only changes its mass lifts it as
    recorded (its flight does not depend on its mass)."""
    summary = replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                     overrides={"parts.peg.density": "200000"}).to_dict()
    assert summary["first_divergence"]["frame"] == 42
    assert summary["analysis"]["refused_grabs"] == {"too_heavy_for_two_hands": 1}
    assert summary["analysis"]["parts"]["peg"]["grabs"] == 0
    assert replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                  overrides={"parts.peg.density": "5000"}).match
    result = run_cli("vade-replay", str(RECORDINGS / "shaft_placed.mcap"), "--set",
                     "parts.nothing.density=1")
    assert result.returncode == 2 and "its parts: sleeve" in result.stderr


def test_the_study_table_names_each_sessions_length_unit():
    """A study may mix sessions in mm and in m: the same --set number is a length in each
    one's own unit, so each row names it."""
    from vade_replay.replay import analysis_rows
    summary = replay(Recording(RECORDINGS / "hoist_placed.mcap"),
                     overrides={"tools.hoist.grab_radius": "0.08"}).to_dict()
    assert summary["units"] == "m"
    (row,) = analysis_rows("hoist_placed.mcap", summary)
    assert (row["units"], row["overrides"]) == ("m", "tools.hoist.grab_radius=0.08")
    (row,) = analysis_rows("x.mcap", {**summary, "units": "mm"})
    assert row["units"] == "mm"


def test_a_what_if_names_its_first_change_in_events():
    """An engineer's trial: a what-if's departure was named at a held part's velocity in
    its last bits (frame 20) where the change that mattered came later. The first frame
    whose events differ is named too: throw_and_catch at half the scaled gravity is not
    caught; at frame 108 the cylinder hits the table instead."""
    result = run_cli("vade-replay", str(RECORDINGS / "throw_and_catch.mcap"), "--set",
                     "physics.gravity_scale_free=0.5")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("what-if (physics.gravity_scale_free=0.5): departs")
    assert lines[1] == ("first change in events: frame 108 (t = 1.800000 s): recorded none; "
                        "what-if ContactMade cylinder (hit_environment), ModeChanged cylinder "
                        "(hit_environment) to STATIC")
    summary = json.loads(run_cli("vade-replay", str(RECORDINGS / "throw_and_catch.mcap"),
                                 "--set", "physics.gravity_scale_free=0.5",
                                 "--json").stdout)
    assert summary["first_event_change"]["frame"] == 108
    # A plain replay has none to name.
    plain = json.loads(run_cli("vade-replay", str(RECORDINGS / "throw_and_catch.mcap"),
                               "--json").stdout)
    assert plain["first_event_change"] is None


def test_the_study_table_says_which_rows_are_as_recorded_and_where_a_what_if_changed():
    """A researcher's trial: --as-recorded rows could not be told from rows replayed with
    this version's defaults, and a what-if's first change in events was only in --json;
    its overrides were doubly quoted (physics.release_velocity=""two_frame"")."""
    import csv
    import io
    old = Path(__file__).resolve().parent / "data" / "shaft_slide_off_before_analytic4.mcap"
    result = run_cli("vade-replay", str(old), "--as-recorded", "--csv", "-")
    rows = list(csv.DictReader(io.StringIO(result.stdout)))
    assert rows and all(r["as_recorded"].startswith("block_cut=both; block_event=always")
                        and "release_velocity=window_fit" in r["as_recorded"] for r in rows)
    plain = list(csv.DictReader(io.StringIO(run_cli(
        "vade-replay", str(RECORDINGS / "throw_and_catch.mcap"), "--csv", "-").stdout)))
    assert plain[0]["as_recorded"] == "" and plain[0]["first_event_change_frame"] == ""
    what_if = list(csv.DictReader(io.StringIO(run_cli(
        "vade-replay", str(RECORDINGS / "throw_and_catch.mcap"), "--set",
        "physics.gravity_scale_free=0.5", "--set", "physics.release_velocity=two_frame",
        "--csv", "-").stdout)))
    assert what_if[0]["first_event_change_frame"] != ""
    assert what_if[0]["overrides"] == ("physics.gravity_scale_free=0.5; "
                                       "physics.release_velocity=two_frame")


def test_a_studys_what_if_of_a_part_applies_where_the_session_has_it(tmp_path):
    """A researcher's trial: a what-if of a part that only some of a study's sessions have
    failed (exit 2) on the others, and a researcher had to pick the files. It is applied
    where the session has the part, left out elsewhere (said on the line, in a warning, in
    the table's not_applied column and in --json), and a part none of them has is one error
    before anything is written. One recording alone still refuses it."""
    import csv
    sleeve, gear = str(RECORDINGS / "shaft_placed.mcap"), str(RECORDINGS / "gear_pendulum.mcap")
    table = tmp_path / "study.csv"
    # 20 kg: more than two hands lift (15 kg), so the sleeve is never picked up.
    result = run_cli("vade-replay", sleeve, gear, "--set", "parts.sleeve.mass=20",
                     "--csv", str(table))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith(f"{sleeve}: what-if (parts.sleeve.mass=20): departs")
    assert lines[1] == f"{gear}: match (not applied: parts.sleeve.mass)"
    assert lines[2] == "2 recordings: 1 unchanged, 1 departed, 0 could not be replayed"
    assert (f"warning: {gear}: --set parts.sleeve.mass not applied: no part 'sleeve' in "
            "this session (its parts: gear)") in result.stderr
    rows = {r["part"]: r for r in csv.DictReader(table.open(newline=""))}
    assert rows["sleeve"]["overrides"] == "parts.sleeve.mass=20"
    assert rows["sleeve"]["not_applied"] == "" and rows["sleeve"]["grabs"] == "0"
    assert rows["gear"]["overrides"] == "" and rows["gear"]["match"] == "True"
    assert rows["gear"]["not_applied"] == "parts.sleeve.mass"
    as_json = json.loads(run_cli("vade-replay", sleeve, gear, "--set",
                                 "parts.sleeve.mass=20", "--json").stdout)
    assert as_json[0]["not_applied"] == {} and as_json[0]["overrides"] == {
        "parts.sleeve.mass": 20}
    assert as_json[1]["not_applied"] == {
        "parts.sleeve.mass": "no part 'sleeve' in this session (its parts: gear)"}
    assert as_json[1]["overrides"] == {}
    table.unlink()
    none = run_cli("vade-replay", sleeve, gear, "--set", "parts.spacer.mass=1",
                   "--csv", str(table))
    assert none.returncode == 2 and not table.exists() and none.stdout == ""
    # Each session's reason, which names its own parts (only the first one's was given).
    assert none.stderr == ("error: --set parts.spacer.mass: none of the 2 recordings' "
                           f"sessions can take it ({sleeve}: no part 'spacer' in this "
                           f"session (its parts: sleeve); {gear}: no part 'spacer' in this "
                           "session (its parts: gear))\n")
    # A study's many recordings of one session: a reason once, with how many it is of.
    tilted = str(RECORDINGS / "gear_tilted_shaft.mcap")
    # Every reason, none left out (a review: "4 more reasons" hid the part names sought).
    every = run_cli("vade-replay", *sorted(str(p) for p in RECORDINGS.glob("*.mcap")),
                    "--set", "parts.spacer.mass=1")
    assert every.returncode == 2 and "more reasons" not in every.stderr
    for name in ("peg", "gear", "ring", "block", "sleeve", "cylinder", "box"):
        assert f"(its parts: {name}" in every.stderr or f", {name}" in every.stderr, name
    many = run_cli("vade-replay", gear, sleeve, tilted, "--set", "parts.spacer.mass=1")
    assert many.returncode == 2 and f"({gear} and 1 more: no part 'spacer' in this session " \
        "(its parts: gear); " in many.stderr
    alone = run_cli("vade-replay", gear, "--set", "parts.sleeve.mass=20")
    assert alone.returncode == 2 and "no part 'sleeve' in this session" in alone.stderr


def test_tables_end_their_lines_with_a_newline_alone(tmp_path):
    """A researcher's trial: the tables ended their lines with \\r\\n (csv's default, RFC
    4180), which awk and cut keep on the last column. Every table's lines end with \\n,
    and the last column reads clean."""
    paths = {option: tmp_path / f"{option[2:]}.csv" for option in ("--csv", "--events",
                                                                   "--poses")}
    args = [x for option, path in paths.items() for x in (option, str(path))]
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), *args)
    assert result.returncode == 0, result.stderr
    for option, path in paths.items():
        data = path.read_bytes()
        assert b"\r" not in data and data.endswith(b"\n"), option
        lines = data.decode().split("\n")[:-1]
        width = len(lines[0].split(","))
        assert len(lines) > 1 and all(line.count(",") + 1 >= width for line in lines)
        assert lines[0].rsplit(",", 1)[1] in ("made_from", "wz"), option


def _snapshot(name: str, position, angle_about_z: float = 0.0):
    import math as m
    from vade_replay.frames import PartSnapshot
    half = 0.5 * angle_about_z
    return PartSnapshot(name, "INSPACE", position, (0.0, 0.0, m.sin(half), m.cos(half)),
                        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def test_the_departure_is_each_parts_largest_distance_and_angle_with_their_frames():
    """``Departure`` against hand-made frames: a 3-4-5 offset is 5, a turn of 0.3 rad
    about z against none is 0.3 rad, and the largest of each is kept with its frame."""
    from vade_replay.frames import FrameRecord, TrackerFrame
    from vade_replay.replay import Departure, describe_departure
    d = Departure()
    for frame, (dx, angle) in enumerate([(0.0, 0.0), (5.0, 0.1), (1.0, 0.3), (2.0, 0.0)]):
        inputs = TrackerFrame(frame, frame * 10**9 // 60, ())
        recorded = FrameRecord(inputs, None, (_snapshot("a", (1.0, 2.0, 3.0)),
                                              _snapshot("b", (0.0, 0.0, 0.0))))
        ours = FrameRecord(inputs, None, (_snapshot("a", (1.0 + 0.6 * dx, 2.0 + 0.8 * dx, 3.0),
                                                    angle),
                                          _snapshot("b", (0.0, 0.0, 0.0))))
        d.add(recorded, ours)
    got = d.result()
    assert got["a"]["distance_m"] == pytest.approx(5.0, rel=1e-15)
    assert got["a"]["distance_frame"] == 1
    assert got["a"]["angle_rad"] == pytest.approx(0.3, rel=1e-12)
    assert got["a"]["angle_frame"] == 2
    assert got["b"] == {"distance_m": 0.0, "distance_frame": None, "angle_rad": 0.0,
                        "angle_frame": None}
    assert describe_departure(got) == "a 5 m (frame 1), 0.3 rad (frame 2); b none"


def test_a_what_if_says_how_far_its_parts_went_from_the_recording():
    """A README trial: a what-if whose change shows only at round-off read "departs from
    the recording" with two values and no word on their size. It now gives each part's
    largest departure. ``drop_on_table`` let go at rest from height h above the table at
    twice the flight gravity: the two falls are apart by (g2 - g1) t^2 / 2 until the faster
    lands, and close again as the slower follows, so the largest is h (1 - g1/g2) at the
    faster's landing, sampled at frames: low by at most the rate at which the gap changes
    there (g1 t1 on either side of it, as g2 = 2 g1) times a frame (1/60 s)."""
    import math as m
    from vade_replay.replay import recorded_records
    path = RECORDINGS / "drop_on_table.mcap"
    records = list(recorded_records(Recording(path)))
    peg = [next(p for p in r.parts if p.name == "peg") for r in records]
    released = max(i for i, p in enumerate(peg) if p.mode == "INHAND") + 1
    assert max(map(abs, peg[released].linear_velocity)) < 1e-9  # let go at rest
    h = peg[released].position[2] - peg[-1].position[2]
    g1 = 9.81 * 0.25
    summary = replay(Recording(path), overrides={"physics.gravity_scale_free": "0.5"})
    far = summary.largest_departure["peg"]
    expected = h * (1.0 - 0.25 / 0.5)
    t1 = m.sqrt(2.0 * h / (2.0 * g1))
    assert expected - g1 * t1 / 60.0 <= far["distance_m"] <= expected + 1e-9
    landing = released + t1 * 60.0
    assert abs(far["distance_frame"] - landing) <= 1.5
    assert far["angle_rad"] == 0.0  # let go level, it falls without turning
    row = analysis_rows_of(summary)["peg"]
    assert row["departure_m"] == far["distance_m"] and row["departure_rad"] == 0.0
    result = run_cli("vade-replay", str(path), "--set", "physics.gravity_scale_free=0.5")
    assert f"\nlargest departure: peg {far['distance_m']:.3g} m (frame " \
           f"{far['distance_frame']})\n" in result.stdout
    # A replay that matches departed nowhere; its table says 0.
    plain = replay(Recording(path))
    assert plain.match and plain.largest_departure == {}
    assert analysis_rows_of(plain)["peg"]["departure_m"] == 0.0


def analysis_rows_of(summary) -> dict:
    from vade_replay.replay import analysis_rows
    return {row["part"]: row for row in analysis_rows("x.mcap", summary.to_dict())}


def test_a_replay_that_diverges_measures_its_departure_from_there(tmp_path):
    """A golden that diverges says whether that is round-off or a part somewhere else: the
    recording's peg, in the hand, moved up 1 mm from frame 60 on (a recording edited for
    the test), so the replay departs at frame 60 by 1 mm, and by no angle."""
    import json as json_
    from mcap_edit import copy_recording

    def lift(topic, frame, data):
        if topic == "/parts" and frame >= 60:
            doc = json_.loads(data)
            for item in doc["parts"]:
                if item["name"] == "peg":
                    item["position"][2] += 0.001
            return json_.dumps(doc).encode()
        return data
    path = tmp_path / "edited.mcap"
    copy_recording(RECORDINGS / "drop_on_table.mcap", path, lift)
    summary = replay(Recording(path))
    assert not summary.match and summary.first_divergence["frame"] == 60
    far = summary.largest_departure["peg"]
    assert far["distance_m"] == pytest.approx(0.001, rel=1e-9)
    assert far["distance_frame"] >= 60 and far["angle_rad"] == 0.0
    result = run_cli("vade-replay", str(path))
    assert result.returncode == 1
    assert "\nlargest departure since: peg 0.001 m (frame " in result.stdout


@pytest.mark.parametrize("name, kinds", [
    ("gear_tilted_shaft", {"ContactMade"}),                  # blocked, and goes on turning
    ("shaft_slide_blocked", {"ContactMade", "ModeChanged"}),  # blocked, and rests there
])
def test_a_block_is_counted_once_whether_or_not_the_part_then_rests(name, kinds):
    """``blocked`` counts the frames in which the base stopped a part's slide or turn (a
    user's trial: the gear on the tilted shaft, blocked in its slide while it went on
    turning, counted 0): one block a frame, its contact and the mode change it brings
    being one."""
    from vade_replay import codec
    blocked: dict[int, set] = {}
    for record in Recording(RECORDINGS / f"{name}.mcap").frames():
        for topic, data in record.derived:
            if topic.startswith("/events/"):
                event = codec.decode_event(topic, data)
                if event.cause == "blocked_by_base":
                    blocked.setdefault(record.inputs.frame, set()).add(event.kind)
    assert list(blocked.values()) == [kinds]  # one frame, with these events
    summary = replay(Recording(RECORDINGS / f"{name}.mcap"))
    (stats,) = summary.analysis.parts.values()
    assert stats.blocked == 1 and stats.as_dict()["blocked"] == 1


@pytest.mark.parametrize("golden", sorted(RECORDINGS.glob("*.mcap")), ids=lambda p: p.stem)
def test_the_recorded_inputs_as_a_tracker_log_record_the_same_session(golden, tmp_path):
    """``--tracker``: the recorded inputs as a tracker log a session reads (a CAD user's
    trial: no way to run a participant's recorded hand motion through a changed design).
    The golden's own session with its tracker replaced by that log records the golden
    again, bit for bit: every pose and event of every frame."""
    from conftest import run_records
    from vade_replay.replay import recorded_records

    log = tmp_path / "hands.csv"
    result = run_cli("vade-replay", str(golden), "--tracker", str(log))
    assert result.returncode == 0, result.stderr
    doc = json.loads(golden.with_suffix(".json").read_text())
    doc["tracker"] = {"csv": "hands.csv", "csv_units": "m", "csv_time_unit": "ns",
                      "csv_quaternion_order": "xyzw"}
    again = run_records(doc, {"hands.csv": log.read_bytes()})
    recorded = list(recorded_records(Recording(golden)))
    assert len(again) == len(recorded)
    for a, b in zip(again, recorded):
        assert a.time_ns == b.time_ns and a.inputs.devices == b.inputs.devices
        assert [(p.name, p.mode, p.position, p.rotation_xyzw) for p in a.parts] == \
            [(p.name, p.mode, p.position, p.rotation_xyzw) for p in b.parts]
        assert [e.kind for e in a.events] == [e.kind for e in b.events]


def test_a_recording_a_what_if_wrote_says_so_when_replayed(tmp_path):
    """A researcher's trial: a what-if written with -o kept the session's name and, replayed
    later, matched with no word of its changes: in a study's table its rows looked like the
    original run's. It now says which changes made it and of which recording, on its line,
    in the table (made_with_overrides, made_from) and in --json; a what-if of that
    recording adds its own changes (the later winning), and a plain -o keeps them."""
    import csv
    import io
    source = str(RECORDINGS / "plane_block_wall.mcap")
    first, second, again = (str(tmp_path / n) for n in ("a.mcap", "b.mcap", "c.mcap"))
    assert run_cli("vade-replay", source, "--set", "physics.friction_dynamic=0.1",
                   "-o", first).returncode == 0
    assert run_cli("vade-replay", first, "--set", "physics.friction_dynamic=0.15",
                   "--set", "parts.block.mass=2", "-o", second).returncode == 0
    assert run_cli("vade-replay", second, "-o", again).returncode == 0
    line = run_cli("vade-replay", first)
    assert line.returncode == 0
    assert line.stdout.startswith(
        f"a what-if's recording (physics.friction_dynamic=0.1; of {source}): match:")
    rows = {r["recording"]: r for r in csv.DictReader(io.StringIO(run_cli(
        "vade-replay", source, first, second, again, "--csv", "-").stdout))}
    assert (rows[source]["made_with_overrides"], rows[source]["made_from"]) == ("", "")
    assert (rows[first]["made_with_overrides"], rows[first]["made_from"]) == (
        "physics.friction_dynamic=0.1", source)
    both = ("parts.block.mass=2; physics.friction_dynamic=0.15", source)
    assert (rows[second]["made_with_overrides"], rows[second]["made_from"]) == both
    assert (rows[again]["made_with_overrides"], rows[again]["made_from"]) == both
    assert all(r["match"] == "True" for r in rows.values())
    made = json.loads(run_cli("vade-replay", second, "--json").stdout)["made_by_what_if"]
    assert made == {"from": source, "overrides": {"parts.block.mass": 2,
                                                  "physics.friction_dynamic": 0.15}}
    assert json.loads(run_cli("vade-replay", source, "--json").stdout)["made_by_what_if"] is None
