"""The episode recorder stays within its memory bound under a flood of large frames (memory and Zenoh).

A flood of fresh camera frames many times larger than the bound (``buffer_bytes + queue_bytes``)
goes through the recorder; the process's resident memory (``VmRSS``) may grow by the bound and a
fixed allowance for the interpreter and the middleware, never by the flood. While an episode runs
through the flood, it is cut at its size cap with the reason in its sidecar.
"""

from __future__ import annotations

import gc
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents_core import Topic
from agents_core.messages import ImageMsg
from agents_core.transport import MemoryTransport

from ..conftest import free_tcp_port, wait_for

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")

from agents_core.episodes import EpisodeLimits, EpisodeRecorder, load_episodes

REPO = Path(__file__).resolve().parents[2]
MiB = 2**20
FLOOD = Topic("flood", "Image")
SIDE = 256  # 192 kB a frame
FRAMES = 1500  # 281 MiB in all: ~7x the bound below
LIMITS = EpisodeLimits(buffer_s=600.0, buffer_bytes=24 * MiB, queue_bytes=16 * MiB, max_episode_bytes=8 * MiB)
#: What the interpreter, numpy, the MCAP writer and the middleware's own buffers may add.
ALLOWANCE = 64 * MiB


def _rss() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS in /proc/self/status")


def _check(recorder: EpisodeRecorder, before: int, peak: int, received_frames: int) -> None:
    stats = recorder.statistics()
    frame_bytes = SIDE * SIDE * 3
    assert received_frames * frame_bytes > 4 * (LIMITS.buffer_bytes + LIMITS.queue_bytes), \
        f"the flood ({received_frames} frames) was too small to test the bound"
    assert stats.buffered_bytes <= LIMITS.buffer_bytes and stats.evicted_for_bytes > 0, stats
    growth = peak - before
    assert growth <= LIMITS.buffer_bytes + LIMITS.queue_bytes + ALLOWANCE, \
        f"RSS grew by {growth / MiB:.0f} MiB for a bound of {(LIMITS.buffer_bytes + LIMITS.queue_bytes) / MiB:.0f} MiB"


def _cut_episode(directory: Path) -> None:
    (info,) = load_episodes(directory)
    assert info.ended == "size_cap" and "max_episode_bytes=8388608" in str(info.reason), info
    assert info.bytes <= 8 * MiB and info.mcap.stat().st_size <= 8 * MiB + 64 * 1024


def test_a_flood_on_memory_stays_within_the_bound(tmp_path: Path) -> None:
    transport = MemoryTransport()
    recorder = EpisodeRecorder(tmp_path, limits=LIMITS).attach(transport, [FLOOD])
    pub = transport.create_publisher(FLOOD)
    rng = np.random.default_rng(1)
    gc.collect()
    before = peak = _rss()
    try:
        recorder.start_episode("flood")
        for i in range(FRAMES):
            pub.publish(ImageMsg.from_array(rng.integers(0, 255, (SIDE, SIDE, 3), dtype=np.uint8)))
            if i % 25 == 0:
                peak = max(peak, _rss())
        peak = max(peak, _rss())
        assert wait_for(lambda: len(recorder.episodes) == 1, timeout=30)
        _check(recorder, before, peak, recorder.statistics().received)
    finally:
        recorder.close()
        transport.close()
    _cut_episode(tmp_path)


@pytest.mark.zenoh
def test_a_flood_over_zenoh_from_another_process_stays_within_the_bound(tmp_path: Path) -> None:
    pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    log = (tmp_path / "flood.log").open("w")
    child = subprocess.Popen([sys.executable, "-m", "tests.episodes.flood_publisher", "--listen", endpoint,
                              "--frames", str(FRAMES), "--side", str(SIDE)], cwd=REPO, stdout=log,
                             stderr=subprocess.STDOUT)
    transport = None
    recorder = None
    try:
        assert wait_for(lambda: "ready" in (tmp_path / "flood.log").read_text() or child.poll() is not None,
                        timeout=60), "the publisher did not start"
        transport = resolve_transport("zenoh", mode="peer", listen=[], connect=[endpoint], multicast_scouting=False)
        recorder = EpisodeRecorder(tmp_path / "episodes", limits=LIMITS).attach(transport, [FLOOD])
        gc.collect()
        before = peak = _rss()
        recorder.start_episode("flood")
        while child.poll() is None:
            peak = max(peak, _rss())
            wait_for(lambda: child.poll() is not None, timeout=0.05)
        peak = max(peak, _rss())
        assert child.returncode == 0, (tmp_path / "flood.log").read_text()[-2000:]
        assert wait_for(lambda: len(recorder.episodes) == 1, timeout=30)  # type: ignore[union-attr]
        _check(recorder, before, peak, recorder.statistics().received)
    finally:
        if recorder is not None:
            recorder.close()
        if transport is not None:
            transport.close()
        if child.poll() is None:
            child.kill()
        child.wait(timeout=10)
        log.close()
    _cut_episode(tmp_path / "episodes")
