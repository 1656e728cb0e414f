"""What a recording carries: chunks of at most a second, attachments, metadata, times."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from conftest import RECORDINGS
from vade_replay.recording import Recording
from vade_replay.replay import record, replay
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


def test_a_recording_in_the_older_full_encoding_still_replays_and_reads(tmp_path):
    """A study's files from before the ``changed`` encoding: replayed with the encoding
    they were written in (and the physics defaults they were made with, ``--as-recorded``:
    the release velocity's default changed since), read back to the same states as their
    re-recording with those defaults."""
    from vade_replay import codec
    from vade_replay.replay import as_made, record, recorded_records, replay
    legacy = Recording(LEGACY)
    assert legacy.parts_encoding == codec.PARTS_FULL
    assert replay(legacy, as_recorded=True).match
    session, _ = as_made(legacy)
    record(session, tmp_path / "again.mcap")
    now = Recording(tmp_path / "again.mcap")
    assert now.parts_encoding == codec.PARTS_CHANGED
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


# The chunk reader (recording._chunk_records) cuts messages out itself; the mcap library's
# breakup_chunk is the reference it is held to.

def _chunks(path: Path):
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader
    with open(path, "rb") as stream:
        return [r for r in StreamReader(stream, emit_chunks=True).records if isinstance(r, Chunk)]


@pytest.mark.parametrize("golden", sorted(RECORDINGS.glob("*.mcap")), ids=lambda p: p.stem)
def test_chunks_are_read_as_the_mcap_library_reads_them(golden):
    from mcap.records import Channel, Message
    from mcap.stream_reader import breakup_chunk
    from vade_replay.recording import _chunk_records
    chunks = _chunks(golden)
    assert chunks
    for chunk in chunks:
        expected = [(r.channel_id, r.data) if isinstance(r, Message) else r
                    for r in breakup_chunk(chunk) if isinstance(r, (Channel, Message))]
        assert list(_chunk_records(chunk)) == expected


def _library_records(stream):
    """The reference for ``recording._records``: the library's reader, filtered."""
    from mcap.records import (Attachment, Channel, Chunk, DataEnd, Footer, Header, Message,
                              Metadata)
    from mcap.stream_reader import StreamReader
    for item in StreamReader(stream, emit_chunks=True).records:
        if isinstance(item, (Header, Attachment, Chunk, Channel, Message, Metadata, DataEnd,
                             Footer)):
            yield item


@pytest.mark.parametrize("golden", sorted(RECORDINGS.glob("*.mcap"))[:3], ids=lambda p: p.stem)
def test_records_outside_chunks_are_the_mcap_librarys_less_the_indexes(golden):
    """``_records`` passes over the message indexes (and the summary's other records)
    unread; every record it yields is the library's, in the library's order."""
    from vade_replay.recording import _records
    with open(golden, "rb") as stream:
        ours = list(_records(stream))
    with open(golden, "rb") as stream:
        assert ours == list(_library_records(stream))
    assert type(ours[-1]).__name__ == "Footer"


def _outcome(monkeypatch):
    """``outcome(path, reader)``: the frames, the cut-short flag and the error of reading
    ``path`` with ``reader`` in the place of ``recording._records``."""
    from vade_replay import recording as rec_module
    from vade_replay.errors import VadeError

    def outcome(path, reader):
        monkeypatch.setattr(rec_module, "_records", reader)
        try:
            recording = Recording(path)
            frames = [(f.inputs, f.derived) for f in recording.frames()]
            return frames, recording.truncated, None
        except VadeError as exc:
            return None, None, exc.message
    return outcome


def test_a_file_cut_anywhere_reads_as_it_did_through_the_library(tmp_path, monkeypatch):
    """Cut short at any byte (inside a chunk, a message index, the summary, the footer), a
    recording gives the frames, the cut-short flag and the error it gave when the mcap
    library read every record."""
    from vade_replay import recording as rec_module
    golden = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    ours = rec_module._records
    outcome = _outcome(monkeypatch)
    cuts = sorted({*range(0, len(golden), len(golden) // 37), *range(len(golden) - 400,
                                                                     len(golden), 7)})
    for cut in cuts:
        path = tmp_path / "cut.mcap"
        path.write_bytes(golden[:cut])
        assert outcome(path, ours) == outcome(path, _library_records), cut


@pytest.mark.stress
def test_a_file_damaged_at_any_byte_reads_as_it_did_through_the_library(tmp_path, monkeypatch):
    """One byte changed anywhere (a length, an opcode, an index's head, the summary): the
    same frames, cut-short flag or error as when the mcap library read every record. A
    review found the first version of ``_records``, which passed over the indexes by their
    length, reading 867 of 13,200 such files otherwise (a chunk whose opcode became an
    index's was passed over: 60 frames gone without a word). Every 61st byte in CI;
    ``VADE_STRESS=full``: every byte (67,036 files, ~4 min)."""
    import strategies as S
    from vade_replay import recording as rec_module
    golden = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    ours = rec_module._records
    outcome = _outcome(monkeypatch)
    path = tmp_path / "damaged.mcap"
    stored = _attachment_bodies(golden)
    assert len(stored) >= 1  # (the session; drop_on_table stores no other file)
    checked = 0
    for at in sorted({*range(0, len(golden), 1 if S.FULL else 61),
                      *(start + 3 for start, _ in stored)}):  # (one inside each, in CI too)
        for value in (golden[at] ^ 0xFF, 7):
            if value == golden[at]:
                continue
            damaged = bytearray(golden)
            damaged[at] = value
            path.write_bytes(damaged)
            if any(start <= at < end for start, end in stored):
                # Inside a stored session or file: the library reads on (whatever the
                # damage made of it); ours refuses the file. A length field damaged may
                # make it fail elsewhere first: an error either way, never frames.
                frames, _, message = outcome(path, ours)
                assert frames is None and message, (at, value)
                checked += "damaged (its CRC-32 does not match" in message
                continue
            assert outcome(path, ours) == outcome(path, _library_records), (at, value)
    assert checked >= 2


def _attachment_bodies(data: bytes) -> list[tuple[int, int]]:
    """The byte ranges of the attachment records' bodies in an MCAP file (after each
    record's opcode and length), found by walking its records from the magic on."""
    import struct
    at, out = 8, []
    while at + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, at)
        if opcode == 0x09:  # Attachment
            out.append((at + 9, at + 9 + length))
        if opcode == 0x02:  # Footer: the end
            break
        at += 9 + length
    return out


@pytest.mark.parametrize("chunking, compression", [(False, "NONE"), (True, "NONE")])
def test_a_recording_written_otherwise_by_another_mcap_writer_replays(tmp_path, chunking,
                                                                     compression):
    """Unchunked or uncompressed: what another tool may write reads the same."""
    from mcap.writer import CompressionType
    from mcap_edit import copy_recording
    from vade_replay.replay import replay
    golden = RECORDINGS / "drop_on_table.mcap"
    path = tmp_path / "other.mcap"
    copy_recording(golden, path, lambda topic, index, data: data, use_chunking=chunking,
                   compression=getattr(CompressionType, compression))
    read = [(f.inputs, f.derived) for f in Recording(path).frames()]
    assert read == [(f.inputs, f.derived) for f in Recording(golden).frames()]
    assert replay(Recording(path)).match


def _chunk(data: bytes, crc: int | None = None):
    import zlib
    from mcap.records import Chunk
    return Chunk(compression="", data=data, message_start_time=0, message_end_time=0,
                 uncompressed_crc=zlib.crc32(data) if crc is None else crc,
                 uncompressed_size=len(data))


def test_a_chunk_whose_data_fails_its_crc_is_refused():
    import struct
    from vade_replay.recording import _READ_ERRORS, _chunk_records
    record = struct.pack("<BQHIQQ", 5, 22 + 3, 1, 0, 0, 0) + b"abc"
    assert list(_chunk_records(_chunk(record))) == [(1, b"abc")]
    with pytest.raises(_READ_ERRORS, match="crc"):
        list(_chunk_records(_chunk(record, crc=12345)))


@pytest.mark.parametrize("record", [
    b"\x05" + (1000).to_bytes(8, "little") + bytes(30),   # runs past the chunk
    b"\x05" + (10).to_bytes(8, "little") + bytes(10),     # shorter than a message head
    b"\x05\x01\x00",                                      # a record head cut short
])
def test_a_malformed_record_in_a_chunk_is_a_read_error(record):
    from vade_replay.recording import _READ_ERRORS, _chunk_records
    with pytest.raises(_READ_ERRORS):
        list(_chunk_records(_chunk(record)))


def test_a_channel_record_cut_short_inside_a_chunk_is_damage_not_the_end_of_the_file():
    import struct
    from mcap.exceptions import EndOfFile
    from vade_replay.recording import _READ_ERRORS, _chunk_records
    record = struct.pack("<BQ", 4, 10) + bytes(10)  # a channel record of 10 bytes: too short
    with pytest.raises(_READ_ERRORS) as info:
        list(_chunk_records(_chunk(record)))
    assert not isinstance(info.value, EndOfFile)  # frames() would call that "cut short"


def test_a_damaged_lz4_chunk_is_a_read_error():
    """With lz4 installed, its damage is a RuntimeError; without, the compression is
    unsupported: a read error (exit 2 naming the file) either way, never a traceback."""
    from mcap.records import Chunk
    from vade_replay.recording import _READ_ERRORS, _chunk_records
    chunk = Chunk(compression="lz4", data=b"\x04\x22\x4d\x18garbage", message_start_time=0,
                  message_end_time=0, uncompressed_crc=0, uncompressed_size=100)
    with pytest.raises(_READ_ERRORS):
        list(_chunk_records(chunk))


def test_an_interrupted_recording_says_where_its_frames_are(tmp_path, capsys):
    """Ctrl-C while recording: the frames so far are kept in OUT.partial, and the one line
    the command prints says so (exit 130)."""
    from conftest import interrupted_recording
    session = load(RECORDINGS / "drop_on_table.json")
    out = tmp_path / "run.mcap"
    assert interrupted_recording(session, out, 10) == 130
    partial = tmp_path / "run.mcap.partial"
    assert capsys.readouterr().err.strip() == (
        f"interrupted; the 10 frames written so far are kept in {partial}")
    assert not out.exists() and len(list(Recording(partial).frames())) == 10
    # Closed properly, but short of the session: it says so when read (an engineer's
    # trial found a replay of such a file saying nothing).
    kept = Recording(partial)
    list(kept.frames())
    assert kept.truncated and kept.stopped == "interrupted"
    from conftest import run_cli
    result = run_cli("vade-replay", str(partial))
    assert result.returncode == 0 and ("the run that recorded it stopped before the "
                                       "session's end (interrupted); replayed the 10 frames"
                                       ) in result.stderr
    assert not Recording(RECORDINGS / "drop_on_table.mcap").stopped
    # The next run to the same output does not write over those frames (a user's trial:
    # an interrupted take was lost without a word), nor does a replay's -o; --force does.
    kept_bytes = partial.read_bytes()
    again = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(out))
    assert again.returncode == 2 and "Traceback" not in again.stderr
    assert again.stderr.startswith(f"error: {out}: {partial} holds the frames a run that "
                                   "stopped early kept"), again.stderr
    assert "--force" in again.stderr
    replayed = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "-o", str(out))
    assert replayed.returncode == 2 and str(partial) in replayed.stderr
    assert partial.read_bytes() == kept_bytes and not out.exists()
    forced = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(out),
                     "--force")
    assert forced.returncode == 0 and out.exists() and not partial.exists()
    # What is not a recording there is not called one (a review), and is kept all the same.
    partial.write_text("my notes\n")
    junk = run_cli("vade-record", str(RECORDINGS / "drop_on_table.json"), "-o", str(out))
    assert junk.returncode == 2 and (f"{partial} holds something that is not a recording "
                                     "(9 bytes)") in junk.stderr
    assert partial.read_text() == "my notes\n"


def test_a_recording_cut_in_its_index_keeps_every_frame(tmp_path):
    """Cut after its data's end record (the summary and footer lost), a recording still
    holds every frame whole: none is dropped, and it is not marked cut short (a study's
    ``truncated`` column means frames missing)."""
    golden = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    whole = len(list(Recording(RECORDINGS / "drop_on_table.mcap").frames()))
    for cut in (1, 10, 200):
        path = tmp_path / f"cut{cut}.mcap"
        path.write_bytes(golden[:-cut])
        recording = Recording(path)
        assert len(list(recording.frames())) == whole and not recording.truncated
        # Said, though (an engineer's trial: other MCAP tools want the end), with the way
        # to a whole file; a whole one says nothing.
        assert recording.end_lost
        summary = replay(Recording(path))
        assert summary.match and summary.warnings == [
            f"the file ends after its last frame, short of its end (its summary, footer or "
            f"closing bytes missing or unreadable: cut short there?): every frame is whole "
            f"and was replayed, but other MCAP tools may refuse it; vade-replay {path} -o "
            "WHOLE.mcap writes it again whole"]
    whole_file = Recording(RECORDINGS / "drop_on_table.mcap")
    assert len(list(whole_file.frames())) == whole and not whole_file.end_lost
    assert replay(whole_file).warnings == []
    path = tmp_path / "mid.mcap"
    path.write_bytes(golden[:len(golden) // 2])
    recording = Recording(path)
    assert len(list(recording.frames())) < whole and recording.truncated


def _records_at(data: bytes) -> list[tuple[int, int, int]]:
    """``(opcode, offset, length)`` of every record outside chunks, magic to footer."""
    import struct
    at, out = 8, []
    while at + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, at)
        out.append((opcode, at, length))
        if opcode == 0x02:  # Footer
            break
        at += 9 + length
    return out


def test_damage_that_still_parses_in_a_message_index_metadata_or_the_summary_is_said(
        tmp_path):
    """A replay reads neither the message indexes nor the summary, and metadata has no CRC
    of its own: one bit flipped in any of them parsed and replayed as a clean match, while
    other MCAP tools seek by the indexes (a gap the fourteenth session left). The data
    section's CRC (written since) and the summary's are checked: the replay still matches,
    exit 0, with a warning naming what is damaged and how to write the file again whole.
    A recording made before the data section's CRC was written has its summary checked."""
    from conftest import run_cli
    path = tmp_path / "whole.mcap"
    record(load(RECORDINGS / "drop_on_table.json"), path)
    whole = path.read_bytes()
    assert replay(Recording(path)).warnings == []
    records = _records_at(whole)
    first = {}
    for opcode, at, _ in records:
        first.setdefault(opcode, at)
    data_part = ("its data outside the frames and the stored session (a message index or "
                 "metadata)")
    summary_part = "its summary (the indexes and statistics other MCAP tools seek by)"
    for name, at, part in (
            ("index", first[0x07] + 9 + 2 + 4 + 3, data_part),  # a message's log time
            ("metadata", first[0x0C] + 9 + 4 + 3, data_part),  # a metadata record's name
            ("statistics", first[0x0B] + 9 + 3, summary_part),  # the message count
            ("chunk_index", first[0x08] + 9 + 3, summary_part)):  # a chunk's start time
        damaged = bytearray(whole)
        damaged[at] ^= 0x01
        broken = tmp_path / f"{name}.mcap"
        broken.write_bytes(bytes(damaged))
        summary = replay(Recording(broken))
        assert summary.match and summary.warnings == [
            f"the file is damaged: the CRC-32 of {part} does not match its bytes; every "
            "frame and the stored session are whole (their own CRCs match) and were "
            f"replayed, but other MCAP tools may read it wrong; vade-replay {broken} -o "
            "WHOLE.mcap writes it again whole"], name
    result = run_cli("vade-replay", str(tmp_path / "index.mcap"))
    assert result.returncode == 0 and "the CRC-32 of its data outside" in result.stderr
    # Written again whole, it is.
    again = tmp_path / "again.mcap"
    assert run_cli("vade-replay", str(tmp_path / "index.mcap"), "-o", str(again)).returncode == 0
    assert replay(Recording(again)).warnings == []
    # A recording from before the data section's CRC (or another tool's: the mcap
    # library's writer takes none by default): none taken (0), its summary's checked.
    from mcap_edit import copy_recording
    older = tmp_path / "older.mcap"
    copy_recording(path, older, lambda topic, index, data: data)
    golden = older.read_bytes()
    (data_end,) = [at for opcode, at, _ in _records_at(golden) if opcode == 0x0F]
    assert golden[data_end + 9:data_end + 13] == bytes(4)
    assert replay(Recording(older)).warnings == []
    inside = {0x07: 9 + 2 + 4 + 3, 0x0B: 9 + 3}  # an index entry's time, the count
    for opcode, at, _ in _records_at(golden):
        if opcode in inside:
            damaged = bytearray(golden)
            damaged[at + inside.pop(opcode)] ^= 0x01
            broken = tmp_path / "golden.mcap"
            broken.write_bytes(bytes(damaged))
            warned = replay(Recording(broken)).warnings
            assert (warned != []) == (opcode == 0x0B), opcode


def test_the_crc_checks_neither_crash_nor_misreport_at_the_file_s_edges(tmp_path):
    """A review: the footer's summary start damaged in its top byte crashed the check with
    a traceback (a seek past any file), and in another byte lost a mismatch already found;
    bytes after the closing magic (two recordings joined) were reported as a damaged
    summary, the footer taken at the file's end. Now: a summary start outside the file is
    the summary's damage (its CRC covers that field), and the footer is checked where it
    was read."""
    import struct
    path = tmp_path / "whole.mcap"
    record(load(RECORDINGS / "drop_on_table.json"), path)
    whole = path.read_bytes()
    (footer_at,) = [at for opcode, at, _ in _records_at(whole) if opcode == 0x02]
    for k in range(8):  # each byte of the footer's summary start
        damaged = bytearray(whole)
        damaged[footer_at + 9 + k] ^= 0x80
        broken = tmp_path / f"start{k}.mcap"
        broken.write_bytes(bytes(damaged))
        summary = replay(Recording(broken))
        assert summary.match and len(summary.warnings) == 1, (k, summary.warnings)
        assert "the CRC-32 of its summary" in summary.warnings[0], (k, summary.warnings)
    for tail in (b"\n", whole):  # a stray byte, or a second recording joined on
        joined = tmp_path / "joined.mcap"
        joined.write_bytes(whole + tail)
        assert not any("CRC-32" in w for w in replay(Recording(joined)).warnings), tail[:4]
    assert struct  # (the layout: opcode, length, summary start, summary offset start, CRC)


def test_a_recording_damaged_after_its_data_end_keeps_every_frame(tmp_path):
    """Damage past the data's end record (its summary or footer: a user's trial changed one
    byte there) leaves every frame whole: all are replayed, with a warning that names where
    the reading stopped, exit 0 (it was refused, as "damaged after 150 complete frames" of
    151). Damage before the data's end is still refused, naming the frames read before it."""
    import struct
    golden = (RECORDINGS / "drop_on_table.mcap").read_bytes()
    whole = len(list(Recording(RECORDINGS / "drop_on_table.mcap").frames()))
    at = 8
    while golden[at] != 0x0F:  # to the data's end record
        at += 9 + struct.unpack_from("<Q", golden, at + 1)[0]
    after = at + 9 + struct.unpack_from("<Q", golden, at + 1)[0]  # the summary's first record
    data = bytearray(golden)
    data[after + 1:after + 9] = struct.pack("<Q", 2**40)  # a length past any limit
    path = tmp_path / "summary.mcap"
    path.write_bytes(bytes(data))
    recording = Recording(path)
    assert len(list(recording.frames())) == whole and not recording.truncated
    assert recording.end_lost and recording.end_damaged == after + 9
    summary = replay(Recording(path))
    assert summary.match and summary.frames == whole
    assert summary.warnings == [
        f"the file is damaged after its last frame (its summary or footer: reading stopped "
        f"at byte {after + 9} of {len(golden)}): every frame is whole and was replayed, but "
        f"other MCAP tools may refuse it; vade-replay {path} -o WHOLE.mcap writes it again "
        "whole"]
    from conftest import run_cli
    result = run_cli("vade-replay", str(path))
    assert result.returncode == 0 and "damaged after its last frame" in result.stderr
    # The same damage in the data (its last chunk's length): refused, as before.
    last, chunk = 8, None
    while last < at:
        if golden[last] == 0x06:
            chunk = last
        last += 9 + struct.unpack_from("<Q", golden, last + 1)[0]
    data = bytearray(golden)
    data[chunk + 1:chunk + 9] = struct.pack("<Q", 2**40)
    path = tmp_path / "data.mcap"
    path.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(path))
    assert result.returncode == 2 and "complete frames: reading stopped at byte" in result.stderr
    assert "Traceback" not in result.stderr


def _writer_setup():
    from vade_replay.replay import simulate
    session = load(RECORDINGS / "drop_on_table.json")
    scene = session.build_scene()
    return session, scene, list(simulate(scene, session.tracker_frames()))[:20]


def test_a_run_that_opened_the_partial_file_as_another_finished_does_not_truncate_it(
        tmp_path, monkeypatch):
    """Run B opens OUT.partial; run A moves it to OUT and closes; B's lock then succeeds on
    A's finished file. B must see that the path no longer names it and open afresh, not
    truncate A's recording (a review forced this order: OUT went to 0 bytes)."""
    import os

    from vade_replay import recording as rec_module
    from vade_replay.recording import RecordingWriter
    session, scene, frames = _writer_setup()
    out, partial = tmp_path / "OUT.mcap", tmp_path / "OUT.mcap.partial"
    first = RecordingWriter(partial, session, scene)
    for frame in frames:
        first.write_frame(frame)
    real_open = os.open
    finished = []

    def open_then_let_the_other_finish(path, flags, mode=0o777):
        fd = real_open(path, flags, mode)
        if not finished:
            finished.append(True)
            first.close(complete_as=out)
        return fd
    monkeypatch.setattr(rec_module.os, "open", open_then_let_the_other_finish)
    second = RecordingWriter(partial, session, scene)
    monkeypatch.setattr(rec_module.os, "open", real_open)
    second.discard()
    assert len(list(Recording(out).frames())) == len(frames)
    assert not partial.exists()


def test_where_locks_are_refused_a_recording_is_written_unlocked(tmp_path, monkeypatch):
    """An NFS mount without lockd refuses flock (ENOLCK): written as before, not a
    traceback."""
    import errno

    from vade_replay import recording as rec_module
    from vade_replay.recording import RecordingWriter

    def no_locks(fd, op):
        raise OSError(errno.ENOLCK, "No locks available")
    monkeypatch.setattr(rec_module.fcntl, "flock", no_locks)
    session, scene, frames = _writer_setup()
    writer = RecordingWriter(tmp_path / "x.mcap.partial", session, scene)
    for frame in frames:
        writer.write_frame(frame)
    writer.close(complete_as=tmp_path / "x.mcap")
    assert len(list(Recording(tmp_path / "x.mcap").frames())) == len(frames)


def test_a_recording_s_warnings_known_before_its_first_frame_are_said_then(tmp_path):
    """(A user's trial: a session of 100,000 s, "meant less?", said so only when the run
    ended, and never when it was Ctrl-C'd.) The session's warnings come before the first
    frame, and the command prints each once."""
    from conftest import run_cli
    doc = json.loads((RECORDINGS / "drop_on_table.json").read_text())
    doc["tracker"]["duration_s"] = 100.0
    session_path = tmp_path / "long.json"
    session_path.write_text(json.dumps(doc))
    session = load(session_path)
    order = []
    summary = record(session, tmp_path / "a.mcap",
                     on_warnings=lambda warnings: order.append(("warnings", warnings)),
                     on_frame=lambda _: order.append("frame") if len(order) < 3 else None)
    assert order[0][0] == "warnings" and order[1:] == ["frame", "frame"]
    (warning,) = order[0][1]
    assert "meant less?" in warning and summary.warnings == [warning]
    result = run_cli("vade-record", str(session_path), "-o", str(tmp_path / "b.mcap"))
    assert result.returncode == 0 and result.stderr.count("meant less?") == 1
    assert result.stderr.startswith(f"warning: {session_path}: tracker.duration_s")


@pytest.mark.parametrize("later_damage", [False, True])
def test_a_chunk_damaged_into_a_data_end_is_damage_not_the_file_s_end(tmp_path, later_damage):
    """(A review: a chunk's opcode changed to the data's end record's made the frames after
    it vanish, a third of the recording replayed as a match without a word; with damage in
    a later chunk too, that damage was taken for the summary's, "every frame is whole".)
    Data after an end record is damage, held to the summary's count of frames: refused,
    exit 2, naming it."""
    import struct
    from conftest import run_cli
    golden = (RECORDINGS / "shaft_placed.mcap").read_bytes()
    chunks, at = [], 8
    while golden[at] != 0x0F:
        if golden[at] == 0x06:
            chunks.append(at)
        at += 9 + struct.unpack_from("<Q", golden, at + 1)[0]
    data = bytearray(golden)
    data[chunks[1]] = 0x0F  # a chunk in the middle read as the data's end
    if later_damage:
        data[chunks[2] + 100] ^= 0xFF
    path = tmp_path / "false_end.mcap"
    path.write_bytes(bytes(data))
    result = run_cli("vade-replay", str(path))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert ("a data-end record comes before the data's end (its summary counts 181 frames)"
            in result.stderr), result.stderr
    assert result.stderr.startswith(f"error: {path}: damaged after ")


def test_an_output_on_a_read_only_file_system_is_said_to_be_one(tmp_path, monkeypatch):
    """A researcher's trial: an output on a read-only mount read "permission denied", which
    sent them to chmod in vain. A read-only file system is said as one (the folder's
    statvfs flag); a folder that is only not writable stays "permission denied"."""
    import os
    import types
    from vade_replay.errors import VadeError
    from vade_replay.recording import ensure_writable
    monkeypatch.setattr(os, "access", lambda path, mode: False)
    with pytest.raises(VadeError, match="cannot write here: permission denied"):
        ensure_writable(tmp_path / "out.mcap", field="-o")
    monkeypatch.setattr(os, "statvfs", lambda path: types.SimpleNamespace(f_flag=os.ST_RDONLY))
    with pytest.raises(VadeError, match="cannot write here: a read-only file system"):
        ensure_writable(tmp_path / "out.mcap", field="-o")
