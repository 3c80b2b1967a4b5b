"""Reading an MCAP recording back as values, bounded, whatever the file holds.

:func:`read_recording` reads records in file order with the ``mcap`` package's stream reader, so a
file without its summary (a recorder that was killed) reads up to its last complete chunk, and
reports ``truncated``. A file is untrusted input: a record or a chunk larger than
``max_record_bytes`` (before or after decompression), a bad magic, a checksum that does not match
or a record that does not parse raise :class:`RecordingError`; one message that does not decode
is counted in :attr:`ReadSummary.decode_errors` and skipped.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from attrs import define, field

from ..errors import AgentsError, ConfigError, UnknownTypeError
from ..types.base import SupportedType, get_type
from .encodings import decoder_for, type_for_schema

__all__ = ["ReadSummary", "RecordedMessage", "RecordingError", "read_recording"]

#: The largest record or decompressed chunk read by default.
DEFAULT_MAX_RECORD_BYTES = 512 * 2**20


class RecordingError(AgentsError, ValueError):
    """A recording that cannot be read: not MCAP, corrupt, or over the reader's limits."""


@define(frozen=True)
class RecordedMessage:
    """One recorded value: topic (no leading ``/``), type, value, receipt and publish times (ns)."""

    topic: str
    msg_type: type[SupportedType]
    value: Any
    log_time_ns: int
    publish_time_ns: int
    data: bytes = field(repr=False)


@define
class ReadSummary:
    """What reading found besides the messages: skipped channels, undecodable messages, a cut end."""

    messages: int = 0
    decode_errors: int = 0
    truncated: bool = False
    skipped_channels: dict[str, str] = field(factory=dict)


def _channel_decoder(channel: Any, schema: Any) -> tuple[type[SupportedType], Callable[[bytes], Any]]:
    name = channel.metadata.get("agents_type") if channel.metadata else None
    msg_type: type[SupportedType] | None
    if name:
        msg_type = get_type(name)
    else:
        msg_type = type_for_schema(schema.name) if schema is not None else None
        if msg_type is None:
            raise UnknownTypeError(f"no agents_core type for schema {getattr(schema, 'name', None)!r}")
    return msg_type, decoder_for(msg_type, channel.message_encoding)


def read_recording(path: str | Path, *, summary: ReadSummary | None = None, topics: set[str] | None = None,
                   max_record_bytes: int = DEFAULT_MAX_RECORD_BYTES) -> Iterator[RecordedMessage]:
    """The messages of the MCAP file ``path`` in file order (see the module docstring).

    :param summary: filled in while reading (counts, truncation, channels skipped with the reason).
    :param topics: only these topics (no leading ``/``); None: all.
    """
    try:
        from mcap import exceptions, records  # noqa: PLC0415 - the 'record' extra
        from mcap.stream_reader import StreamReader, breakup_chunk  # noqa: PLC0415
    except ImportError as exc:
        raise ConfigError(f"reading recordings needs the 'record' extra ({exc}); "
                          "pip install 'agents-core[record]'") from None
    summary = summary if summary is not None else ReadSummary()
    schemas: dict[int, Any] = {}
    channels: dict[int, tuple[str, type[SupportedType], Callable[[bytes], Any]] | None] = {}

    def flat(reader: StreamReader) -> Iterator[Any]:
        for record in reader.records:
            if isinstance(record, records.Chunk):
                if record.uncompressed_size > max_record_bytes:
                    raise RecordingError(f"a chunk of {record.uncompressed_size} bytes is over the limit "
                                         f"({max_record_bytes})")
                yield from breakup_chunk(record, validate_crc=True)
            else:
                yield record

    # A corrupt record length cannot allocate more than record_size_limit: the reader checks it first.
    with open(path, "rb") as stream:
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True,
                              record_size_limit=max_record_bytes)
        try:
            for record in flat(reader):
                message = _handle(record, records, schemas, channels, topics, summary)
                if message is not None:
                    yield message
        except (exceptions.EndOfFile, struct.error):
            # A short read happens only at the end of the file: a record cut in the middle.
            summary.truncated = True
        # lz4.frame reports a damaged chunk as a bare RuntimeError (zstandard as a ZstdError, a ValueError).
        except (exceptions.McapError, ValueError, KeyError, IndexError, OverflowError, MemoryError,
                RuntimeError) as exc:
            if isinstance(exc, RecordingError):
                raise
            raise RecordingError(f"{path}: not a readable MCAP recording ({type(exc).__name__}: {exc})") from None


def _handle(record: Any, records: Any, schemas: dict[int, Any],
            channels: dict[int, tuple[str, type[SupportedType], Callable[[bytes], Any]] | None],
            topics: set[str] | None, summary: ReadSummary) -> RecordedMessage | None:
    """Keep a schema or channel record; decode a message record of a kept channel (None otherwise)."""
    if isinstance(record, records.Schema):
        schemas[record.id] = record
    elif isinstance(record, records.Channel):
        topic = record.topic.lstrip("/")
        channels[record.id] = None
        if topics is not None and topic not in topics:
            return None
        try:
            msg_type, decode = _channel_decoder(record, schemas.get(record.schema_id))
        except (ConfigError, LookupError) as exc:
            summary.skipped_channels[topic] = str(exc)
            return None
        channels[record.id] = (topic, msg_type, decode)
    elif isinstance(record, records.Message):
        entry = channels.get(record.channel_id)
        if entry is None:
            return None
        try:
            value = entry[2](record.data)
        except Exception:  # an untrusted payload: counted, never fatal
            summary.decode_errors += 1
            return None
        summary.messages += 1
        return RecordedMessage(entry[0], entry[1], value, record.log_time, record.publish_time, record.data)
    return None
