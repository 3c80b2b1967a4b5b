"""Writing MCAP files: chunked, flushed on a clock, split by size or duration, bounded in total.

A recording is one file or a series (``run.mcap``, ``run_1.mcap``, ``run_2.mcap``, ...): a new
file starts when the current one passes :attr:`RecordingLimits.max_file_bytes` or
:attr:`~RecordingLimits.max_file_duration_s`; the recording stops taking messages at
:attr:`~RecordingLimits.max_total_bytes` or :attr:`~RecordingLimits.max_duration_s` (later ones
are counted as ``over_limit``), and one message over :attr:`~RecordingLimits.max_message_bytes` is
skipped and counted as ``oversize``.

Crash safety: :meth:`McapSeriesWriter.flush` closes the open chunk and flushes it to the
operating system; the recorder calls it every ``flush_interval_s``. A recorder killed with
SIGKILL leaves a file without its summary and footer, whose chunks up to the last flush read
back with any MCAP stream reader (the ``mcap`` package's ``StreamReader`` reads them and then
reports the end of the file).
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import Any, BinaryIO, Literal

from attrs import define, field, validators

from ..errors import ConfigError
from ..install_hint import install_hint
from .encodings import Encoding

__all__ = ["Compression", "McapSeriesWriter", "RecordingLimits", "require_mcap"]

#: How each chunk is compressed.
Compression = Literal["zstd", "lz4", "none"]

_positive = validators.optional(validators.gt(0))
#: The bytes an MCAP message record adds to its payload (opcode, length, channel, sequence, two times).
RECORD_OVERHEAD = 31


@define(frozen=True, kw_only=True)
class RecordingLimits:
    """How much a recording may hold; None: no limit of that kind.

    :param max_file_bytes: start a new file after this many bytes.
    :param max_file_duration_s: start a new file after this many seconds of recording.
    :param max_total_bytes: stop recording after this many bytes in all files.
    :param max_duration_s: stop recording after this many seconds.
    :param max_message_bytes: skip (and count) one encoded message larger than this.
    """

    max_file_bytes: int | None = field(default=None, validator=_positive)
    max_file_duration_s: float | None = field(default=None, validator=_positive)
    max_total_bytes: int | None = field(default=None, validator=_positive)
    max_duration_s: float | None = field(default=None, validator=_positive)
    max_message_bytes: int = field(default=256 * 2**20, validator=validators.gt(0))


def require_mcap() -> Any:
    """The ``mcap`` package's writer module, or ConfigError naming the extra."""
    try:
        import mcap.writer  # noqa: PLC0415 - the 'record' extra
    except ImportError as exc:
        raise ConfigError(f"recording needs the 'record' extra ({exc}); {install_hint('record')}") from None
    return mcap.writer


def _check_writable(path: Path) -> None:
    """Refuse at once a recording whose folder cannot be made or written (not at the first message)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot record to {path}: its folder cannot be made ({exc.strerror or exc})") from None
    if path.is_dir():
        raise ConfigError(f"cannot record to {path}: it is a folder; give a file name such as {path / 'run.mcap'}")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot record to {path}: its folder {path.parent} is not writable")


def series_path(path: Path, index: int) -> Path:
    """The ``index``-th file of the series that starts at ``path`` (``run.mcap``, ``run_1.mcap``, ...)."""
    return path if index == 0 else path.with_name(f"{path.stem}_{index}{path.suffix}")


class McapSeriesWriter:
    """Writes messages into a series of MCAP files (see the module docstring); thread-safe."""

    def __init__(self, path: str | Path, limits: RecordingLimits, *, chunk_size: int = 1024 * 1024,
                 compression: Compression = "lz4", fsync: bool = False) -> None:
        self._mcap = require_mcap()
        self._path = Path(path)
        _check_writable(self._path)
        self._limits = limits
        self._chunk_size = chunk_size
        self._compression = {"zstd": self._mcap.CompressionType.ZSTD, "lz4": self._mcap.CompressionType.LZ4,
                             "none": self._mcap.CompressionType.NONE}[compression]
        self._fsync = fsync
        self._lock = threading.Lock()
        self._started = time.monotonic()
        self.files: list[Path] = []
        self.written = self.oversize = self.over_limit = 0
        self.total_bytes = 0
        self._stream: BinaryIO | None = None
        self._writer: Any = None
        self._file_bytes = 0
        self._file_started = 0.0
        self._channels: dict[tuple[str, str], int] = {}
        self._schemas: dict[str, int] = {}
        self._sequence = 0
        self._ended = False

    def _open_next(self) -> None:
        self._close_current()
        path = series_path(self._path, len(self.files))
        path.parent.mkdir(parents=True, exist_ok=True)
        self._stream = open(path, "wb")  # noqa: SIM115 - closed by _close_current
        self._writer = self._mcap.Writer(self._stream, chunk_size=self._chunk_size, compression=self._compression)
        self._writer.start(profile="ros2", library="agents_core")
        self.files.append(path)
        self._channels.clear()
        self._schemas.clear()
        self._file_bytes = 0
        self._file_started = time.monotonic()

    def _close_current(self) -> None:
        if self._writer is not None and self._stream is not None:
            self._writer.finish()
            self._stream.close()
        self._writer = self._stream = None

    def _channel(self, topic: str, agents_type: str, encoding: Encoding) -> int:
        key = (topic, agents_type)
        channel = self._channels.get(key)
        if channel is None:
            schema = self._schemas.get(encoding.schema_name)
            if schema is None:
                schema = self._writer.register_schema(encoding.schema_name, encoding.schema_encoding,
                                                      encoding.schema_data)
                self._schemas[encoding.schema_name] = schema
            channel = self._writer.register_channel(f"/{topic}", encoding.message_encoding, schema,
                                                    {"agents_type": agents_type})
            self._channels[key] = channel
        return channel

    def _limit_reached(self, now: float) -> bool:
        lim = self._limits
        return ((lim.max_total_bytes is not None and self.total_bytes >= lim.max_total_bytes)
                or (lim.max_duration_s is not None and now - self._started >= lim.max_duration_s))

    def _needs_split(self, now: float, size: int) -> bool:
        lim = self._limits
        if self._writer is None:
            return True
        if not self._file_bytes:
            return False  # a file holds at least one message, however large the limit says
        return ((lim.max_file_bytes is not None and self._file_bytes + size > lim.max_file_bytes)
                or (lim.max_file_duration_s is not None and now - self._file_started >= lim.max_file_duration_s))

    def write(self, topic: str, agents_type: str, encoding: Encoding, data: bytes, log_time_ns: int,
              publish_time_ns: int) -> bool:
        """Write one encoded message; False when a limit made it skip (counted)."""
        size = len(data) + RECORD_OVERHEAD
        with self._lock:
            now = time.monotonic()
            if self._ended or self._limit_reached(now):
                self.over_limit += 1
                return False
            if len(data) > self._limits.max_message_bytes:
                self.oversize += 1
                return False
            if self._needs_split(now, size):
                self._open_next()
            channel = self._channel(topic, agents_type, encoding)
            self._writer.add_message(channel, log_time_ns, data, publish_time_ns, self._sequence % 2**32)
            self._sequence += 1
            self._file_bytes += size
            self.total_bytes += size
            self.written += 1
            return True

    def flush(self) -> None:
        """Close the open chunk and hand everything written so far to the operating system."""
        with self._lock:
            if self._writer is None or self._stream is None:
                return
            self._writer.flush()
            if self._fsync:
                os.fsync(self._stream.fileno())

    def close(self) -> None:
        """Finish the current file (summary and footer); idempotent."""
        with self._lock:
            self._ended = True
            self._close_current()
