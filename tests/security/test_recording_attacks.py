"""Hostile MCAP files against :func:`agents_core.recording.read_recording` and ``agentsctl play``.

Each file is built record by record (the ``mcap`` package's record classes, not our writer), so a
field can lie: a chunk that says it holds 100 bytes but decompresses to 64 MiB (zstd and lz4
bombs), a zstd frame that declares a huge content size, a channel naming a type that does not
exist or a registry attribute, schema text of megabytes. A file is untrusted input: the reader
must refuse or skip, never allocate past its limit, never crash with something but RecordingError.
"""

from __future__ import annotations

import struct
import subprocess
import sys
import time
import tracemalloc
import zlib
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mcap.writer", reason="pip install 'agents-core[record]'")
pytest.importorskip("zstandard")
pytest.importorskip("lz4.frame")
import lz4.frame as lz4_frame
import zstandard
from mcap import records
from mcap.data_stream import RecordBuilder

from agents_core.recording import ReadSummary, RecordingError, read_recording
from agents_core.recording.encodings import MSGPACK, encoding_for
from agents_core.supported_types import Int64
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.recipes import recipe_environment
from agents_core.transport.registry import resolve_transport

REPO = Path(__file__).resolve().parents[2]
MAGIC = b"\x89MCAP0\r\n"
LIMIT = 1 << 20
BOMB = 64 << 20


def _file(path: Path, *parts: Any, footer: bool = False) -> Path:
    builder = RecordBuilder()
    records.Header(profile="", library="attack").write(builder)
    for part in parts:
        part.write(builder)
    if footer:
        records.DataEnd(data_section_crc=0).write(builder)
        records.Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(builder)
    path.write_bytes(MAGIC + builder.end() + (MAGIC if footer else b""))
    return path


def _channel(agents_type: str = "Int64", **fields: Any) -> records.Channel:
    return records.Channel(id=1, topic="t", message_encoding=fields.pop("encoding", MSGPACK),
                           metadata={"agents_type": agents_type}, schema_id=fields.pop("schema_id", 0), **fields)


def _chunk(compression: str, data: bytes, uncompressed_size: int, crc: int = 0) -> records.Chunk:
    return records.Chunk(compression=compression, data=data, message_start_time=0, message_end_time=0,
                         uncompressed_crc=crc, uncompressed_size=uncompressed_size)


def _read(path: Path, **options: Any) -> tuple[list[Any], ReadSummary]:
    summary = ReadSummary()
    return list(read_recording(path, summary=summary, **options)), summary


def _peak_mib(path: Path, **options: Any) -> tuple[float, BaseException | None]:
    tracemalloc.start()
    error: BaseException | None = None
    try:
        _read(path, **options)
    except RecordingError as exc:
        error = exc
    finally:
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return peak, error


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_a_chunk_that_lies_about_its_size_is_refused_before_it_is_inflated(tmp_path: Path,
                                                                           compression: str) -> None:
    zeros = b"\x00" * BOMB
    data = zstandard.ZstdCompressor().compress(zeros) if compression == "zstd" else lz4_frame.compress(zeros)
    del zeros
    assert len(data) < BOMB // 100  # a bomb: tiny on disk
    path = _file(tmp_path / "bomb.mcap", _chunk(compression, data, uncompressed_size=100))
    started = time.monotonic()
    peak, error = _peak_mib(path, max_record_bytes=LIMIT)
    assert isinstance(error, RecordingError), error
    assert peak < 8, f"{peak:.1f} MiB allocated for a chunk limited to 1 MiB"
    assert time.monotonic() - started < 10


def test_a_zstd_frame_declaring_a_huge_content_size_is_not_allocated(tmp_path: Path) -> None:
    # the frame header says 64 MiB; zstandard.decompress would allocate that from the header alone
    data = zstandard.ZstdCompressor(write_content_size=True).compress(b"\x00" * BOMB)
    path = _file(tmp_path / "declared.mcap", _chunk("zstd", data, uncompressed_size=LIMIT))
    peak, error = _peak_mib(path, max_record_bytes=LIMIT)
    assert isinstance(error, RecordingError), error
    assert peak < 8


def test_a_chunk_shorter_than_it_says_is_refused(tmp_path: Path) -> None:
    data = zstandard.ZstdCompressor().compress(b"\x00" * 10)
    with pytest.raises(RecordingError):
        _read(_file(tmp_path / "short.mcap", _chunk("zstd", data, uncompressed_size=1000)))


def test_an_honest_compressed_chunk_still_reads(tmp_path: Path) -> None:
    inner = RecordBuilder()
    _channel().write(inner)
    records.Message(channel_id=1, log_time=5, publish_time=5, sequence=0,
                    data=encoding_for(Int64, "msgpack").encode(7)).write(inner)
    body = inner.end()
    for compression, data in (("zstd", zstandard.ZstdCompressor().compress(body)),
                              ("lz4", lz4_frame.compress(body)), ("", body)):
        path = _file(tmp_path / f"ok{compression}.mcap", _chunk(compression, data, len(body), zlib.crc32(body)),
                     footer=True)
        messages, summary = _read(path)
        assert summary.messages == 1 and not summary.truncated, (compression, summary)
        assert messages[0].log_time_ns == 5


def test_an_unknown_compression_is_refused(tmp_path: Path) -> None:
    with pytest.raises(RecordingError):
        _read(_file(tmp_path / "bz.mcap", _chunk("bz2", b"x" * 10, uncompressed_size=10)))


@pytest.mark.parametrize("agents_type", ["NoSuchType", "__class__", "os.system", "", "x" * 100_000,
                                         "Int64\x00", "../../etc/passwd"])
def test_a_channel_naming_a_type_that_does_not_exist_is_skipped(tmp_path: Path, agents_type: str) -> None:
    message = records.Message(channel_id=1, log_time=1, publish_time=1, sequence=0, data=b"\x80")
    path = _file(tmp_path / "type.mcap", _channel(agents_type), message, footer=True)
    messages, summary = _read(path)
    assert messages == [] and summary.messages == 0
    if agents_type:  # an empty name falls back to the schema (none here): skipped as well
        assert "t" in summary.skipped_channels
        assert len(summary.skipped_channels["t"]) < 2000  # the name is not echoed back whole


def test_megabytes_of_schema_text_and_a_bogus_encoding_are_skipped(tmp_path: Path) -> None:
    schema = records.Schema(id=1, name="x" * (4 << 20), encoding="jsonschema", data=b"{" * (4 << 20))
    channel = records.Channel(id=1, topic="t", message_encoding="pickle", metadata={}, schema_id=1)
    message = records.Message(channel_id=1, log_time=1, publish_time=1, sequence=0, data=b"cos\nsystem\n")
    messages, summary = _read(_file(tmp_path / "schema.mcap", schema, channel, message, footer=True))
    assert messages == [] and "t" in summary.skipped_channels
    assert len(summary.skipped_channels["t"]) < 2000
    bogus = _channel("Int64", encoding="pickle")
    messages, summary = _read(_file(tmp_path / "enc.mcap", bogus, message, footer=True))
    assert messages == [] and "t" in summary.skipped_channels


def test_a_record_length_past_the_limit_is_refused_without_reading_it(tmp_path: Path) -> None:
    path = tmp_path / "len.mcap"
    path.write_bytes(MAGIC + struct.pack("<BQ", 0x01, 1 << 62) + b"\x00" * 16)
    with pytest.raises(RecordingError):
        _read(path, max_record_bytes=LIMIT)


@pytest.mark.zenoh
def test_agentsctl_play_and_record_refuse_hostile_files_and_paths_with_a_message(tmp_path: Path) -> None:
    pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")
    bomb = _file(tmp_path / "bomb.mcap", _chunk("zstd", zstandard.ZstdCompressor().compress(b"\x00" * BOMB), 100))
    passwd = tmp_path / "not.mcap"
    passwd.write_text("root:x:0:0:root:/root:/bin/bash\n")
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    cases = [["play", str(bomb)], ["play", str(tmp_path / "missing.mcap")],
             ["play", str(passwd)]]
    with resolve_transport("zenoh", mode="peer", listen=[endpoint], connect=[], multicast_scouting=False):
        for args in cases:
            done = subprocess.run([sys.executable, "-m", "agents_core.cli", *args, "-t", "zenoh", "--connect",
                                   endpoint], cwd=REPO, env=recipe_environment(), capture_output=True, text=True,
                                  timeout=60, check=False)
            assert done.returncode != 0, (args, done.stdout[-2000:])
            assert "Traceback" not in done.stderr and "error" in done.stderr.lower(), (args, done.stderr[-3000:])


@pytest.mark.parametrize("where", ["under_a_file", "a_folder"])
def test_a_destination_that_cannot_be_written_is_refused_at_once(tmp_path: Path, where: str) -> None:
    from agents_core.errors import ConfigError  # noqa: PLC0415
    from agents_core.recording.writer import McapSeriesWriter, RecordingLimits  # noqa: PLC0415

    blocker = tmp_path / "not_a_folder"
    blocker.write_text("x")
    path = blocker / "run.mcap" if where == "under_a_file" else tmp_path
    with pytest.raises(ConfigError, match="cannot record to"):
        McapSeriesWriter(path, RecordingLimits())
