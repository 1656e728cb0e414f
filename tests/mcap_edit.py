"""Test helper: copy a recording, changing or dropping messages (as a corrupted file would)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer


def copy_recording(src: Path, dst: Path, edit: Callable[[str, int, bytes], bytes | None],
                   *, drop_attachments: tuple[str, ...] = (),
                   edit_attachment: Callable[[str, bytes], bytes] | None = None,
                   edit_metadata: Callable[[str, dict], dict] | None = None,
                   use_chunking: bool = True,
                   compression: CompressionType = CompressionType.ZSTD) -> None:
    """Copy src to dst; ``edit(topic, index_on_topic, data)`` returns new data or None to drop;
    ``edit_attachment(name, data)`` and ``edit_metadata(name, values)`` the new contents."""
    with open(src, "rb") as f_in, open(dst, "wb") as f_out:
        reader = make_reader(f_in)
        header = reader.get_header()
        writer = Writer(f_out, compression=compression, use_chunking=use_chunking)
        writer.start(profile=header.profile, library=header.library)
        summary = reader.get_summary()
        schema_ids, channel_ids = {}, {}
        for schema_id, schema in sorted(summary.schemas.items()):
            schema_ids[schema_id] = writer.register_schema(schema.name, schema.encoding,
                                                           schema.data)
        for channel_id, channel in sorted(summary.channels.items()):
            channel_ids[channel_id] = writer.register_channel(
                channel.topic, channel.message_encoding, schema_ids[channel.schema_id])
        for attachment in reader.iter_attachments():
            if attachment.name not in drop_attachments:
                data = attachment.data if edit_attachment is None \
                    else edit_attachment(attachment.name, attachment.data)
                writer.add_attachment(attachment.create_time, attachment.log_time,
                                      attachment.name, attachment.media_type, data)
        for metadata in reader.iter_metadata():
            values = dict(metadata.metadata)
            if edit_metadata is not None:
                values = edit_metadata(metadata.name, values)
            writer.add_metadata(metadata.name, values)
        counts: dict[str, int] = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            index = counts.get(channel.topic, 0)
            counts[channel.topic] = index + 1
            data = edit(channel.topic, index, message.data)
            if data is not None:
                writer.add_message(channel_ids[channel.id], message.log_time, data,
                                   message.publish_time, message.sequence)
        writer.finish()


def nudge_pose(src: Path, dst: Path, *, frame: int, axis: int, delta: float) -> None:
    """Copy src to dst with the first part's recorded position at ``frame`` moved by ``delta``."""

    def edit(topic: str, index: int, data: bytes) -> bytes:
        if topic == "/parts" and index == frame:
            msg = json.loads(data)
            # A "changed" frame lists only parts that moved: pick a frame where one did.
            assert msg["parts"], f"no part is listed at frame {frame}: pick another"
            msg["parts"][0]["position"][axis] += delta
            return json.dumps(msg, sort_keys=True, separators=(",", ":")).encode()
        return data

    copy_recording(src, dst, edit)
