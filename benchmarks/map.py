"""The map path: layer values written per second through MapEncoding into a local Chroma server, against the
same values written directly with the ChromaClient.

One child process starts ``chroma run`` (from this environment's chromadb, data in a temporary folder,
telemetry off) and measures, with the same embedding client (hashed bag of words: the model is not what
is measured here, and a real one would cost the same on both sides):

- raw: for each value, one ``ChromaClient.add`` with its id, text and map metadata (what an application
  without MapEncoding would write).
- framework: the values published as Detections on the memory transport (odometry alongside) to a
  MapEncoding with an accumulating layer triggered by that topic, each value once the previous one is in
  the database (one write per value, as raw); the clock stops when every value is in the database.

MapEncoding writes whatever has arrived since its last write in one request, so values published as fast
as possible are batched: that rate is recorded as ``burst_writes_per_s`` (framework only, not compared:
raw writes one value per request).

rate = values / seconds (higher is better). ``python -m benchmarks.map --values N --reps R`` is the child;
:func:`run_suite` runs it.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import logging
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, MutableMapping
from pathlib import Path
from typing import Any

from .common import ChildFailed, Children, available, child_env, emit, free_tcp_port, log

LABELS = ["cup", "chair", "table", "person", "door", "plant", "bottle", "laptop"]


def unavailable_reason() -> str | None:
    """Why the map suite cannot run here, or None."""
    if not available("chromadb") or not Path(sys.executable).with_name("chroma").exists():
        return "chromadb (its `chroma` server) is not installed next to this Python"
    return None


@contextlib.contextmanager
def chroma_server() -> Iterator[int]:
    """A local Chroma server on a free port; stopped by its process group id."""
    port = free_tcp_port()
    import httpx  # noqa: PLC0415

    with tempfile.TemporaryDirectory() as data:
        env = {**os.environ, "ANONYMIZED_TELEMETRY": "False"}
        proc = subprocess.Popen([str(Path(sys.executable).with_name("chroma")), "run", "--host", "127.0.0.1",
                                 "--port", str(port), "--path", str(Path(data) / "db")],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True)
        try:
            deadline = time.monotonic() + 60
            while True:
                with contextlib.suppress(httpx.TransportError):
                    if httpx.get(f"http://127.0.0.1:{port}/api/v2/heartbeat", timeout=1.0).is_success:
                        break
                if time.monotonic() > deadline or proc.poll() is not None:
                    raise RuntimeError("chroma did not start")
                time.sleep(0.1)
            yield port
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=10)


def _embedder() -> Any:
    from agents_core.clients import ModelClient  # noqa: PLC0415
    from agents_core.models import GenericLLM  # noqa: PLC0415

    class HashEmbeddings(ModelClient):
        """Hashed bag-of-words vectors (64 dims): a cheap, deterministic embedding model."""

        def _check_connection(self) -> None: ...
        def _initialize(self) -> None: ...
        def _deinitialize(self) -> None: ...

        def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
            return None

        def _embed(self, texts: list[str]) -> list[list[float]]:
            vectors = []
            for text in texts:
                vec = [0.0] * 64
                for word in re.findall(r"[a-z]+", text.lower()):
                    vec[int(hashlib.md5(word.encode()).hexdigest(), 16) % 64] += 1.0
                norm = math.sqrt(sum(x * x for x in vec)) or 1.0
                vectors.append([x / norm for x in vec])
            return vectors

    return HashEmbeddings(GenericLLM(name="hash", checkpoint="hash-64"))


def _client(port: int, collection: str) -> Any:
    from agents_core.clients import ChromaClient  # noqa: PLC0415
    from agents_core.vectordbs import ChromaDB  # noqa: PLC0415

    client = ChromaClient(ChromaDB(name="bench", collection_name=collection), port=port,
                          embedding_client=_embedder(), response_timeout=30)
    client.check_connection()
    client.initialize()
    return client


def _values(n: int) -> list[tuple[float, float, str]]:
    return [(0.1 * (i % 50), 0.1 * (i // 50 % 20), LABELS[i % len(LABELS)]) for i in range(n)]


def raw(port: int, n: int, collection: str) -> float:
    client = _client(port, collection)
    start = time.perf_counter()
    for i, (x, y, label) in enumerate(_values(n)):
        cell = (int(x / 0.1), int(y / 0.1))
        client.add({"collection_name": collection, "ids": [f"seen:{cell[0]}:{cell[1]}:{i}"], "documents": [label],
                    "metadatas": [{"layer": "seen", "cell_x": cell[0], "cell_y": cell[1], "x": x, "y": y,
                                   "stamp": time.time(), "frame_id": "map"}]})
    seconds = time.perf_counter() - start
    client.deinitialize()
    return n / seconds


def framework(port: int, n: int, collection: str, paced: bool = True) -> float:
    import numpy as np  # noqa: PLC0415

    from agents_core import Launcher, MemoryTransport, Topic  # noqa: PLC0415
    from agents_core.components import MapEncoding, MapLayer  # noqa: PLC0415
    from agents_core.config import MapConfig  # noqa: PLC0415
    from agents_core.messages import DetectionsMsg, Header, OccupancyGridMsg, OdometryMsg, PoseMsg  # noqa: PLC0415
    from agents_core.topics import QoSConfig  # noqa: PLC0415

    grid_topic = Topic("map", "OccupancyGrid", qos_profile=QoSConfig(durability="transient_local", depth=1))
    odom_topic, seen_topic = Topic("odom", "Odometry"), Topic("seen", "Detections")
    transport = MemoryTransport()
    transport.create_publisher(grid_topic).publish(OccupancyGridMsg(
        data=np.zeros((40, 60), np.int8), resolution=0.1, origin=PoseMsg(position=[-0.5, -0.5, 0.0]),
        header=Header(frame_id="map")))
    mapper = MapEncoding(layers=[MapLayer(subscribes_to=seen_topic)], position=odom_topic, map_topic=grid_topic,
                         db_client=_client(port, collection), trigger=seen_topic,
                         config=MapConfig(map_name=collection, buffer_size=max(n, 1000), position_timeout=60.0))
    launcher = Launcher(transport)
    launcher.add_pkg(components=[mapper])
    odom, seen = transport.create_publisher(odom_topic), transport.create_publisher(seen_topic)
    values = _values(n)
    try:
        with launcher:
            start = time.perf_counter()
            for i, (x, y, label) in enumerate(values):
                odom.publish(OdometryMsg(pose=PoseMsg(position=[x, y, 0.0]), header=Header(frame_id="map")))
                seen.publish(DetectionsMsg(boxes=[[0, 0, 5, 5]], labels=[label], scores=[0.9]))
                while paced and mapper.stats["written"] <= i and time.perf_counter() - start < 300:
                    time.sleep(0.0002)
            deadline = time.monotonic() + 300
            while mapper.stats["written"] < n and time.monotonic() < deadline:
                time.sleep(0.001)
            seconds = time.perf_counter() - start
            stats = mapper.stats
    finally:
        transport.close()
    if stats["written"] != n:
        raise RuntimeError(f"MapEncoding wrote {stats['written']} of {n} values: {stats}")
    return n / seconds


def run_child(n: int, reps: int) -> None:
    with chroma_server() as port:
        measures: tuple[tuple[str, Callable[[int, int, str], float]], ...] = (("raw", raw), ("framework", framework))
        for mode, measure in measures:
            rates = [measure(port, n, f"bench_{mode}_{rep}") for rep in range(reps)]
            record = {"suite": "map", "transport": "memory", "payload": "detections_to_chroma", "mode": mode,
                      "writes_per_s": statistics.median(rates), "values": n, "reps": reps}
            if mode == "framework":
                record["burst_writes_per_s"] = statistics.median(
                    framework(port, n, f"bench_burst_{rep}", paced=False) for rep in range(reps))
            emit(record)


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The map child (raw then framework); (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"map: skipped: {reason}")
        return [], [{"suite": "map", "transport": "memory", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    try:
        child = children.start("map", ["-m", "benchmarks.map", "--values", str(settings.get("map_values", 200)),
                                       "--reps", str(settings.get("map_reps", 1))], child_env())
        records += list(child.records(timeout=600))
        children.stop(child)
        for r in records:
            progress(f"{'map':<10} {'memory':<6} {r['mode']:<9} {r['writes_per_s']:8.1f} writes/s")
    except ChildFailed as exc:
        progress(f"map: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": "map", "transport": "memory", "mode": "both", "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--values", type=int, default=200)
    parser.add_argument("--reps", type=int, default=1)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    run_child(args.values, args.reps)
    log("map done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
