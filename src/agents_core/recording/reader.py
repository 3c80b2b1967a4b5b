"""Reading an MCAP recording back as values, bounded, whatever the file holds.

:func:`read_recording` reads records in file order with the ``mcap`` package's stream reader, so a
file without its summary (a recorder that was killed) reads up to its last complete chunk, and
reports ``truncated``. A file is untrusted input: a record or a chunk larger than
``max_record_bytes`` (before or after decompression: a chunk is inflated by at most the size it
declares, plus one byte, so a compression bomb or a lying header allocates no more), a bad magic,
a checksum that does not match or a record that does not parse raise :class:`RecordingError`;
one message that does not decode is counted in :attr:`ReadSummary.decode_errors` and skipped.

What the reader keeps about the file is bounded too, whatever the file holds: a channel it cannot
read is counted (:attr:`ReadSummary.skipped_channel_count`) but remembered by name and reason only
for the first :data:`MAX_SKIPPED_LISTED`; at most :data:`MAX_CHANNELS` readable channels and
:data:`MAX_SCHEMAS` schemas are kept (later ones are skipped and counted), and the answer for a
type name or schema is looked up once, not once per channel naming it.
"""

from __future__ import annotations

import dataclasses
import io
import struct
import zlib
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
#: Skipped channels named (with the reason) in :attr:`ReadSummary.skipped_channels`; the rest only counted.
MAX_SKIPPED_LISTED = 100
#: Readable channels kept at once (a file of more is hostile: the later ones are skipped and counted).
MAX_CHANNELS = 10_000
#: Schemas kept at once (the same bound).
MAX_SCHEMAS = 10_000
#: Type lookups remembered (a name that fails once fails the same way for every channel naming it).
_LOOKUPS = 1024


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
    #: The first :data:`MAX_SKIPPED_LISTED` skipped channels, by topic, with the reason.
    skipped_channels: dict[str, str] = field(factory=dict)
    #: Every channel skipped (unknown type, bad encoding, past :data:`MAX_CHANNELS`), listed or not.
    skipped_channel_count: int = 0

    def skip(self, topic: str, reason: str) -> None:
        """Count a skipped channel; name it only while fewer than :data:`MAX_SKIPPED_LISTED` are named."""
        self.skipped_channel_count += 1
        if len(self.skipped_channels) < MAX_SKIPPED_LISTED or topic in self.skipped_channels:
            self.skipped_channels[topic[:200]] = reason[:500]  # the file chose the name


def _channel_decoder(channel: Any, schema: Any) -> tuple[type[SupportedType], Callable[[bytes], Any]]:
    name = channel.metadata.get("agents_type") if channel.metadata else None
    msg_type: type[SupportedType] | None
    if name:
        msg_type = get_type(name)
    else:
        msg_type = type_for_schema(schema.name) if schema is not None else None
        if msg_type is None:
            raise UnknownTypeError(f"no agents_core type for schema {getattr(schema, 'name', None)!r}"[:500])
    return msg_type, decoder_for(msg_type, channel.message_encoding)


class _Lookups:
    """:func:`_channel_decoder`'s answers by (type name, schema name, encoding), at most ``_LOOKUPS`` kept."""

    def __init__(self) -> None:
        self._known: dict[tuple[str, str, str], tuple[type[SupportedType], Callable[[bytes], Any]] | str] = {}

    def get(self, channel: Any, schema: Any) -> tuple[type[SupportedType], Callable[[bytes], Any]]:
        name = channel.metadata.get("agents_type", "") if channel.metadata else ""
        key = (str(name)[:300], str(getattr(schema, "name", ""))[:300] if not name else "",
               str(channel.message_encoding)[:100])
        found = self._known.get(key)
        if found is None:
            try:
                found = _channel_decoder(channel, schema)
            except (ConfigError, LookupError) as exc:
                found = str(exc)[:500]
            if len(self._known) >= _LOOKUPS:
                self._known.pop(next(iter(self._known)))
            self._known[key] = found
        if isinstance(found, str):
            raise LookupError(found)
        return found


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


def _text(data: bytes, pos: int, end: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", data, pos)
    pos += 4
    if pos + n > end:
        raise ValueError("a string runs past its record")
    return data[pos:pos + n].decode(), pos + n


def _chunk_records(data: bytes, records: Any) -> Iterator[Any]:
    """The schema, channel and message records of a decompressed chunk (others skipped).

    Parsed here with ``struct`` rather than by the ``mcap`` package's record readers, which cost
    ~10x more per record: a chunk of a million channels reads in seconds. Each record must stay
    inside the length it declares and the chunk; otherwise :class:`RecordingError`.
    """
    pos, size = 0, len(data)
    try:
        while pos < size:
            opcode, length = struct.unpack_from("<BQ", data, pos)
            pos += 9
            end = pos + length
            if end > size:
                raise ValueError("a record runs past the end of its chunk")
            if opcode == 0x04:  # Channel
                cid, schema_id = struct.unpack_from("<HH", data, pos)
                topic, at = _text(data, pos + 4, end)
                encoding, at = _text(data, at, end)
                (meta_len,) = struct.unpack_from("<I", data, at)
                at += 4
                meta_end = at + meta_len
                if meta_end > end:
                    raise ValueError("channel metadata runs past its record")
                metadata: dict[str, str] = {}
                while at < meta_end:
                    key, at = _text(data, at, meta_end)
                    metadata[key], at = _text(data, at, meta_end)
                yield records.Channel(id=cid, topic=topic, message_encoding=encoding, metadata=metadata,
                                      schema_id=schema_id)
            elif opcode == 0x05:  # Message
                if length < 22:
                    raise ValueError("a message record shorter than its header")
                cid, sequence, log_time, publish_time = struct.unpack_from("<HIQQ", data, pos)
                yield records.Message(channel_id=cid, sequence=sequence, log_time=log_time,
                                      publish_time=publish_time, data=data[pos + 22:end])
            elif opcode == 0x03:  # Schema
                (sid,) = struct.unpack_from("<H", data, pos)
                name, at = _text(data, pos + 2, end)
                encoding, at = _text(data, at, end)
                (data_len,) = struct.unpack_from("<I", data, at)
                if at + 4 + data_len > end:
                    raise ValueError("schema data runs past its record")
                yield records.Schema(id=sid, name=name, encoding=encoding, data=data[at + 4:at + 4 + data_len])
            pos = end
    except (struct.error, ValueError, UnicodeDecodeError) as exc:
        raise RecordingError(f"a chunk record that does not parse ({exc})") from None


def read_recording(path: str | Path, *, summary: ReadSummary | None = None, topics: set[str] | None = None,
                   max_record_bytes: int = DEFAULT_MAX_RECORD_BYTES) -> Iterator[RecordedMessage]:
    """The messages of the MCAP file ``path`` in file order (see the module docstring).

    :param summary: filled in while reading (counts, truncation, channels skipped with the reason).
    :param topics: only these topics (no leading ``/``); None: all.
    """
    try:
        from mcap import exceptions, records  # noqa: PLC0415 - the 'record' extra
        from mcap.stream_reader import StreamReader  # noqa: PLC0415
    except ImportError as exc:
        raise ConfigError(f"reading recordings needs the 'record' extra ({exc}); "
                          "pip install 'agents-core[record]'") from None
    summary = summary if summary is not None else ReadSummary()
    schemas: dict[int, Any] = {}
    channels: dict[int, tuple[str, type[SupportedType], Callable[[bytes], Any]]] = {}
    lookups = _Lookups()

    def flat(reader: StreamReader) -> Iterator[Any]:
        for record in reader.records:
            if isinstance(record, records.Chunk):
                chunk = _inflated(record, max_record_bytes)
                if chunk.uncompressed_crc and zlib.crc32(chunk.data) != chunk.uncompressed_crc:
                    raise RecordingError("a chunk whose checksum does not match its data")
                yield from _chunk_records(chunk.data, records)
            else:
                yield record

    # A corrupt record length cannot allocate more than record_size_limit: the reader checks it first.
    with open(path, "rb") as stream:
        reader = StreamReader(stream, emit_chunks=True, validate_crcs=True,
                              record_size_limit=max_record_bytes)
        try:
            for record in flat(reader):
                message = _handle(record, records, schemas, channels, topics, summary, lookups)
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
            channels: dict[int, tuple[str, type[SupportedType], Callable[[bytes], Any]]],
            topics: set[str] | None, summary: ReadSummary, lookups: _Lookups) -> RecordedMessage | None:
    """Keep a schema or channel record; decode a message record of a kept channel (None otherwise).

    Only readable channels are kept: a message of any other channel id is skipped.
    """
    if isinstance(record, records.Schema):
        if record.id in schemas or len(schemas) < MAX_SCHEMAS:
            # Only the name is needed (type_for_schema): the schema text is not kept.
            schemas[record.id] = records.Schema(id=record.id, name=record.name[:300], encoding="", data=b"")
    elif isinstance(record, records.Channel):
        topic = record.topic.lstrip("/")
        channels.pop(record.id, None)  # an id defined again: the old definition is gone
        if topics is not None and topic not in topics:
            return None
        if len(channels) >= MAX_CHANNELS:
            summary.skip(topic, f"more than {MAX_CHANNELS} channels in one file")
            return None
        try:
            msg_type, decode = lookups.get(record, schemas.get(record.schema_id))
        except LookupError as exc:
            summary.skip(topic, str(exc.args[0] if exc.args else exc))
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
