"""MCAP recordings; the only module that imports mcap.

A recording is an event log: the tracker inputs are the source of truth, everything else
is derived and checked by replay. It carries what it needs to be replayed anywhere: the
session file and every file it names as attachments, the physics and package versions as
metadata. Chunks are zstd-compressed and closed every simulated second, so a crash loses at
most the last second.
"""

from __future__ import annotations

import errno
import functools
import json
import os
import platform
import stat
import struct
import time
import zlib
from dataclasses import asdict, dataclass
from functools import cached_property
from importlib import metadata as importlib_metadata
from io import BytesIO
from pathlib import Path
from typing import Iterator

try:
    import fcntl
except ImportError:  # Windows: outputs are not locked
    fcntl = None  # type: ignore[assignment]

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, McapError, RecordLengthLimitExceeded
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (Attachment, AttachmentIndex, Channel, Chunk, ChunkIndex, DataEnd,
                          Footer, Header, Message, Metadata, MetadataIndex, Schema, Statistics,
                          SummaryOffset)
from mcap.stream_reader import StreamReader, get_chunk_data_stream, read_magic
from mcap.writer import CompressionType, Writer
from zstandard import ZstdError

from . import codec
from .errors import RecordingError
from .frames import FrameRecord, RecordedFrame
from .scene import Scene
from .session import MCAP_MAGIC, Session, load_schema, parse, validated_digest

PROFILE = "vade"
SESSION_ATTACHMENT = "session.json"
FILE_ATTACHMENT_PREFIX = "files/"
CHUNK_SECONDS_NS = 10**9
ENCODING_METADATA = "encoding"
# How a rerun review (.rrd) begins: what a review's place may hold, and what a review given
# for a recording is told it is.
RERUN_MAGIC = b"RRF"
# session.validated_digest of the attached session: a replay skips validating it again.
VALIDATED_METADATA = "validated"
# Written when a run stops before its end (an error, Ctrl-C): why, and how many frames.
STOPPED_METADATA = "stopped"
# What vade-record warned of, one entry a warning ("0", "1", ...): a replay tells it again.
WARNINGS_METADATA = "warnings"
# What a damaged file raises from mcap and its zstd chunks (a flipped byte in a compressed
# chunk is a ZstdError, not an McapError).
# What the mcap library raises on a damaged or cut file (OverflowError: a chunk's compression
# field damaged, its data then taken as raw bytes).
_READ_ERRORS = (McapError, ZstdError, OSError, EOFError, ValueError, struct.error, KeyError,
                OverflowError, MemoryError)
PACKAGES = ("vade_replay", "numpy", "trimesh", "python-fcl", "mcap", "rerun-sdk", "jsonschema",
            "orjson")


_RECORD_HEAD = struct.Struct("<BQ")      # opcode, length
_MESSAGE_HEAD = struct.Struct("<HIQQ")   # channel id, sequence, log time, publish time


def _chunk_records(chunk: Chunk) -> Iterator[Channel | tuple[int, bytes]]:
    """The channels of a chunk and its messages, as ``(channel id, data)``.

    The mcap library decompresses the chunk and checks its CRC (a damaged chunk is then
    an error, not a replay that diverges), and reads its channels. Messages, nearly every
    record, are cut out here with one ``struct`` call each: the library's ``breakup_chunk``
    reads them field by field in Python, ~4 us a message, three a frame.
    The layout is MCAP's Message record: opcode 0x05, u64 length, u16 channel id, u32
    sequence, u64 log time, u64 publish time, then the data to the end of the record.
    """
    try:
        stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    except RuntimeError as exc:  # lz4 (when installed) reports damage so
        raise McapError(f"the chunk cannot be decompressed ({exc})") from None
    data = stream.read(size)
    at = 0
    while at < size:
        opcode, length = _RECORD_HEAD.unpack_from(data, at)
        start = at + _RECORD_HEAD.size
        at = start + length
        if at > size:
            raise McapError(f"a record in a chunk runs {at - size} bytes past its end")
        if opcode == Opcode.MESSAGE:
            if length < _MESSAGE_HEAD.size:
                raise McapError(f"a message record of {length} bytes")
            yield _MESSAGE_HEAD.unpack_from(data, start)[0], \
                data[start + _MESSAGE_HEAD.size:at]
        elif opcode == Opcode.CHANNEL:
            try:
                channel = Channel.read(ReadDataStream(BytesIO(data[start:at])))
            except EndOfFile:  # inside a chunk that is damage, not a file cut short
                raise McapError("a channel record in a chunk is cut short") from None
            yield channel
        # Schemas and any record type this version does not know: skipped, as MCAP says.


class DamagedAttachment(McapError):
    """An attachment whose bytes are not those its CRC-32 was taken of."""

    def __init__(self, name: str) -> None:
        super().__init__(f"attachment {name!r} is damaged: its CRC-32 does not match its bytes")
        self.name = name


def _checked_attachment(stream: ReadDataStream) -> Attachment:
    """An attachment read as the mcap library's ``Attachment.read`` reads it (the same
    bytes), with its CRC-32 checked, which the library skips: the session and files stored
    in a recording are what a replay re-runs, so damage there is an unusable file, not a
    replay that diverges (a user's trial: one byte of a stored friction changed was
    reported as a divergence at frame 112). A CRC of 0 means none was taken (MCAP)."""
    def piece(n: int) -> bytes:
        data = stream.read(n)
        if len(data) < n:
            raise EndOfFile()
        return data
    times = piece(16)  # log time, create time
    name_size = piece(4)
    name = piece(struct.unpack("<I", name_size)[0])
    media_size = piece(4)
    media_type = piece(struct.unpack("<I", media_size)[0])
    data_size = piece(8)
    data = piece(struct.unpack("<Q", data_size)[0])
    crc = struct.unpack("<I", piece(4))[0]
    if crc != 0:
        computed = 0
        for part in (times, name_size, name, media_size, media_type, data_size, data):
            computed = zlib.crc32(part, computed)
        if computed != crc:
            raise DamagedAttachment(str(name, "utf-8", errors="replace"))
    log_time, create_time = struct.unpack("<QQ", times)
    return Attachment(create_time=create_time, log_time=log_time, name=str(name, "utf-8"),
                      media_type=str(media_type, "utf-8"), data=data)


# Every record outside chunks is read by the mcap library, as its StreamReader reads it
# (so damage anywhere in the file is found as it was), but for the message indexes and the
# attachments' CRCs.
_READ_OUTSIDE_CHUNKS = {
    Opcode.ATTACHMENT: _checked_attachment, Opcode.ATTACHMENT_INDEX: AttachmentIndex.read,
    Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read,
    Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.DATA_END: DataEnd.read,
    Opcode.FOOTER: Footer.read, Opcode.HEADER: Header.read, Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read, Opcode.SCHEMA: Schema.read,
    Opcode.STATISTICS: Statistics.read, Opcode.SUMMARY_OFFSET: SummaryOffset.read}
_YIELDED = (Header, Attachment, Chunk, Channel, Message, Metadata, DataEnd, Footer)
_RECORD_SIZE_LIMIT = 4 * 2**30  # StreamReader's default: a larger record is damage
_INDEX_HEAD = struct.Struct("<HI")  # a message index: channel id, byte length of entries


def _records(stream) -> Iterator[Header | Attachment | Chunk | Channel | Message | Metadata
                                   | DataEnd | Footer]:
    """The header, attachments, chunks, channels, unchunked messages, metadata, data end and
    footer of an MCAP stream, in order: ``StreamReader(stream, emit_chunks=True).records``
    less the records a replay does not use, read as the library reads them but for the
    attachments' CRCs (checked, ``_checked_attachment``) and the message indexes (one a
    channel and chunk, with an entry for every message, which the library reads eight
    bytes at a time: ~3 us a frame, a quarter of a read-and-decode). An index's entries
    are read as one block of the length its head gives, so a damaged file reads on from
    the same byte as with the library (a chunk whose opcode became an index's is damage
    found at the next record, not a chunk passed over). A file cut short ends in
    ``EndOfFile``; damage is what the library's reading of a record raises."""
    data = ReadDataStream(stream)
    read_magic(data)
    while True:
        opcode = data.read1()
        length = data.read8()
        if length > _RECORD_SIZE_LIMIT:
            raise RecordLengthLimitExceeded(opcode, length, _RECORD_SIZE_LIMIT)
        if opcode == Opcode.MESSAGE_INDEX:
            # As MessageIndex.read reads it, its entries taken as one block: the same bytes
            # consumed (past the record's end too, where a damaged head says so).
            count = data.count
            head = data.read(_INDEX_HEAD.size)
            if len(head) < _INDEX_HEAD.size:
                raise EndOfFile()
            _, size = _INDEX_HEAD.unpack(head)
            entries = -(-size // 16) * 16
            if entries and len(data.read(entries)) < entries:
                raise EndOfFile()
            padding = length - (data.count - count)
            if padding > 0:
                data.read(padding)
            continue
        read = _READ_OUTSIDE_CHUNKS.get(opcode)
        if read is None and opcode != Opcode.MESSAGE:
            data.read(length)  # a record type this version does not know: as MCAP says
            continue
        count = data.count
        record = Message.read(data, length) if read is None else read(data)
        padding = length - (data.count - count)
        if padding > 0:
            data.read(padding)
        if opcode == Opcode.DATA_END or opcode == Opcode.FOOTER:
            # Where it begins, for the CRC checks (``_crc_mismatches``): not where a whole
            # file's would be, in a file with bytes after its end (a review).
            record._at = count - _RECORD_HEAD.size  # type: ignore[union-attr]
        if isinstance(record, _YIELDED):
            yield record
        if opcode == Opcode.FOOTER:
            read_magic(data)
            return


def _messages(stream, after_end: list[bool] | None = None
              ) -> Iterator[Channel | tuple[int, bytes] | DataEnd | Footer]:
    """Channels, messages as ``(channel id, data)``, and the records that end the file:
    the records of a recording that replay reads, in order, chunk by chunk. ``after_end``
    (one flag) is set where data (a chunk, a message, metadata, another end) comes after
    the data's end record: that end was damage (``Recording.frames`` then holds the frames
    read to the summary's count)."""
    ended = False
    for record in _records(stream):
        if ended and after_end is not None \
                and isinstance(record, (Chunk, Message, Metadata, DataEnd)):
            after_end[0] = True
        ended = ended or isinstance(record, DataEnd)
        if isinstance(record, Chunk):
            yield from _chunk_records(record)
        elif isinstance(record, Message):  # a file written without chunks
            yield record.channel_id, record.data
        elif isinstance(record, (Channel, Metadata, DataEnd, Footer)):
            yield record


def physics_metadata(physics) -> dict[str, str]:
    """The physics a recording is made with, as its metadata holds it: every field (JSON
    text), and the sub-steps on the base in effect (``turn_step_s``, ``slide_step_s``: a
    field left at None takes a default that a later version may change)."""
    out = {k: json.dumps(v) for k, v in asdict(physics).items()}
    out["turn_step_s"] = json.dumps(physics.turn_step_s)
    out["slide_step_s"] = json.dumps(physics.slide_step_s)
    return out


def _cpu() -> str:
    """The processor's model name (on Linux from /proc/cpuinfo), to tell machines apart."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def package_versions() -> dict[str, str]:
    """Where a recording was made: the versions of Python and the packages, and the machine
    (system, architecture, C library, processor), whose libm and compilers decide round-off
    (``replay.made_elsewhere``). Found once a process (2-3 ms: the packages' metadata)."""
    return dict(_versions())


@functools.lru_cache(maxsize=1)
def _versions() -> dict[str, str]:
    out = {"python": platform.python_version(), "platform": platform.platform(),
           "system": platform.system(), "machine": platform.machine(),
           "libc": " ".join(part for part in platform.libc_ver() if part) or "unknown",
           "cpu": _cpu()}
    for name in PACKAGES:
        try:
            out[name] = importlib_metadata.version(name)
        except importlib_metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def ensure_writable(path: str | Path, field: str | None = None) -> Path:
    """Check that an output file can be written (creating its folder) before any work;
    ``field``, the option that names it, is named in the error."""
    path = Path(path)
    if path.is_dir():
        raise RecordingError("is a folder; give a file name to write", file=str(path),
                             field=field)
    for folder in path.parents:
        if folder.exists():
            if not folder.is_dir():
                raise RecordingError(f"{folder} is a file, not a folder", file=str(path),
                                     field=field)
            break
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f"cannot create its folder: {exc.strerror}", file=str(path),
                             field=field) from None
    if not os.access(path.parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise RecordingError(f"cannot write here: {_why_unwritable(path.parent)}",
                             file=str(path), field=field)
    return path


def _why_unwritable(folder: Path) -> str:
    """A read-only file system (a mounted archive, a study's copy on read-only media) is
    said as one: "permission denied" sent a researcher's trial to chmod, in vain."""
    try:
        if os.statvfs(folder).f_flag & os.ST_RDONLY:
            return "a read-only file system"
    except (OSError, AttributeError):  # (no statvfs on Windows)
        pass
    return "permission denied"


def in_place(path: Path) -> bool:
    """Whether an output is written where it is rather than beside it and moved there: a
    pipe, a device, anything not a regular file (or under /dev or /proc, where a path may
    stand for this process's own output)."""
    if str(path.absolute()).startswith(("/dev/", "/proc/")):
        return True
    try:
        return not stat.S_ISREG(os.stat(path).st_mode)
    except FileNotFoundError:
        return False
    except OSError:
        return False


def partial_output(out: str | Path) -> tuple[Path, Path | None]:
    """Where a recording meant for ``out`` is written: ``(file to write, file it becomes)``.
    A regular file (or a new one) is written as ``NAME.partial`` beside the file (beside
    the file a link points to) and becomes it when complete (``complete_output``); a pipe
    or a device is written in place (``(out, None)``)."""
    out = ensure_writable(out)
    if in_place(out):
        return out, None
    target = out.resolve()
    return ensure_writable(target.with_name(target.name + ".partial")), target


def left_partial(out: str | Path) -> Path | None:
    """The ``.partial`` file a run to ``out`` would write over, where one is there with
    something in it and no run is writing it now (it is locked while written): the frames
    an interrupted run kept (``vade-record`` says so as it stops), which may exist nowhere
    else. None for a pipe or device, or where there is none."""
    out = Path(out)
    if in_place(out):
        return None
    target = out.resolve()
    partial = target.with_name(target.name + ".partial")
    try:
        found = os.stat(partial)
        if not stat.S_ISREG(found.st_mode) or found.st_size == 0:
            return None
        try:
            fd = os.open(partial, os.O_RDONLY)
        except PermissionError:
            fd = os.open(partial, os.O_WRONLY)  # (one we may write but not read)
    except OSError:
        return None
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return None  # a run is writing it: its own open says so
            except OSError:
                pass  # locks not supported here
        return partial
    finally:
        os.close(fd)  # (and the lock with it)


def holds_recording(path: Path) -> bool | None:
    """Whether a file begins as a recording does (MCAP's magic); None where it cannot be
    read."""
    try:
        with open(path, "rb") as stream:
            return stream.read(8) == MCAP_MAGIC + b"0\r\n"
    except OSError:
        return None


def complete_output(partial: Path, target: Path | None) -> None:
    """Move a complete ``partial`` over its ``target`` (keeping the mode of a file there)."""
    if target is None:
        return
    try:
        if target.exists():
            os.chmod(partial, stat.S_IMODE(os.stat(target).st_mode))
        os.replace(partial, target)
    except OSError as exc:
        raise RecordingError(f"cannot finish writing it ({exc.strerror or exc}); what was "
                             f"written is in {partial}", file=str(target)) from None


_PIPE_REFUSED = ("cannot write a recording to a pipe: an MCAP file is written with offsets "
                 "into it; give a file")


def _open_alone(path: Path):
    """``open(path, "wb")``, but a regular file is first locked (fcntl), without truncating
    it: a second run writing the same ``.partial`` (two ``vade-record -o X`` at once) is
    refused, naming the file, instead of each truncating and interleaving the other's
    records. Locked, the file must still be the one at ``path`` (another run may have
    moved it to its output between the open and the lock: then it is opened again). A pipe
    or device is not locked, nor anything where fcntl is missing (Windows) or the file
    system refuses locks (an NFS mount without lockd). The lock goes with the closing."""
    try:
        if stat.S_ISFIFO(os.stat(path).st_mode):
            # (Opened, a pipe with no reader blocks: a user's trial waited on it for ever.)
            raise RecordingError(_PIPE_REFUSED, file=str(path))
    except OSError:
        pass  # none there yet (or not to be asked): opened below, as any other
    for _ in range(100):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT, 0o666)
        except OSError as exc:
            raise RecordingError(f"cannot write here: {exc.strerror or exc}",
                                 file=str(path)) from None
        try:
            if fcntl is not None and stat.S_ISREG(os.fstat(fd).st_mode):
                try:
                    _lock_soon(fd)
                except BlockingIOError:
                    raise RecordingError(
                        "another run is writing this file now (two runs with the same "
                        "output?); wait for it to finish or give another output",
                        file=str(path)) from None
                except OSError:
                    pass  # locks not supported here: written unlocked, as before
                else:
                    if not _names(path, fd):
                        os.close(fd)
                        continue  # moved away while we waited: open what is there now
                os.ftruncate(fd, 0)
            return open(fd, "wb", closefd=True)
        except BaseException:
            os.close(fd)
            raise
    raise RecordingError("cannot lock this file: it keeps being replaced", file=str(path))


# How long a writer waits for a lock held for a moment: ``left_partial``'s shared lock,
# taken and let go to see whether a run is writing a ``.partial``, made a run starting in
# that moment report "another run is writing". A run writing holds it for the whole run.
_LOCK_WAIT_S = 0.2
_LOCK_POLL_S = 0.005


def _lock_soon(fd: int) -> None:
    """``flock(fd, LOCK_EX)``, waiting up to ``_LOCK_WAIT_S`` for a lock held a moment;
    ``BlockingIOError`` where it is still held then."""
    deadline = time.monotonic() + _LOCK_WAIT_S
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() >= deadline:
                raise
            time.sleep(_LOCK_POLL_S)


def _names(path: Path, fd: int) -> bool:
    """Whether ``path`` is still the file open as ``fd``."""
    try:
        here, there = os.stat(path), os.fstat(fd)
    except OSError:
        return False
    return (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino)


def _unwritable(exc: OSError, path: Path) -> RecordingError:
    """A recording that cannot be written on (a full disk, a device that takes nothing)."""
    return RecordingError(f"cannot write it: {exc.strerror or exc}", file=str(path))


class RecordingWriter:
    """Writes one session: attachments and metadata first, then frame after frame."""

    def __init__(self, path: str | Path, session: Session, scene: Scene, *,
                 extra_metadata: dict[str, str] | None = None,
                 parts_encoding: str = codec.PARTS_CHANGED) -> None:
        self.path = Path(path)
        self._stream = _open_alone(self.path)
        try:
            self._stream.tell()  # the MCAP writer keeps offsets: a pipe has none
        except OSError:
            self._stream.close()
            raise RecordingError(_PIPE_REFUSED, file=str(self.path)) from None
        # The data section's CRC too (the library leaves it out by default): what the
        # chunks' and attachments' own CRCs leave, the message indexes and the metadata, is
        # then checked by a replay (``Recording.crc_mismatches``).
        try:
            self._writer = Writer(self._stream, compression=CompressionType.ZSTD,
                                  chunk_size=4 * 1024 * 1024, enable_data_crcs=True)
            self._writer.start(profile=PROFILE,
                               library=f"vade_replay {package_versions()['vade_replay']}")
            self._channels: dict[str, int] = {}
            for topic, (schema_name, schema_file) in codec.CHANNELS.items():
                schema_id = self._writer.register_schema(
                    name=schema_name, encoding="jsonschema",
                    data=json.dumps(load_schema(schema_file)).encode())
                self._channels[topic] = self._writer.register_channel(
                    topic=topic, message_encoding="json", schema_id=schema_id)
            self._writer.add_attachment(0, 0, SESSION_ATTACHMENT, "application/json",
                                        session.raw)
            for name in sorted(session.files):
                self._writer.add_attachment(0, 0, FILE_ATTACHMENT_PREFIX + name,
                                            "application/octet-stream", session.files[name])
            self._writer.add_metadata("versions", package_versions())
            self._writer.add_metadata("physics", physics_metadata(scene.physics))
            self._writer.add_metadata("session", {"name": session.name,
                                                  **(extra_metadata or {})})
            # What the run warns of, kept at the end (``close``) for a replay to tell again.
            self.warnings: list[str] = []
            # How /parts and the transforms are written (codec.derived_messages): a file
            # without this record is from before the ``changed`` encoding and lists every
            # part.
            self._writer.add_metadata(ENCODING_METADATA, {"parts": parts_encoding})
            self._writer.add_metadata(VALIDATED_METADATA,
                                      {"session": validated_digest(session.raw)})
        except OSError as exc:
            # (A user's trial: a full disk gave a traceback and exit 1, "diverged".) No
            # frame is in it: a file of its own is removed, as ``discard`` does.
            if stat.S_ISREG(os.fstat(self._stream.fileno()).st_mode):
                self.path.unlink(missing_ok=True)
            self._close_after_failure()
            raise _unwritable(exc, self.path) from None
        self._encoder = codec.FrameEncoder(parts_encoding)
        self._sequence = 0
        self._last_flush_ns: int | None = None
        self.frames = 0
        # A write failed (a full disk): frames counted here may be missing from the file,
        # which has no summary (a replay reads it as cut short).
        self.unfinished = False

    def _add(self, topic: str, time_ns: int, data: bytes) -> None:
        self._writer.add_message(self._channels[topic], log_time=time_ns, data=data,
                                 publish_time=time_ns, sequence=self._sequence)
        self._sequence += 1

    def write_frame(self, record: FrameRecord,
                    derived: list[tuple[str, bytes]] | None = None) -> None:
        """Write a frame's tracker input and its derived messages."""
        t = record.time_ns
        try:
            self._add(codec.TRACKER_TOPIC, t, codec.tracker_message(record.inputs))
            if derived is None:
                derived = self._encoder.derived_messages(record)
            for topic, data in derived:
                self._add(topic, t, data)
            self.frames += 1
            if self._last_flush_ns is None:
                self._last_flush_ns = t
            elif t - self._last_flush_ns >= CHUNK_SECONDS_NS:
                self._writer.flush()
                self._last_flush_ns = t
        except OSError as exc:
            self.unfinished = True
            raise _unwritable(exc, self.path) from None

    def close(self, *, complete_as: Path | None = None, stopped: str | None = None) -> None:
        """Write the summary and close; a closed file is complete and indexed. With
        ``complete_as`` (``partial_output``'s target) it is moved there first, while it is
        still open and locked: no other run can begin writing the partial name between.
        ``stopped``: why the run ended before its end (kept as metadata: a reader then
        knows the file holds fewer frames than the session, ``Recording.truncated``)."""
        if self._stream.closed:
            return
        try:
            try:
                if self.warnings:
                    self._writer.add_metadata(WARNINGS_METADATA, {
                        str(k): text for k, text in enumerate(self.warnings)})
                if stopped is not None:
                    self._writer.add_metadata(STOPPED_METADATA, {
                        "reason": stopped, "frames": str(self.frames)})
                self._writer.finish()
                self._stream.flush()
                try:
                    os.fsync(self._stream.fileno())
                except OSError as exc:
                    if exc.errno not in (errno.EINVAL, errno.EROFS):  # a pipe, a device
                        raise
            except OSError as exc:
                raise self._cannot_finish(exc) from None
            if fcntl is None:  # not locked; and Windows cannot move an open file
                self._stream.close()
            complete_output(self.path, complete_as)
        except BaseException:
            self._close_after_failure()
            raise
        try:
            self._stream.close()
        except OSError as exc:
            raise self._cannot_finish(exc) from None

    def _cannot_finish(self, exc: OSError) -> RecordingError:
        """The file's end could not be written (a full disk): it replays as cut short."""
        self.unfinished = True
        return RecordingError(f"cannot finish writing it: {exc.strerror or exc}",
                              file=str(self.path))

    def _close_after_failure(self) -> None:
        """Close the file where writing it failed: what the buffer still holds is lost (a
        full disk fails its flush again), the file descriptor is not."""
        try:
            self._stream.close()
        except OSError:
            self.unfinished = True

    def discard(self) -> None:
        """Close and remove a file that holds no frame, removed while still locked (no run
        that began writing it meanwhile loses its file)."""
        try:
            self.path.unlink(missing_ok=True)
        finally:
            self.close()

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Recording:
    """A recording opened for reading: session from attachments, metadata, frame stream.

    It is read as a stream of records, never through the summary at the end of the file, so
    a recording cut short by a crash still opens: its frames up to the last complete chunk
    are read, and ``truncated`` says that the end was missing.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if self.path.is_dir():
            raise RecordingError("is a folder, not a recording (give its recordings: "
                                 f"{self.path}/*.mcap)", file=str(self.path))
        if not self.path.is_file():
            # (A user's trial: /dev/null and a named pipe, which exist, read "no such file".)
            raise RecordingError("not a file (a device or a pipe): a recording is read from "
                                 "its file" if self.path.exists() else "no such file",
                                 file=str(self.path))
        self.profile = None
        self.truncated = False
        # Cut after its data's end: every frame whole, its summary and footer lost (other
        # MCAP tools want them), read with the frames.
        self.end_lost = False
        # And where it is not cut there but damaged: the byte its reading stopped at.
        self.end_damaged: int | None = None
        # Read whole, the parts whose CRC does not match their bytes though they parse (its
        # data section outside the chunks and attachments, its summary; ``_crc_mismatches``).
        self.crc_mismatches: list[str] = []
        # Why the run that wrote it stopped before its end, if it did (``STOPPED_METADATA``).
        self.stopped: str | None = None
        # What vade-record warned of when it made it (``WARNINGS_METADATA``), read with the
        # frames (it is kept at the file's end).
        self.warnings: list[str] = []
        self.metadata: dict[str, dict[str, str]] = {}
        attachments: dict[str, bytes] = {}
        try:
            with open(self.path, "rb") as stream:
                # Chunks are not opened: the writer puts attachments and metadata before
                # any chunk, so the first one ends the head (its schemas and channels are
                # read by frames()). Opening it here cost a whole chunk's decompression.
                for record in _records(stream):
                    if isinstance(record, Header):
                        self.profile = record.profile
                    elif isinstance(record, Attachment):
                        attachments[record.name] = record.data
                    elif isinstance(record, Metadata):
                        self.metadata[record.name] = dict(record.metadata)
                    elif isinstance(record, (Chunk, Message)):
                        break  # schemas and channels before it may precede attachments
        except DamagedAttachment as exc:
            # (Its name may be what is damaged: a review read "file 's\ufffdssion.json'".)
            what = "session" if exc.name == SESSION_ATTACHMENT else \
                f"file {exc.name.removeprefix(FILE_ATTACHMENT_PREFIX)!r}" \
                if exc.name.startswith(FILE_ATTACHMENT_PREFIX) \
                else f"attachment whose name reads {exc.name!r} (the session or a file)"
            raise RecordingError(f"the {what} stored in it is damaged (its CRC-32 does not "
                                 "match its bytes): it cannot be replayed; record the "
                                 "session again, or replay a copy", file=str(self.path),
                                 field=f"attachment {exc.name}") from None
        except _READ_ERRORS as exc:
            raise RecordingError(self._unreadable(exc), file=str(self.path)) from None
        if self.profile != PROFILE or SESSION_ATTACHMENT not in attachments:
            raise RecordingError("not a vade_replay recording (no session attachment)",
                                 file=str(self.path))
        files = {name[len(FILE_ATTACHMENT_PREFIX):]: data for name, data in attachments.items()
                 if name.startswith(FILE_ATTACHMENT_PREFIX)}
        self.session = parse(attachments[SESSION_ATTACHMENT], files,
                             source=f"{self.path}:{SESSION_ATTACHMENT}",
                             validated=self.metadata.get(VALIDATED_METADATA, {}).get("session"))
        self.parts_encoding = self.metadata.get(ENCODING_METADATA, {}).get(
            "parts", codec.PARTS_FULL)
        if self.parts_encoding not in codec.PARTS_ENCODINGS:
            # (A byte of it damaged reads as a name no version wrote: a user's trial.)
            raise RecordingError(f"unknown parts encoding {self.parts_encoding!r}: damaged, or "
                                 "written by a newer version (this version reads "
                                 f"{', '.join(codec.PARTS_ENCODINGS)})",
                                 file=str(self.path), field="metadata encoding.parts")

    def _ends_as_written(self) -> bool:
        """Whether the file ends in MCAP's closing magic (a closed file not cut short), after
        more than the opening magic and a record's head (a file cut just after its opening
        magic ends in the same bytes)."""
        try:
            with open(self.path, "rb") as stream:
                if stream.seek(0, os.SEEK_END) <= 8 + 9 + 8:
                    return False
                stream.seek(-8, os.SEEK_END)
                return stream.read(8) == MCAP_MAGIC + b"0\r\n"
        except OSError:
            return False

    def _unreadable(self, exc: BaseException) -> str:
        """Why the head of the file cannot be read, in a user's terms."""
        try:
            with open(self.path, "rb") as stream:
                first = stream.read(64)
        except OSError as error:
            return f"cannot read it: {error.strerror or error}"
        if not first:
            return "an empty file, not a recording"
        if first.removeprefix(b"\xef\xbb\xbf").lstrip()[:1] in (b"{", b"["):
            return ("not a recording: this looks like a session file (JSON); record it with "
                    "vade-record first")
        if first.startswith(RERUN_MAGIC):
            return ("not a recording: this is a rerun review (vade-replay --rerun writes "
                    "them); open it with `rerun`")
        if not (first.startswith(MCAP_MAGIC) or MCAP_MAGIC.startswith(first)):
            return "not an MCAP file (it does not begin with MCAP's magic bytes)"
        size = self.path.stat().st_size
        # Whole to its closing magic: a length near its start is damaged, reading on past
        # the end (a user's trial was told the file was cut short), or too large to read at
        # all (a review: "MemoryError").
        whole = self._ends_as_written()
        if isinstance(exc, (EndOfFile, EOFError, struct.error)):
            # (The reader's own words, "unpack requires a buffer of 8 bytes", say nothing.)
            if whole:
                return (f"damaged near its start: a record there claims more bytes than "
                        f"the file's {size} hold (the file itself ends as a whole recording "
                        "does, so it is not cut short)")
            return (f"cut short before its first frame: no complete frame to replay (the "
                    f"file holds only {size} byte{'s' if size != 1 else ''})")
        if whole and isinstance(exc, (MemoryError, OverflowError, RecordLengthLimitExceeded)):
            return (f"damaged near its start: a record there claims a length no file of "
                    f"{size} bytes has ({str(exc) or type(exc).__name__})")
        if whole:
            # (A user's trial of one flipped bit a file: a record's text that is no longer
            # UTF-8 read "not a readable MCAP file", where every other damage says damaged.)
            return (f"damaged near its start: a record there cannot be read "
                    f"({str(exc) or type(exc).__name__}; the file itself ends as a whole "
                    "recording does)")
        return f"not a readable MCAP file ({str(exc) or type(exc).__name__})"

    @cached_property
    def frame_count(self) -> int | None:
        """Frames = tracker messages, from the summary when the file was closed properly.
        Read when first asked (a progress bar asks): the summary is at the file's end, and
        a replay does not need it (0.3 ms of a short golden's 2 ms read)."""
        try:
            with open(self.path, "rb") as stream:
                summary = make_reader(stream).get_summary()
        except _READ_ERRORS:
            return None
        if not summary or not summary.statistics:
            return None
        for channel_id, channel in summary.channels.items():
            if channel.topic == codec.TRACKER_TOPIC:
                return summary.statistics.channel_message_counts.get(channel_id)
        return None

    def _false_end(self, count: int) -> RecordingError:
        """The error of a data-end record before the data's end (damage), ``count`` frames
        read whole before it."""
        counted = self.frame_count
        return RecordingError(
            f"damaged after {count} complete frames: a data-end record comes before the "
            "data's end" + (f" (its summary counts {counted} frames)"
                            if counted is not None else ""), file=str(self.path))

    def frames(self) -> Iterator[RecordedFrame]:
        """Frames in the order written, streaming chunk by chunk."""
        topics: dict[int, str] = {}
        ends = [False, False]  # a data end or footer read (complete), a footer read
        pending: list[RecordedFrame] = []  # the frame being read (codec.recorded_frames)

        closing: list = []  # the data end and footer records read (``_crc_mismatches``)

        def other(record) -> None:  # what is not a message: kept, or a note of the end
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Metadata):
                if record.name == STOPPED_METADATA:
                    self.stopped = record.metadata.get("reason", "stopped")
                elif record.name == WARNINGS_METADATA:
                    self.warnings = [record.metadata[k] for k in sorted(
                        record.metadata, key=lambda k: int(k) if k.isdigit() else 1 << 30)]
            else:  # DataEnd, Footer
                closing.append(record)
                ends[0] = True
                ends[1] = ends[1] or isinstance(record, Footer)

        complete = False
        count = 0
        after_end = [False]  # data after the data's end record (``_messages``)
        try:
            with open(self.path, "rb") as stream:
                size = os.fstat(stream.fileno()).st_size
                try:
                    # The grouping of messages into frames compiled (``codec``): ~0.6 us a
                    # frame less than this loop over every message.
                    for frame in codec.recorded_frames(_messages(stream, after_end), topics,
                                                       other, pending):
                        yield frame
                        count += 1
                    complete = ends[0]
                except RecordingError as exc:
                    if exc.file is not None:
                        raise
                    if after_end[0]:
                        # Past a data-end record that is damage (a chunk's opcode): what
                        # follows is misread for that, not for itself (a gap in the frames).
                        raise self._false_end(count) from None
                    raise RecordingError(exc.message, file=str(self.path), field=exc.field,
                                         frame=exc.frame) from None
                except _READ_ERRORS as exc:
                    at = stream.tell()
                    if ends[0] and at < size and not isinstance(exc, (EndOfFile, EOFError)):
                        # Past its data's end record: every frame is whole, only its
                        # summary or footer is damaged (a user's trial: one byte changed
                        # there refused the whole file, as "damaged after 180 complete
                        # frames" of its 181). Replayed, and said (``end_damaged``).
                        self.end_damaged = at
                        complete = False
                    elif not (isinstance(exc, (EndOfFile, EOFError)) or at >= size):
                        # Damaged, not cut short: the reader stopped inside the file.
                        detail = str(exc) or type(exc).__name__
                        # (A newcomer read "the data before byte N cannot be read" as
                        # all of it lost, though the frames before it were read.)
                        raise RecordingError(
                            f"damaged after {count} complete frames: reading stopped at byte "
                            f"{at} of {size}, at a damaged chunk ({detail}); the frames "
                            "before it were read",
                            file=str(self.path)) from None
                    complete = False  # cut short (a crash while recording)
        except OSError:
            complete = False
        data_end, footer = ends
        if not complete and not data_end and self._ends_as_written():
            # Its data ends short, but the file is whole to its closing magic: a length
            # damaged, read on past the end, not a file cut short (a review: a chunk's
            # length so replayed 120 of 151 frames as a crash's, and said "match").
            raise RecordingError(
                f"damaged after {count} complete frames: a record there claims more bytes "
                f"than the file's {size} hold (the file itself ends as a whole recording "
                "does, so it is not cut short)", file=str(self.path))
        if not complete and not data_end:
            # Cut short in its data: the last frame read may lack some of its messages; drop
            # it. (Cut after the data's end record, only the index is lost: every frame is
            # whole, and the recording is not short of any.)
            self.truncated = True
            return
        self.end_lost = not (footer and complete)  # (complete: read to its closing magic)
        if not self.end_lost:
            self.crc_mismatches = _crc_mismatches(self.path, closing)
        if after_end[0] or self.end_damaged is not None:
            # An end record before the data's end (a chunk's opcode damaged into one), or
            # damage after it: held to the summary's count of frames where it can be read
            # (a review: a chunk read as the end replayed a third of the frames as a match,
            # and with damage further on took that for the summary's, "every frame whole").
            read = count + len(pending)
            counted = self.frame_count
            if (counted is not None and counted > read) or (counted is None and after_end[0]):
                raise self._false_end(count)
        if pending:
            yield pending[0]
        if self.stopped is not None:
            self.truncated = True  # closed properly, but short of its session's end


_FOOTER_TAIL = 1 + 8 + 8 + 8 + 4 + 8  # a footer record (opcode, length, three fields), magic
_DATA_END_HEAD = struct.pack("<BQ", Opcode.DATA_END, 4)
_CRC_BLOCK = 1 << 20


def _crc_mismatches(path: Path, closing: list) -> list[str]:
    """The parts of a whole recording (read to its footer and closing magic) whose CRC-32,
    as its data end and footer records give it, does not match their bytes: its data
    section (from the file's start to the data end record: what the chunks' and
    attachments' own CRCs leave is its message indexes and metadata) and its summary (the
    indexes and statistics other MCAP tools seek by, with the footer's first fields). A
    replay reads neither the message indexes nor the summary, so damage there that still
    parses went unnoticed (a damaged golden read by another tool). A CRC of 0 is none
    taken (MCAP; recordings before this version have none of the data section). The two
    records are found where they were read (``_records``), else where a whole file has
    them. A footer whose summary start lies outside the file is damage to the summary's
    CRC too (it covers that field). Read in blocks, so memory stays flat; ~1 ms a
    megabyte."""
    data_end = next((r for r in closing if isinstance(r, DataEnd)), None)
    footer = next((r for r in closing if isinstance(r, Footer)), None)
    if footer is None:
        return []
    summary = "its summary (the indexes and statistics other MCAP tools seek by)"
    out: list[str] = []
    try:
        with open(path, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            footer_at = getattr(footer, "_at", size - _FOOTER_TAIL)
            summary_start = footer.summary_start
            if not 0 <= footer_at <= size or not 0 <= summary_start <= footer_at:
                return [summary] if footer.summary_crc else []
            end_at = getattr(data_end, "_at", None)
            if end_at is None:  # (where a whole file has it: just before the summary)
                end_at = (summary_start or footer_at) - len(_DATA_END_HEAD) - 4

            def crc(start: int, stop: int, value: int = 0) -> int:
                stream.seek(start)
                while start < stop:
                    block = stream.read(min(_CRC_BLOCK, stop - start))
                    if not block:
                        break
                    value = zlib.crc32(block, value)
                    start += len(block)
                return value

            if data_end is not None and data_end.data_section_crc and 0 <= end_at < size:
                stream.seek(end_at)
                if stream.read(len(_DATA_END_HEAD)) == _DATA_END_HEAD \
                        and crc(0, end_at) != data_end.data_section_crc:
                    out.append("its data outside the frames and the stored session (a message "
                               "index or metadata)")
            if footer.summary_crc:
                fields = struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start,
                                     footer.summary_offset_start)
                if zlib.crc32(fields, crc(summary_start or footer_at, footer_at)) \
                        != footer.summary_crc:
                    out.append(summary)
    except (OSError, ValueError, OverflowError, struct.error):
        pass  # (what was found stands; the rest cannot be read to be checked)
    return out


def read_and_decode(path: str | Path) -> int:
    """The floor a replay is measured against (``vade-bench --replay``): read every record
    of the file and decode every message as a replay decodes one (``codec.parse_json``:
    orjson), doing nothing with them. Returns the number of messages."""
    count = 0
    with open(path, "rb") as stream:
        for record in _messages(stream):
            if type(record) is tuple:
                codec.parse_json(record[1])
                count += 1
    return count


def library_read_and_decode(path: str | Path) -> int:
    """The floor of the bench's figures before the chunk reader and orjson: every record
    read by the mcap library's ``StreamReader``, every message ``json.loads``-ed."""
    count = 0
    with open(path, "rb") as stream:
        for record in StreamReader(stream).records:
            if isinstance(record, Message):
                json.loads(record.data)
                count += 1
    return count
