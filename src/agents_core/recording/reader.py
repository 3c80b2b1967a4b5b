"""Reading an MCAP recording back as values, bounded, whatever the file holds.

:func:`read_recording` reads records in file order with the ``mcap`` package's stream reader, so a
file without its summary (a recorder that was killed) reads up to its last complete chunk, and
reports ``truncated``. A file is untrusted input: a record or a chunk larger than
``max_record_bytes`` (before or after decompression: a chunk is inflated by at most the size it
declares, plus one byte, so a compression bomb or a lying header allocates no more), a bad magic,
a checksum that does not match or a record that does not parse raise :class:`RecordingError`;
one message that does not decode is counted in :attr:`ReadSummary.decode_errors` and skipped.
"""

from __future__ import annotations

import dataclasses
import io
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


def _inflated(chunk: Any, limit: int) -> Any:
    """``chunk`` with its data decompressed, reading no more than it declares (RecordingError otherwise).

    The ``mcap`` package trusts the chunk: lz4 inflates whatever the data holds, and zstandard
    allocates the content size the frame header declares. Here both stop one byte past the size.
    """
    size = chunk.uncompressed_size
    if size > limit:
        raise RecordingError(f"a chunk of {size} bytes is over the limit ({limit})")
    if chunk.compression not in ("zstd", "lz4", ""):
        raise RecordingError(f"a chunk compressed as {chunk.compression[:40]!r}, which is not zstd or lz4")
    try:
        data = _decompress(chunk.compression, chunk.data, size + 1)
    except Exception as exc:  # each library has its own errors for corrupt data
        raise RecordingError(f"a chunk that does not decompress ({type(exc).__name__}: {str(exc)[:200]})") from None
    if len(data) != size:
        raise RecordingError(f"a chunk that declares {size} bytes decompresses to "
                             f"{'more' if len(data) > size else len(data)}")
    return dataclasses.replace(chunk, compression="", data=data)


def _decompress(compression: str, data: bytes, most: int) -> bytes:
    """At most ``most`` bytes of ``data`` decompressed as ``compression`` (zstd, lz4 or none)."""
    if compression == "zstd":
        import zstandard  # noqa: PLC0415 - with the 'record' extra

        reader = zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data), read_across_frames=True)
        parts, got = [], 0
        while got < most and (part := reader.read(most - got)):
            parts.append(part)
            got += len(part)
        return b"".join(parts)
    if compression == "lz4":
        import lz4.frame  # noqa: PLC0415 - with the 'record' extra (untyped; listed in mypy's overrides)

        return bytes(lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=most))
    return data[:most]


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
                yield from breakup_chunk(_inflated(record, max_record_bytes), validate_crc=True)
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
            summary.skipped_channels[topic] = str(exc)[:500]  # the file chose the name
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
