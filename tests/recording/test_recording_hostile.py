"""A recorder killed with SIGKILL leaves a readable file; broken files and oversized messages are refused, counted.

The SIGKILL test runs ``agentsctl record`` in its own process on Zenoh (connected to this
process's session, which publishes a counter), kills it mid-run, and reads what it flushed with the
``mcap`` package's stream reader (not our code) and with :func:`read_recording`.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from agents_core import Topic
from agents_core.messages import Header, ImageMsg
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.recipes import recipe_environment
from agents_core.transport.registry import resolve_transport

from ..conftest import wait_for

pytest.importorskip("mcap.writer", reason="pip install 'agents-core[record]'")
from mcap import exceptions as mcap_exceptions
from mcap import records as mcap_records
from mcap.stream_reader import StreamReader

from agents_core.recording import (
    Player,
    ReadSummary,
    Recorder,
    RecordingError,
    RecordingLimits,
    read_recording,
)

TICKS = Topic("ticks", "Int64")
REPO = Path(__file__).resolve().parents[2]


def _flushed_messages(path: Path) -> tuple[list[int], bool]:
    """(the values of the complete Message records, whether the stream ended early), by the mcap package alone."""
    values: list[int] = []
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, mcap_records.Message):
                    values.append(record.log_time)
        except mcap_exceptions.EndOfFile:
            return values, True
    return values, False


def _recording(tmp_path: Path, count: int = 50, **options: object) -> Path:
    transport = resolve_transport("memory")
    pub = transport.create_publisher(TICKS)
    path = tmp_path / "ticks.mcap"
    with Recorder(transport, path, topics=[TICKS], encoding="msgpack", **options):  # type: ignore[arg-type]
        for i in range(count):
            pub.publish(i)
    transport.close()
    return path


@pytest.mark.zenoh
def test_sigkill_leaves_the_flushed_chunks_readable(tmp_path: Path) -> None:
    pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    here = resolve_transport("zenoh", mode="peer", listen=[endpoint], connect=[], multicast_scouting=False)
    out = tmp_path / "killed.mcap"
    log = open(tmp_path / "recorder.log", "wb")  # noqa: SIM115 - closed below
    recorder = subprocess.Popen([sys.executable, "-m", "agents_core.cli", "record", str(out), "-T", "ticks",
                                 "-t", "zenoh", "--connect", endpoint, "--encoding", "msgpack"],
                                cwd=REPO, env=recipe_environment(), stdout=log, stderr=subprocess.STDOUT)
    try:
        pub = here.create_publisher(TICKS)
        deadline = time.monotonic() + 30
        sent = 0
        # Publish until the recorder has flushed a few chunks (its flush interval is 1 s).
        while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < 2000 or sent < 100):
            pub.publish(sent)
            sent += 1
            time.sleep(0.01)
        time.sleep(1.5)
        assert recorder.poll() is None, (tmp_path / "recorder.log").read_text()
        os.kill(recorder.pid, signal.SIGKILL)
        recorder.wait(timeout=10)
    finally:
        if recorder.poll() is None:
            os.kill(recorder.pid, signal.SIGKILL)
            recorder.wait(timeout=10)
        log.close()
        here.close()
    times, cut = _flushed_messages(out)
    assert cut, "a killed recorder cannot have written the footer"
    assert 10 <= len(times) <= sent, (len(times), sent)
    summary = ReadSummary()
    values = [m.value for m in read_recording(out, summary=summary)]
    assert summary.truncated and len(values) == len(times)
    assert values == sorted(values) and len(set(values)) == len(values)  # the counter, in order, no repeats


def test_a_truncated_file_plays_up_to_its_cut(tmp_path: Path) -> None:
    path = _recording(tmp_path, chunk_size=200)
    whole = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[: len(whole) // 3])
    memory = resolve_transport("memory")
    got: list[int] = []
    memory.create_subscription(TICKS, got.append, inline=True)  # no delivery queue that could drop
    with Player(memory, cut, rate=None) as player:
        stats = player.play()
    assert stats.read.truncated and 0 < stats.published < 50
    assert wait_for(lambda: len(got) == stats.published, timeout=5)
    assert got == list(range(stats.published))
    memory.close()


@pytest.mark.parametrize("damage", ["garbage", "bad_crc", "huge_length"])
def test_a_corrupt_file_is_refused_with_a_reason(tmp_path: Path, damage: str) -> None:
    path = _recording(tmp_path)
    data = bytearray(path.read_bytes())
    if damage == "garbage":
        data = bytearray(os.urandom(4096))
    elif damage == "bad_crc":
        # The first chunk's compressed bytes sit well inside the file: flip a few of them.
        for i in range(200, 220):
            data[i] ^= 0xFF
    else:
        # The first record after the magic (the header) declares an absurd length.
        data[9:17] = (2**62).to_bytes(8, "little")
    broken = tmp_path / f"{damage}.mcap"
    broken.write_bytes(bytes(data))
    memory = resolve_transport("memory")
    with Player(memory, broken, rate=None, max_record_bytes=2**20) as player, pytest.raises(RecordingError):
        player.play()
    memory.close()


def test_a_message_over_the_size_limit_is_skipped_and_counted(tmp_path: Path) -> None:
    transport = resolve_transport("memory")
    camera = Topic("camera", "Image")
    pub = transport.create_publisher(camera)
    path = tmp_path / "big.mcap"
    small = np.zeros((8, 8, 3), np.uint8)
    huge = np.zeros((1000, 1000, 3), np.uint8)
    with Recorder(transport, path, topics=[camera], encoding="msgpack",
                  limits=RecordingLimits(max_message_bytes=100_000)) as recorder:
        for i, pixels in enumerate([small, huge, small]):
            pub.publish(ImageMsg(data=pixels, encoding="rgb8", header=Header(stamp_ns=i + 1)))
    stats = recorder.statistics()
    transport.close()
    assert (stats.received, stats.written, stats.oversize) == (3, 2, 1)
    assert [m.value.header.stamp_ns for m in read_recording(path)] == [1, 3]


def test_size_limits_split_files_and_stop_the_recording(tmp_path: Path) -> None:
    path = _recording(tmp_path, count=200, chunk_size=100,
                      limits=RecordingLimits(max_file_bytes=2000, max_total_bytes=5000))
    files = sorted(tmp_path.glob("ticks*.mcap"))
    assert len(files) >= 2 and files[0] == path
    counts = [len(list(read_recording(f))) for f in files]
    assert 0 < sum(counts) < 200
    for f in files:
        _, cut = _flushed_messages(f)
        assert not cut  # every file of a stopped recorder is finished


@pytest.mark.zenoh
def test_agentsctl_play_publishes_a_recording_on_zenoh_with_a_remap(tmp_path: Path) -> None:
    pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")
    path = _recording(tmp_path, count=30)
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    got: list[int] = []
    with resolve_transport("zenoh", mode="peer", listen=[endpoint], connect=[], multicast_scouting=False) as here:
        here.create_subscription(Topic("counter", "Int64"), got.append, inline=True)
        done = subprocess.run([sys.executable, "-m", "agents_core.cli", "play", str(path), "-t", "zenoh",
                               "--connect", endpoint, "-r", "0", "--remap", "ticks:=counter", "--wait", "2",
                               "--json"], cwd=REPO, env=recipe_environment(), capture_output=True, timeout=60,
                              check=False)
        assert done.returncode == 0, done.stderr.decode()[-2000:]
        assert wait_for(lambda: len(got) == 30, timeout=10), got
    assert got == list(range(30))
    assert b'"published": 30' in done.stdout
