"""MCAP recordings; the only module that imports mcap.

A recording is an event log: the tracker inputs are the source of truth, everything else
is derived and checked by replay. It carries what it needs to be replayed anywhere: the
session file and every file it names as attachments, the physics and package versions as
metadata. Chunks are zstd-compressed and closed every simulated second, so a crash loses at
most the last second.
"""

from __future__ import annotations

import json
import os
import platform
from dataclasses import asdict, dataclass
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Iterator

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from . import codec
from .errors import RecordingError
from .frames import FrameRecord, TrackerFrame
from .scene import Scene
from .session import Session, load_schema, parse

PROFILE = "vade"
SESSION_ATTACHMENT = "session.json"
FILE_ATTACHMENT_PREFIX = "files/"
CHUNK_SECONDS_NS = 10**9
PACKAGES = ("vade_replay", "numpy", "trimesh", "python-fcl", "mcap", "rerun-sdk", "jsonschema")


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in PACKAGES:
        try:
            out[name] = importlib_metadata.version(name)
        except importlib_metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


class RecordingWriter:
    """Writes one session: attachments and metadata first, then frame after frame."""

    def __init__(self, path: str | Path, session: Session, scene: Scene, *,
                 extra_metadata: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        self._stream = open(self.path, "wb")
        self._writer = Writer(self._stream, compression=CompressionType.ZSTD,
                              chunk_size=4 * 1024 * 1024)
        self._writer.start(profile=PROFILE, library=f"vade_replay {package_versions()['vade_replay']}")
        self._channels: dict[str, int] = {}
        for topic, (schema_name, schema_file) in codec.CHANNELS.items():
            schema_id = self._writer.register_schema(
                name=schema_name, encoding="jsonschema",
                data=json.dumps(load_schema(schema_file)).encode())
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_id)
        self._writer.add_attachment(0, 0, SESSION_ATTACHMENT, "application/json", session.raw)
        for name in sorted(session.files):
            self._writer.add_attachment(0, 0, FILE_ATTACHMENT_PREFIX + name,
                                        "application/octet-stream", session.files[name])
        self._writer.add_metadata("versions", package_versions())
        self._writer.add_metadata("physics", {k: json.dumps(v) for k, v in
                                              asdict(scene.physics).items()})
        self._writer.add_metadata("session", {"name": session.name, **(extra_metadata or {})})
        self._sequence = 0
        self._last_flush_ns: int | None = None
        self.frames = 0

    def _add(self, topic: str, time_ns: int, data: bytes) -> None:
        self._writer.add_message(self._channels[topic], log_time=time_ns, data=data,
                                 publish_time=time_ns, sequence=self._sequence)
        self._sequence += 1

    def write_frame(self, record: FrameRecord,
                    derived: list[tuple[str, bytes]] | None = None) -> None:
        """Write a frame's tracker input and its derived messages."""
        t = record.time_ns
        self._add(codec.TRACKER_TOPIC, t, codec.dumps(codec.encode_tracker(record.inputs)))
        for topic, data in derived if derived is not None else codec.derived_messages(record):
            self._add(topic, t, data)
        self.frames += 1
        if self._last_flush_ns is None:
            self._last_flush_ns = t
        elif t - self._last_flush_ns >= CHUNK_SECONDS_NS:
            self._writer.flush()
            self._last_flush_ns = t

    def close(self) -> None:
        """Write the summary and close; a closed file is complete and indexed."""
        if self._stream.closed:
            return
        self._writer.finish()
        self._stream.flush()
        os.fsync(self._stream.fileno())
        self._stream.close()

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class RecordedFrame:
    """One frame as read back: its inputs and its derived messages, bytes as recorded."""

    inputs: TrackerFrame
    derived: list[tuple[str, bytes]]


class Recording:
    """A recording opened for reading: session from attachments, metadata, frame stream."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise RecordingError("no such file", file=str(self.path))
        try:
            with open(self.path, "rb") as stream:
                reader = make_reader(stream)
                header = reader.get_header()
                self.profile = header.profile
                summary = reader.get_summary()
                attachments = {a.name: a.data for a in reader.iter_attachments()}
                self.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except (McapError, OSError, ValueError, EOFError) as exc:
            raise RecordingError(f"not a readable MCAP file: {exc}", file=str(self.path)) \
                from None
        if self.profile != PROFILE or SESSION_ATTACHMENT not in attachments:
            raise RecordingError("not a vade_replay recording (no session attachment)",
                                 file=str(self.path))
        # Frames = tracker messages, known from the summary when the file was closed properly.
        self.frame_count = None
        if summary and summary.statistics:
            for channel_id, channel in summary.channels.items():
                if channel.topic == codec.TRACKER_TOPIC:
                    self.frame_count = summary.statistics.channel_message_counts.get(channel_id)
        files = {name[len(FILE_ATTACHMENT_PREFIX):]: data for name, data in attachments.items()
                 if name.startswith(FILE_ATTACHMENT_PREFIX)}
        self.session = parse(attachments[SESSION_ATTACHMENT], files,
                             source=f"{self.path}:{SESSION_ATTACHMENT}")

    def frames(self) -> Iterator[RecordedFrame]:
        """Frames in the order written, streaming chunk by chunk."""
        current: RecordedFrame | None = None
        try:
            with open(self.path, "rb") as stream:
                reader = make_reader(stream)
                for _, channel, message in reader.iter_messages(log_time_order=False):
                    topic = channel.topic
                    if topic == codec.TRACKER_TOPIC:
                        if current is not None:
                            yield current
                        try:
                            inputs = codec.decode_tracker(message.data)
                        except RecordingError as exc:
                            exc.file = str(self.path)
                            raise RecordingError(exc.message, file=str(self.path),
                                                 field=exc.field, frame=exc.frame) from None
                        current = RecordedFrame(inputs, [])
                    elif topic in codec.CHANNELS:
                        if current is None:
                            raise RecordingError(f"{topic} message before the first tracker "
                                                 "frame", file=str(self.path))
                        current.derived.append((topic, message.data))
        except (McapError, EOFError) as exc:
            frame = current.inputs.frame if current else None
            raise RecordingError(f"recording is damaged: {exc}", file=str(self.path),
                                 frame=frame) from None
        if current is not None:
            yield current
