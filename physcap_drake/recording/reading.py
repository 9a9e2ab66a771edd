"""Reading a recording back with the `mcap` reader, including one cut short by a crash.

Design notes: docs/design/recording.md.
"""

from __future__ import annotations

import dataclasses as dc
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.exceptions import EndOfFile, McapError, RecordLengthLimitExceeded
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import MCAP0_MAGIC
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

from physcap_drake.recording import time_base


class RecordingError(ValueError):
    """The file is not an MCAP recording."""


def check_is_mcap(path: Path) -> None:
    """Raises FileNotFoundError for a missing file, RecordingError for a file that does not
    start like an MCAP file."""
    if not path.is_file():
        raise FileNotFoundError(f"no recording at {path}" + (
            " (it is a folder)" if path.is_dir() else ""))
    with path.open("rb") as stream:
        if stream.read(len(MCAP0_MAGIC)) != MCAP0_MAGIC:
            raise RecordingError(f"{path} is not an MCAP recording (it does not start with "
                                 "the MCAP magic bytes)")


class JsonDecoderFactory(McapDecoderFactory):
    """Decodes messages whose channel encoding is "json" into Python values."""

    def decoder_for(self, message_encoding: str, schema: Schema | None):
        if message_encoding != "json":
            return None
        return lambda data: json.loads(data)


@dc.dataclass(frozen=True)
class RecordedMessage:
    """One message: its topic, schema name, log time (ns since the Unix epoch on the
    episode's time base), the decoded value (a protobuf message for Foxglove schemas, a dict
    for JSON topics) and the episode's start (ns since the Unix epoch; 0 when unknown)."""

    topic: str
    schema: str
    log_time_ns: int
    value: Any
    episode_start_ns: int = 0

    @property
    def episode_time_ns(self) -> int:
        """ns since the episode's start (on its time base)."""
        return self.log_time_ns - self.episode_start_ns

    @property
    def time_s(self) -> float:
        """s since the episode's start (on its time base)."""
        return self.episode_time_ns * 1e-9


@dc.dataclass
class Recording:
    """Everything read from one file. complete: the file was closed properly (it has its
    summary section); False for a file cut short."""

    path: Path
    messages: list[RecordedMessage]
    metadata: dict[str, dict[str, str]]
    complete: bool

    @property
    def episode_start_ns(self) -> int:
        """The episode's start, ns since the Unix epoch (UTC); 0 for a recording that does
        not say (see `time_base_note`)."""
        return recorded_start_ns(self.metadata, self.path)

    @property
    def time_base(self) -> str:
        """time_base.SIMULATED or time_base.WALL_CLOCK; "" for a recording that does not
        say."""
        return self.metadata.get(time_base.TIME_METADATA, {}).get(time_base.KIND, "")

    @property
    def time_base_note(self) -> str:
        """One line on what the recording's times count."""
        if time_base.TIME_METADATA not in self.metadata:
            return (f"{self.path.name} records no start date (an older recording): its log "
                    "times are taken as simulated time from 0")
        what = ("wall-clock time" if self.time_base == time_base.WALL_CLOCK
                else "simulated time")
        return (f"episode started {time_base.utc_text(self.episode_start_ns)}; times are "
                f"{what} since then")

    def on(self, topic: str) -> list[RecordedMessage]:
        return [m for m in self.messages if m.topic == topic]

    def topics(self) -> dict[str, str]:
        """topic -> schema name, for every topic that has messages."""
        return {m.topic: m.schema for m in self.messages}


def recorded_start_ns(metadata: dict[str, dict[str, str]], path: Path | str = "") -> int:
    """The episode's start recorded in `metadata` (a recording's metadata records), ns since
    the Unix epoch; 0 when there is none. Raises RecordingError for a start that is not a
    whole number of ns."""
    text = metadata.get(time_base.TIME_METADATA, {}).get(time_base.START_DATE_NS)
    if text is None:
        return 0
    try:
        return int(text)
    except ValueError:
        raise RecordingError(f"{path}: '{time_base.TIME_METADATA}' metadata has "
                             f"{time_base.START_DATE_NS}={text!r}, not a whole number of "
                             "ns") from None


def iter_messages(path: str | Path, start_ns: int = 0) -> Iterator[RecordedMessage]:
    """The file's messages in the order they were written, decoded, with the episode's
    start `start_ns` (ns since the Unix epoch, for their `time_s`); stops quietly at the end
    of the data of a file cut short (see `read_recording` to know whether it was)."""
    with Path(path).open("rb") as stream:
        reader = NonSeekingReader(stream, decoder_factories=[ProtobufDecoderFactory(),
                                                             JsonDecoderFactory()])
        try:
            for schema, channel, message, value in reader.iter_decoded_messages(
                    log_time_order=False):
                yield RecordedMessage(channel.topic, schema.name if schema else "",
                                      message.log_time, value, start_ns)
        except (EndOfFile, RecordLengthLimitExceeded):
            # The file was cut short: its data ends here (the writer had begun a chunk whose
            # length it writes only when the chunk is finished).
            return


def read_recording(path: str | Path) -> Recording:
    """Reads a whole recording (see the design notes). Raises FileNotFoundError for a
    missing file and RecordingError for a file that is not MCAP at all."""
    path = Path(path)
    check_is_mcap(path)
    metadata, complete = _summary_metadata(path)
    messages = list(iter_messages(path, recorded_start_ns(metadata, path)))
    return Recording(path, messages, metadata, complete)


def _summary_metadata(path: Path) -> tuple[dict[str, dict[str, str]], bool]:
    """The metadata records, and whether the file is complete (has a footer and summary)."""
    with path.open("rb") as stream:
        reader = make_reader(stream)
        try:
            metadata = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
            complete = reader.get_summary() is not None
        except (McapError, EOFError):
            return _metadata_front_to_back(path), False
    return metadata, complete


def _metadata_front_to_back(path: Path) -> dict[str, dict[str, str]]:
    found: dict[str, dict[str, str]] = {}
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream).records:
                if isinstance(record, Metadata):
                    found[record.name] = dict(record.metadata)
        except (McapError, EOFError):
            pass
    return found
