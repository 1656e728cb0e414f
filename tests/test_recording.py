"""What a recording carries: chunks of at most a second, attachments, metadata, times."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from conftest import RECORDINGS
from vade_replay.recording import Recording
from vade_replay.replay import record
from vade_replay.session import load


def test_chunks_span_at_most_a_second_and_are_zstd():
    with open(RECORDINGS / "throw_and_catch.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert len(summary.chunk_indexes) >= 3  # 3 s of session
    for chunk in summary.chunk_indexes:
        assert chunk.compression == "zstd"
        assert chunk.message_end_time - chunk.message_start_time <= 10**9


def test_attachments_and_metadata_make_it_self_contained():
    with open(RECORDINGS / "drop_on_table.mcap", "rb") as f:
        reader = make_reader(f)
        attachments = {a.name: a.data for a in reader.iter_attachments()}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert attachments["session.json"] == (RECORDINGS / "drop_on_table.json").read_bytes()
    assert json.loads(metadata["physics"]["gravity_scale_free"]) == 0.25
    for package in ("numpy", "trimesh", "python-fcl", "mcap", "vade_replay", "python"):
        assert metadata["versions"][package]


def test_log_time_is_simulated_nanoseconds_in_frame_order():
    with open(RECORDINGS / "drop_on_table.mcap", "rb") as f:
        times, sequences = [], []
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.topic == "/tracker":
                data = json.loads(message.data)
                assert message.log_time == data["time_ns"] == data["frame"] * 10**9 // 60
                times.append(message.log_time)
            sequences.append(message.sequence)
    assert times == sorted(times) and times[0] == 0
    assert sequences == list(range(len(sequences)))
    assert Recording(RECORDINGS / "drop_on_table.mcap").frame_count == len(times) == 151


LEGACY = Path(__file__).resolve().parent / "data" / "legacy_full_drop_on_table.mcap"


def test_new_recordings_list_only_the_parts_that_changed():
    from vade_replay import codec
    recording = Recording(RECORDINGS / "drop_on_table.mcap")
    assert recording.parts_encoding == codec.PARTS_CHANGED
    listed = [json.loads(d)["parts"] for f in recording.frames() for t, d in f.derived
              if t == codec.PARTS_TOPIC]
    # The peg rests until it is grabbed: frames before that list nothing, but the first and
    # the first of each second list it.
    assert listed[0] and listed[60] and listed[120] and not listed[7]


def test_a_recording_in_the_older_full_encoding_still_replays_and_reads():
    """A study's files from before the ``changed`` encoding: replayed with the encoding
    they were written in, read back to the same states as their re-recording."""
    from vade_replay import codec
    from vade_replay.replay import recorded_records, replay
    legacy = Recording(LEGACY)
    assert legacy.parts_encoding == codec.PARTS_FULL
    assert replay(legacy).match
    now = Recording(RECORDINGS / "drop_on_table.mcap")
    assert [(r.frame, r.parts, r.events) for r in recorded_records(legacy)] == \
        [(r.frame, r.parts, r.events) for r in recorded_records(now)]


def test_a_replay_written_out_keeps_its_sources_encoding(tmp_path):
    from vade_replay import codec
    from vade_replay.replay import replay
    out = tmp_path / "again.mcap"
    replay(Recording(LEGACY), out=out)
    assert Recording(out).parts_encoding == codec.PARTS_FULL and replay(Recording(out)).match


def test_a_session_validated_when_recorded_is_not_validated_again(tmp_path, monkeypatch):
    """The recording stores a digest of the schema and the session bytes it validated;
    opening it skips jsonschema (most of the setup of a 200-part session) while both are
    unchanged, and validates as before once either differs."""
    from mcap_edit import copy_recording
    from vade_replay import session as session_module
    from vade_replay.errors import SessionError

    path = tmp_path / "drop.mcap"
    record(load(RECORDINGS / "drop_on_table.json"), path)
    calls = []
    real = session_module.validate
    monkeypatch.setattr(session_module, "validate",
                        lambda doc, *, file: (calls.append(file), real(doc, file=file)))
    Recording(path)
    assert calls == []

    # The digest does not match (another schema, or an edited digest): validated again.
    stale = tmp_path / "stale.mcap"
    copy_recording(path, stale, lambda topic, i, data: data,
                   edit_metadata=lambda name, v: {"session": "0" * 64}
                   if name == "validated" else v)
    Recording(stale)
    assert len(calls) == 1

    # The session edited after recording: validated, and the mistake named as before.
    def unknown_field(name, data):
        if name != "session.json":
            return data
        doc = json.loads(data)
        doc["colour"] = "red"
        return json.dumps(doc).encode()
    edited = tmp_path / "edited.mcap"
    copy_recording(path, edited, lambda topic, i, data: data, edit_attachment=unknown_field)
    with pytest.raises(SessionError, match="unknown field 'colour'"):
        Recording(edited)

    # A digest made for the edited bytes (forged: no mistake does that) skips the schema;
    # what the scene builder then trips on is still named by the schema, not a traceback.
    def far(name, data):
        if name != "session.json":
            return data
        doc = json.loads(data)
        doc.setdefault("physics", {})["grab_radius"] = "far"
        return json.dumps(doc).encode()
    forged_session = far("session.json", (RECORDINGS / "drop_on_table.json").read_bytes())
    forged = tmp_path / "forged.mcap"
    copy_recording(path, forged, lambda topic, i, data: data, edit_attachment=far,
                   edit_metadata=lambda name, v: {"session": session_module.validated_digest(
                       forged_session)} if name == "validated" else v)
    recording = Recording(forged)
    assert recording.session.trusted
    with pytest.raises(SessionError, match="grab_radius"):
        recording.session.build_scene()
