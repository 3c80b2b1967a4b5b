"""Recordings, round 3 (issue 36, items 8, 9 and 11): a reader whose bookkeeping is bounded whatever the
file holds, a recorder that survives a file size limit (EFBIG) and goes on when it is lifted, and a
player that skips a channel conflicting with the live recipe and refuses impossible timestamps.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import threading
import time
import zlib
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mcap.writer", reason="pip install 'agents-core[record]'")
from mcap import records
from mcap.data_stream import RecordBuilder

from agents_core.recording import Player, ReadSummary, read_recording
from agents_core.recording.encodings import MSGPACK, encoding_for
from agents_core.supported_types import Int64, String
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.recipes import recipe_environment
from agents_core.topics import Topic
from agents_core.transport.memory import MemoryTransport

pytestmark = pytest.mark.timeout(180)
REPO = Path(__file__).resolve().parents[2]
#: Skipped channels the summary names at most (agents_core.recording.reader.MAX_SKIPPED_LISTED).
MAX_SKIPPED_LISTED = 100
MAGIC = b"\x89MCAP0\r\n"


def _string(text: str) -> bytes:
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def _record(opcode: int, body: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(body)) + body


def _channels_file(path: Path, count: int, agents_type: str = "NoSuchType" + "x" * 40) -> Path:
    """``count`` channel records naming an unknown type (ids wrap at 65536), with one message per 1000
    channels, packed by hand into zstd chunks of ~1 MiB each: a few MB on disk."""
    import zstandard  # noqa: PLC0415

    metadata = _string("agents_type") + _string(agents_type)
    metadata = struct.pack("<I", len(metadata)) + metadata
    enc = _string(MSGPACK)
    out = [MAGIC, _record(0x01, _string("") + _string("attack"))]
    compressor = zstandard.ZstdCompressor(level=3)
    body: list[bytes] = []
    size = 0

    def close_chunk() -> None:
        nonlocal size
        data = b"".join(body)
        packed = compressor.compress(data)
        out.append(_record(0x06, struct.pack("<QQQI", 0, 1, len(data), zlib.crc32(data)) + _string("zstd")
                           + struct.pack("<Q", len(packed)) + packed))
        body.clear()
        size = 0

    for i in range(count):
        body.append(_record(0x04, struct.pack("<HH", i % 65536, 0) + _string(f"t{i}") + enc + metadata))
        if i % 1000 == 0:
            body.append(_record(0x05, struct.pack("<HIQQ", i % 65536, 0, 1, 1) + b"\x80"))
        size += 120
        if size >= 2**20:
            close_chunk()
    if body:
        close_chunk()
    path.write_bytes(b"".join(out))
    return path


_READ_IN_A_CHILD = """
import json, resource, sys, time
from agents_core.recording import ReadSummary, read_recording
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
summary = ReadSummary()
start = time.monotonic()
messages = list(read_recording(sys.argv[1], summary=summary))
print(json.dumps({"seconds": time.monotonic() - start, "messages": len(messages),
                  "count": summary.skipped_channel_count, "listed": len(summary.skipped_channels),
                  "grown_mb": (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024}))
"""


def test_a_million_unknown_channels_cost_little_to_read(tmp_path: Path) -> None:
    path = _channels_file(tmp_path / "million.mcap", 1_000_000)
    assert path.stat().st_size < 8 * 2**20  # the file was 3.4 MB
    done = subprocess.run([sys.executable, "-c", _READ_IN_A_CHILD, str(path)], cwd=REPO, env=recipe_environment(),
                          capture_output=True, text=True, timeout=150, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"1,000,000 unknown channels ({path.stat().st_size / 2**20:.1f} MB): read in {got['seconds']:.1f} s, "
          f"RSS +{got['grown_mb']:.0f} MB, {got['count']} skipped, {got['listed']} listed")
    assert got["messages"] == 0 and got["count"] == 1_000_000 and got["listed"] == MAX_SKIPPED_LISTED, got
    assert got["grown_mb"] < 100, got  # 1,170 MB on 367a9ce
    assert got["seconds"] < 60, got  # ~7 s here (73 s on 367a9ce)


def test_a_readable_channel_after_many_unknown_ones_still_reads(tmp_path: Path) -> None:
    path = _channels_file(tmp_path / "mixed.mcap", 5000)
    builder = RecordBuilder()
    records.Channel(id=7, topic="/ok", message_encoding=MSGPACK, metadata={"agents_type": "Int64"},
                    schema_id=0).write(builder)
    records.Message(channel_id=7, log_time=5, publish_time=5, sequence=0,
                    data=encoding_for(Int64, "msgpack").encode(41)).write(builder)
    path.write_bytes(path.read_bytes() + builder.end())
    summary = ReadSummary()
    messages = list(read_recording(path, summary=summary))
    assert [m.value for m in messages] == [41]
    assert summary.skipped_channel_count == 5000


# -- item 9: a file size limit hit, then lifted; a disk that fills up, then is freed ----------------

#: Mounts a 256 KiB tmpfs at $1 in a private mount namespace (no root needed where user namespaces are
#: allowed) and runs the recorder on it: ENOSPC from a real file system, not a simulated error.
_ON_A_SMALL_DISK = ('mount -t tmpfs -o size=256k tmpfs "$1" && '
                    'exec "$2" -m tests.security.fsize_recorder --enospc "$1" "$3"')


def _small_disk_command(tmp_path: Path, out: Path) -> list[str]:
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount -t tmpfs tmpfs {tmp_path}"],
                           capture_output=True, text=True, timeout=30, check=False) \
        if shutil.which("unshare") else None
    if probe is None or probe.returncode != 0:
        why = probe.stderr.strip() if probe is not None else "no unshare"
        pytest.skip(f"no private mount namespace for a small tmpfs here ({why})")
    disk = tmp_path / "disk"
    disk.mkdir()
    return ["unshare", "-rm", "sh", "-c", _ON_A_SMALL_DISK, "sh", str(disk), sys.executable, str(out)]


@pytest.mark.parametrize("failure", ["efbig", "enospc"])
def test_the_recorder_survives_a_failing_disk_and_resumes_when_it_recovers(tmp_path: Path, failure: str) -> None:
    out = tmp_path / "run.mcap"
    command = ([sys.executable, "-m", "tests.security.fsize_recorder", str(out)] if failure == "efbig"
               else _small_disk_command(tmp_path, out))
    done = subprocess.run(command, cwd=REPO, env=recipe_environment(), capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    stats = json.loads(done.stdout.strip().splitlines()[-1])
    assert stats["received"] == stats["sent"] == 2100
    assert stats["lost"] > 0 and stats["write_failures"] >= 1, stats
    # every value is accounted for: written, lost, dropped or an error
    assert stats["written"] + stats["lost"] + stats["dropped"] + stats["errors"] == stats["received"], stats
    # said once when it failed, once when it resumed: not once per value
    assert 1 <= stats["warnings"] <= 6, stats["warning_lines"]  # an outage and its end; never per value
    errno_name = "ENOSPC" if failure == "enospc" else "EFBIG"
    assert any(errno_name in line for line in stats["warning_lines"]), stats["warning_lines"]
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    # every file reads to its last good chunk, and what was counted written is what reads back
    assert len(stats["files"]) >= 2, stats
    values: list[int] = []
    for name in stats["files"]:
        summary = ReadSummary()
        values += [int(m.value)
                   for m in read_recording(name, summary=summary)]
        assert summary.decode_errors == 0
    assert len(values) == stats["written"], (len(values), stats)
    assert values == sorted(values) and values[0] == 0
    assert values[-1] == 2099  # the last values, after the limit was lifted, are there
    print(f"{failure}: {stats['written']} written, {stats['lost']} lost, {stats['write_failures']} failed writes, "
          f"{stats['warnings']} warnings, {len(values)} read back")


# -- item 11: the player ------------------------------------------------------------------------------


def _recording(path: Path, items: list[tuple[str, str, Any, int]]) -> Path:
    """A recording of ``(topic, agents type, value, log time)`` written record by record."""
    builder = RecordBuilder()
    records.Header(profile="", library="attack").write(builder)
    ids: dict[tuple[str, str], int] = {}
    for topic, type_name, value, log_time in items:
        key = (topic, type_name)
        if key not in ids:
            ids[key] = len(ids) + 1
            records.Channel(id=ids[key], topic=f"/{topic}", message_encoding=MSGPACK,
                            metadata={"agents_type": type_name}, schema_id=0).write(builder)
        cls = {"Int64": Int64, "String": String}[type_name]
        records.Message(channel_id=ids[key], log_time=log_time, publish_time=log_time, sequence=0,
                        data=encoding_for(cls, "msgpack").encode(value)).write(builder)
    path.write_bytes(MAGIC + builder.end())
    return path


@pytest.fixture(params=["memory", "zenoh", "ros2"])
def transport(request: pytest.FixtureRequest) -> Any:
    if request.param == "memory":
        with MemoryTransport() as t:
            yield t
        return
    from agents_core.testing.pairs import skip_unless_installed  # noqa: PLC0415
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

    skip_unless_installed(request.param)
    if request.param == "ros2":
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        with resolve_transport("ros2") as t:
            yield t
        return

    with resolve_transport("zenoh", mode="peer", listen=[f"tcp/127.0.0.1:{free_tcp_port()}"], connect=[],
                           multicast_scouting=False) as t:
        yield t


def test_a_channel_conflicting_with_the_live_recipe_is_skipped_and_counted(tmp_path: Path, transport: Any) -> None:
    live = transport.create_publisher(Topic("words", "String"))  # the recipe's own topic, as String
    got: list[Any] = []
    sub = transport.create_subscription(Topic("count", "Int64"), got.append)
    path = _recording(tmp_path / "conflict.mcap",
                      [("words", "Int64", i, 1000 + i) for i in range(5)] + [("count", "Int64", i, 2000 + i)
                                                                           for i in range(5)])
    try:
        with Player(transport, path, rate=None) as player:
            stats = player.play()
        assert stats.published == 5 and stats.per_topic == {"count": 5}
        assert "words" in stats.skipped_topics and "String" in stats.skipped_topics["words"]
        assert stats.skipped_messages == 5
        deadline = time.monotonic() + 5
        while len(got) < 5 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert len(got) == 5
    finally:
        sub.close()
        live.close()


def test_impossible_timestamps_are_refused_and_a_jump_is_not_waited_for(tmp_path: Path) -> None:
    path = _recording(tmp_path / "time.mcap", [
        ("n", "Int64", 1, 1_000), ("n", "Int64", 2, 2_000_000),
        ("n", "Int64", 3, 2**64 - 1),                 # past 2**63 ns: no clock gives it
        ("n", "Int64", 4, 10**18),                    # a jump of 31 years
        ("n", "Int64", 5, 10**18 + 1_000_000)])
    result: dict[str, Any] = {}
    with MemoryTransport() as transport:
        player = Player(transport, path, rate=1.0)

        def play() -> None:
            try:
                result["stats"] = player.play()
            except BaseException as exc:  # what the test reports
                result["error"] = exc

        thread = threading.Thread(target=play, daemon=True)
        start = time.monotonic()
        thread.start()
        thread.join(10)
        player.close()
    assert not thread.is_alive(), "the player waited for a timestamp decades ahead"
    assert "error" not in result, repr(result.get("error"))
    stats = result["stats"]
    assert stats.published == 4 and stats.bad_timestamps == 1 and stats.time_jumps == 1
    assert time.monotonic() - start < 5
