"""Memory suite: observations stored per second and ``semantic_search`` latency, the component against emem directly.

framework: values published on a memory transport to a running Memory component (position + String layer),
until all are committed; ``semantic_search`` through the component's ``execute_method`` service.
raw: ``emem.SpatioTemporalMemory.add`` with the same embeddings (the same hashed bag-of-words client,
called in the same batches), and its ``semantic_search`` called directly.
Run alone: ``python -m benchmarks.memory --values 300``.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .map import _embedder

TEXTS = ["a red cup on the kitchen table", "a person walking in the corridor", "the charging dock by the door",
         "a cat sleeping on the sofa", "a bicycle leaning on the garage wall"]
QUERIES = 50


def unavailable_reason() -> str | None:
    """Why the suite cannot run here, or None."""
    return None if importlib.util.find_spec("emem") else "the memory extra is not installed (emem)"


def raw(n: int, folder: Path) -> dict[str, Any]:
    from emem import SpatioTemporalMemory, SpatioTemporalMemoryConfig  # noqa: PLC0415

    from agents_core.components.memory.engine import ClientEmbedder  # noqa: PLC0415

    embedder = ClientEmbedder(_embedder())
    mem = SpatioTemporalMemory(config=SpatioTemporalMemoryConfig(
        db_path=str(folder / "raw.db"), hnsw_path=str(folder / "raw.hnsw.bin"), embedding_dim=embedder.dim),
        embedding_provider=embedder)
    start = time.perf_counter()
    for i in range(0, n, 5):  # the component's default flush_batch_size: one embedding request per 5
        batch = [f"{TEXTS[(i + k) % len(TEXTS)]} #{i + k}" for k in range(min(5, n - i))]
        for k, (text, vec) in enumerate(zip(batch, embedder.embed(batch), strict=True)):
            mem.add(text, x=0.1 * (i + k), y=0.0, layer_name="heard", embedding=vec)
    mem.save()
    rate = n / (time.perf_counter() - start)
    lat = []
    for q in range(QUERIES):
        t = time.perf_counter()
        mem.semantic_search(query=TEXTS[q % len(TEXTS)], n_results=5)
        lat.append((time.perf_counter() - t) * 1e6)
    mem.close()
    return {"writes_per_s": rate, "search_median_us": statistics.median(lat)}


def framework(n: int, folder: Path) -> dict[str, Any]:
    from agents_core import Launcher, MemoryTransport, Topic  # noqa: PLC0415
    from agents_core.components import MemLayer, Memory  # noqa: PLC0415
    from agents_core.config import MemoryConfig  # noqa: PLC0415
    from agents_core.messages import OdometryMsg, PoseMsg  # noqa: PLC0415

    odom, heard = Topic("odom", "Odometry"), Topic("heard", "String")
    mem = Memory(layers=[MemLayer(subscribes_to=heard, temporal_change=True)], position=odom,
                 embedding_client=_embedder(), config=MemoryConfig(db_path=str(folder / "fw.db"), buffer_size=n + 10),
                 trigger=heard)
    transport = MemoryTransport()
    launcher = Launcher(transport)
    launcher.add_pkg(components=[mem])
    with launcher:
        pub_odom, pub_heard = transport.create_publisher(odom), transport.create_publisher(heard)
        while mem._fix is None:
            pub_odom.publish(OdometryMsg(pose=PoseMsg(position=[0.0, 0.0, 0.0])))
            time.sleep(0.01)
        start = time.perf_counter()
        for i in range(n):
            # A layer keeps its newest value per step: each value is sent once the previous one was taken.
            text = f"{TEXTS[i % len(TEXTS)]} #{i}"
            pub_odom.publish(OdometryMsg(pose=PoseMsg(position=[0.1 * i, 0.0, 0.0])))
            pub_heard.publish(text)
            while mem._last_stored.get("heard", ("",))[0] != text:
                time.sleep(0.0002)
        mem.store_specific_memory("end of the run", x=0.0, y=0.0)  # writes what is still buffered
        while mem.stats["stored"] < n + 1 or mem.stats["pending"]:
            time.sleep(0.001)
            if time.perf_counter() - start > 60:
                raise TimeoutError(f"memory bench: {mem.stats}")
        rate = n / (time.perf_counter() - start)
        lat = []
        for q in range(QUERIES):
            t = time.perf_counter()
            transport.request("memory/execute_method", {"method": "semantic_search",
                                                        "kwargs": {"query": TEXTS[q % len(TEXTS)], "n_results": 5}})
            lat.append((time.perf_counter() - t) * 1e6)
        stats = mem.stats
    transport.close()
    return {"writes_per_s": rate, "search_median_us": statistics.median(lat), "stats": stats}


def run_suite(settings: dict[str, Any], progress: Callable[[str], None],
              ) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Raw then framework, in this process; (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"memory: skipped: {reason}")
        return [], [{"suite": "memory", "transport": "memory", "mode": "both", "reason": reason}]
    n = int(settings.get("map_values", 200))
    records = []
    with tempfile.TemporaryDirectory() as folder:
        for mode, run in (("raw", raw), ("framework", framework)):
            got = run(n, Path(folder))
            records.append({"suite": "memory", "transport": "memory", "payload": "string", "mode": mode, **got})
            progress(f"{'memory':<10} {'memory':<6} {mode:<9} {got['writes_per_s']:8.1f} obs/s  "
                     f"search {got['search_median_us']:8.0f} us")
    return records, []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--values", type=int, default=300)
    args = parser.parse_args(argv)
    records, _ = run_suite({"map_values": args.values}, print)
    fw, rw = records[1], records[0]
    print(f"stored/s framework / raw = {fw['writes_per_s'] / rw['writes_per_s']:.2f}; "
          f"semantic_search latency framework / raw = {fw['search_median_us'] / rw['search_median_us']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
