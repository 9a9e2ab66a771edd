"""Making a recording whose writer never closed it a complete MCAP file again.

Design notes: docs/design/recording.md.
"""

from __future__ import annotations

import dataclasses as dc
import os
import struct
import zlib
from pathlib import Path

import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from physcap_drake.recording.reading import check_is_mcap

#: What reading a torn or garbled record can raise (the reader's own errors, a short read,
#: a bad length, a chunk that does not decompress).
_TORN = (McapError, EOFError, ValueError, struct.error, zlib.error, zstandard.ZstdError)

#: Suffix added to the original file's name when it is replaced by its recovered copy.
ORIGINAL_SUFFIX = ".orig"


@dc.dataclass(frozen=True)
class Recovery:
    """What `recover` did: whether the file needed it, the messages kept, whether the
    original ended in a torn record (what it held after the last whole record is lost) and
    where the original was kept (None when nothing was rewritten)."""

    path: Path
    needed: bool
    messages: int
    torn: bool
    original: Path | None


def is_complete(path: str | Path) -> bool:
    """Whether the file ends with a Footer that points to a summary section (its writer
    closed it). Raises FileNotFoundError for a missing file."""
    with Path(path).open("rb") as stream:
        try:
            return make_reader(stream).get_summary() is not None
        except (*_TORN, OSError):
            return False


def recover(path: str | Path) -> Recovery:
    """Rewrites an incomplete recording as a complete one (see the design notes); a
    complete file is left alone. Raises FileNotFoundError, or reading.RecordingError for a
    file that does not start like an MCAP file."""
    path = Path(path)
    check_is_mcap(path)
    if is_complete(path):
        return Recovery(path, needed=False, messages=0, torn=False, original=None)
    records, torn = _readable_records(path)
    partial = path.with_name(path.name + ".partial")
    messages = _write_complete(records, partial)
    original = path.with_name(path.name + ORIGINAL_SUFFIX)
    os.replace(path, original)
    os.replace(partial, path)
    return Recovery(path, needed=True, messages=messages, torn=torn, original=original)


def _readable_records(path: Path) -> tuple[list, bool]:
    """Every record up to the first that cannot be read; and whether one could not."""
    records = []
    with path.open("rb") as stream:
        reader = StreamReader(stream, emit_chunks=False)
        try:
            for record in reader.records:
                if isinstance(record, Footer):
                    return records, False
                records.append(record)
        except _TORN:
            return records, True
    return records, True


def _write_complete(records: list, path: Path) -> int:
    """Writes `records` (as read) into a new, closed MCAP file; returns the message count."""
    messages = 0
    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        header = next((r for r in records if isinstance(r, Header)), None)
        writer.start(profile=header.profile if header else "",
                     library=header.library if header else "physcap recover")
        schema_ids: dict[int, int] = {0: 0}
        channel_ids: dict[int, int] = {}
        for record in records:
            if isinstance(record, Schema):
                schema_ids[record.id] = writer.register_schema(record.name, record.encoding,
                                                               record.data)
            elif isinstance(record, Channel):
                channel_ids[record.id] = writer.register_channel(
                    record.topic, record.message_encoding, schema_ids[record.schema_id],
                    dict(record.metadata))
            elif isinstance(record, Message):
                writer.add_message(channel_ids[record.channel_id], record.log_time,
                                   record.data, record.publish_time, record.sequence)
                messages += 1
            elif isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
            elif isinstance(record, Attachment):
                writer.add_attachment(record.create_time, record.log_time, record.name,
                                      record.media_type, record.data)
        writer.finish()
    return messages
