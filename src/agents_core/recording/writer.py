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

A full disk or a file size limit (``ENOSPC``, ``EFBIG``, ``EDQUOT``: any ``OSError`` of a write)
does not end the recording: the file is cut back to the end of its last complete flush (so it
reads to that point, as a killed recorder's does), the values that were only in the lost part and
every later one are counted as ``lost``, one warning says so, and every ``retry_interval_s`` the
writer tries again with the next file of the series; when a write succeeds it says so once and
goes on.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import threading
import time
from pathlib import Path
from typing import Any, BinaryIO, Literal

from attrs import define, field, validators

from ..errors import ConfigError
from ..support.install_hint import install_hint
from .encodings import Encoding

__all__ = ["Compression", "McapSeriesWriter", "RecordingLimits", "require_mcap"]

logger = logging.getLogger(__name__)

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


class _CheckedFile:
    """An unbuffered file for the ``mcap`` writer whose ``write`` writes everything or raises.

    A buffered file reports a failed write late (at a later flush, or never for a short write);
    here a short write is retried and an error is raised at the call that hit it, so the writer
    knows which flush was the last complete one.
    """

    def __init__(self, path: Path) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._pos = 0

    def write(self, data: bytes | bytearray | memoryview) -> int:
        view = memoryview(data).cast("B")
        done = 0
        while done < len(view):
            n = os.write(self._fd, view[done:])
            if n <= 0:
                raise OSError(errno.EIO, "a write made no progress")
            done += n
            self._pos += n
        return done

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def fileno(self) -> int:
        return self._fd

    def cut(self, size: int) -> None:
        """Cut the file back to ``size`` bytes (what a failed write left past it goes)."""
        os.ftruncate(self._fd, size)
        os.lseek(self._fd, size, os.SEEK_SET)
        self._pos = size

    def close(self) -> None:
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            os.close(fd)


def series_path(path: Path, index: int) -> Path:
    """The ``index``-th file of the series that starts at ``path`` (``run.mcap``, ``run_1.mcap``, ...)."""
    return path if index == 0 else path.with_name(f"{path.stem}_{index}{path.suffix}")


class McapSeriesWriter:
    """Writes messages into a series of MCAP files (see the module docstring); thread-safe."""

    def __init__(self, path: str | Path, limits: RecordingLimits, *, chunk_size: int = 1024 * 1024,
                 compression: Compression = "lz4", fsync: bool = False, retry_interval_s: float = 1.0) -> None:
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
        #: Values lost to failed writes (a full disk, a file size limit), and how many writes failed.
        self.lost = self.write_failures = 0
        self.total_bytes = 0
        self._retry_interval = retry_interval_s
        self._failing_since: float | None = None
        self._last_attempt = 0.0
        self._good = 0  # the file's size at its last complete flush
        self._pending = self._pending_bytes = 0  # values (and bytes) written since then
        self._lost_in_outage = 0
        self._stream: _CheckedFile | BinaryIO | None = None
        self._writer: Any = None
        self._file_bytes = 0
        self._file_started = 0.0
        self._channels: dict[tuple[str, str], int] = {}
        self._schemas: dict[str, int] = {}
        self._sequence = 0
        self._ended = False

    def _open_next(self) -> None:
        healthy = self._failing_since is None
        self._close_current()
        if healthy and self._failing_since is not None:
            raise OSError(errno.EIO, "finishing the previous file failed")
        path = series_path(self._path, len(self.files))
        path.parent.mkdir(parents=True, exist_ok=True)
        self._stream = _CheckedFile(path)
        self.files.append(path)
        self._good = 0  # nothing of this file is good yet: a failed start leaves no bytes behind
        self._writer = self._mcap.Writer(self._stream, chunk_size=self._chunk_size, compression=self._compression)
        self._writer.start(profile="ros2", library="agents_core")
        self._good = self._stream.tell()
        self._pending = self._pending_bytes = 0
        self._channels.clear()
        self._schemas.clear()
        self._file_bytes = 0
        self._file_started = time.monotonic()

    def _close_current(self) -> None:
        if self._writer is not None and self._stream is not None:
            try:
                self._writer.finish()
            except OSError as exc:
                self._failed(exc)
                return
            self._stream.close()
        self._writer = self._stream = None

    def _failed(self, exc: OSError) -> None:
        """A write failed: cut the file back to its last complete flush, count the loss, say so once."""
        self.write_failures += 1
        self.lost += self._pending
        self._lost_in_outage += self._pending
        self.written -= self._pending
        self.total_bytes -= self._pending_bytes
        self._pending = self._pending_bytes = 0
        stream, self._stream, self._writer = self._stream, None, None
        if isinstance(stream, _CheckedFile):
            with contextlib.suppress(OSError):  # else the file keeps a torn end; a reader stops there
                stream.cut(self._good)
            stream.close()
            if self._good == 0 and self.files:  # a file that failed at its start holds nothing: not kept
                with contextlib.suppress(OSError):
                    self.files.pop().unlink()
        now = time.monotonic()
        self._last_attempt = now
        if self._failing_since is None:
            self._failing_since = now
            name = errno.errorcode.get(exc.errno or 0, "error")
            where = self.files[-1] if self.files else self._path
            logger.warning("recorder: writing %s failed (%s: %s); it keeps what was flushed before, values are "
                           "counted as lost, and writing is tried again every %.0f s with the next file",
                           where, name, exc.strerror or exc, self._retry_interval)

    def _resume(self, now: float) -> bool:
        """Whether writing may go on: not failing, or the retry after a failure opened a new file."""
        if self._failing_since is None:
            return True
        if now - self._last_attempt < self._retry_interval:
            return False
        self._last_attempt = now
        try:
            self._open_next()
        except OSError as exc:
            self._failed(exc)
            return False
        logger.warning("recorder: writing again, to %s, after %.1f s (%d values lost)", self.files[-1],
                       now - self._failing_since, self._lost_in_outage)
        self._failing_since = None
        self._lost_in_outage = 0
        return True

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
            if not self._resume(now):
                self.lost += 1
                self._lost_in_outage += 1
                return False
            try:
                if self._needs_split(now, size):
                    self._open_next()
                channel = self._channel(topic, agents_type, encoding)
                self._writer.add_message(channel, log_time_ns, data, publish_time_ns, self._sequence % 2**32)
            except OSError as exc:
                self._failed(exc)
                self.lost += 1  # this value too
                self._lost_in_outage += 1
                return False
            self._sequence += 1
            self._file_bytes += size
            self.total_bytes += size
            self.written += 1
            self._pending += 1
            self._pending_bytes += size
            return True

    def flush(self) -> None:
        """Close the open chunk and hand everything written so far to the operating system."""
        with self._lock:
            if self._writer is None or self._stream is None:
                return
            try:
                self._writer.flush()
                if self._fsync:
                    os.fsync(self._stream.fileno())
            except OSError as exc:
                self._failed(exc)
                return
            self._good = self._stream.tell()
            self._pending = self._pending_bytes = 0

    def close(self) -> None:
        """Finish the current file (summary and footer); idempotent."""
        with self._lock:
            self._ended = True
            self._close_current()
