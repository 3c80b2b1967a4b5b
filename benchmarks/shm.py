"""Large values between two processes on one host: the framework's Zenoh shared memory against raw zenoh-python.

``python -m benchmarks.shm [--quick] [--rounds N]`` runs, for a 640x480 rgb8 image (921,600 B) and a
1 MiB PointCloud2 (65,536 points of x, y, z, intensity float32), the hop (round trip through a relay
process, one value in flight) and the throughput (8 in flight) of five modes, interleaved (the
order rotates each round), and prints every figure with its baseline:

- ``fw``: the framework (a relay component under ``Launcher``, the transport's publisher and
  subscription in the pinger) with the default ``ZenohConfig`` (Zenoh's shared-memory transport on,
  no pool of its own: Zenoh's transport optimisation moves the bytes);
- ``fw_pool``: the same putting values of 64 KiB or more from its own pool (``shm_threshold=65536``);
  ``fw_pool`` ÷ ``fw`` is what the pool itself adds;
- ``fw_noshm``: the same with ``ZenohConfig(shared_memory=False)``;
- ``raw_noshm``: zenoh-python alone with ``transport/shared_memory/enabled: false`` (the network path);
- ``raw_default``: zenoh-python's default configuration (its transport optimisation moves payloads
  above 3 KB through shared memory, with a copy on each side);
- ``raw_shm``: zenoh-python publishing from its own ``ShmProvider`` blocks on both sides (what a
  hand-written program gets at best).

Raw payloads are an 8-byte sequence number followed by the array's bytes, received with ``to_bytes``
and viewed with ``np.frombuffer``; the raw relay copies each sample out (``to_bytes``) and puts it back.
The ratios are framework / raw of the medians over rounds; a range is the min..max of the rounds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import struct
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

from .common import READY, Children, StopFlag, child_env, emit, free_tcp_port, zenoh_raw_config
from .hop import await_echo, measure_latency
from .throughput import measure_throughput

MODES = ("fw", "raw_noshm", "fw_noshm", "raw_default", "fw_pool", "raw_shm")
TOPICS = {"image": ("shm/img_in", "shm/img_out"), "cloud": ("shm/pc_in", "shm/pc_out")}
CLOUD_POINTS = 65_536
SIZES = {"image": 640 * 480 * 3, "cloud": CLOUD_POINTS * 16}


def _arrays() -> dict[str, Any]:
    import numpy as np  # noqa: PLC0415

    image = (np.arange(SIZES["image"], dtype=np.uint32) % 251).astype(np.uint8).reshape(480, 640, 3)
    cloud = np.zeros(CLOUD_POINTS, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])
    for i, name in enumerate(("x", "y", "z", "intensity")):
        cloud[name] = np.arange(CLOUD_POINTS, dtype=np.float32) * (i + 1)
    return {"image": image, "cloud": cloud}


def _raw_config(mode: str, listen: list[str], connect: list[str]) -> Any:
    conf = zenoh_raw_config(listen, connect)
    if mode == "raw_noshm":
        conf.insert_json5("transport/shared_memory/enabled", "false")
    return conf


def _fw_options(mode: str, listen: list[str], connect: list[str], namespace: str) -> dict[str, Any]:
    options: dict[str, Any] = {"mode": "peer", "listen": listen, "connect": connect, "namespace": namespace,
                               "multicast_scouting": False, "shared_memory": mode != "fw_noshm"}
    if mode == "fw_pool":
        options["shm_threshold"] = 65_536
    return options


class _Putter:
    """Puts bytes on a raw publisher, from a shared-memory block of its own in ``raw_shm`` mode."""

    def __init__(self, pub: Any, mode: str) -> None:
        self._pub = pub
        self._provider: Any = None
        if mode == "raw_shm":
            from zenoh import shm  # noqa: PLC0415

            self._provider = shm.ShmProvider.default_backend(32 * 1024 * 1024)
            self._policy = shm.GarbageCollect()

    def put(self, data: bytes | bytearray) -> None:
        if self._provider is None:
            self._pub.put(data)
            return
        import zenoh  # noqa: PLC0415

        block = self._provider.alloc(len(data), self._policy)
        block[0:len(data)] = data
        self._pub.put(zenoh.ZBytes(block))


# -- the relay process ----------------------------------------------------------------------------


def _relay(mode: str, listen: str, namespace: str) -> None:
    stop = StopFlag()
    if mode.startswith("fw"):
        from agents_core import Component, Launcher, Topic  # noqa: PLC0415
        from agents_core.supported_types import Image, PointCloud2  # noqa: PLC0415

        class ShmRelay(Component):
            def __init__(self) -> None:
                self.allowed_inputs = {"Required": [Image, PointCloud2]}
                self.allowed_outputs = {"Required": [Image, PointCloud2]}
                inputs = [Topic(TOPICS["image"][0], "Image"), Topic(TOPICS["cloud"][0], "PointCloud2")]
                outputs = [Topic(TOPICS["image"][1], "Image"), Topic(TOPICS["cloud"][1], "PointCloud2")]
                self._route = {TOPICS[k][0]: TOPICS[k][1] for k in TOPICS}
                super().__init__(inputs=inputs, outputs=outputs, trigger=inputs, component_name="shm_relay")

            def _execution_step(self, **kwargs: Any) -> None:
                topic = kwargs["topic"]
                self.publishers_dict[self._route[topic.name]].publish(self.trig_callbacks[topic.name].msg)

        launcher = Launcher(transport="zenoh", transport_options=_fw_options(mode, [listen], [], namespace))
        launcher.add_pkg(components=[ShmRelay()])
        launcher.start()
        try:
            print(READY, flush=True)
            while not stop.wait(0.5):
                pass
        finally:
            launcher.stop()
        return
    import zenoh  # noqa: PLC0415

    session = zenoh.open(_raw_config(mode, [listen], []))
    try:
        subs = []
        for inp, out in TOPICS.values():
            putter = _Putter(session.declare_publisher(f"{namespace}/{out}",
                                                       congestion_control=zenoh.CongestionControl.BLOCK), mode)

            def echo(sample: Any, putter: _Putter = putter) -> None:
                putter.put(sample.payload.to_bytes())

            subs.append(session.declare_subscriber(f"{namespace}/{inp}", echo))
        print(READY, flush=True)
        while not stop.wait(0.5):
            pass
    finally:
        session.close()


# -- the pinger process ---------------------------------------------------------------------------


class _FwChannel:
    def __init__(self, bus: Any, payload: str, array: Any) -> None:
        from agents_core import Topic  # noqa: PLC0415
        from agents_core.messages import Header, ImageMsg, PointCloud2Msg  # noqa: PLC0415

        self.payload = payload
        self.on_reply: Any = lambda seq: None
        type_name = "Image" if payload == "image" else "PointCloud2"
        if payload == "image":
            self._make: Any = lambda seq: ImageMsg(data=array, encoding="rgb8", header=Header(frame_id=str(seq)))
        else:
            self._make = lambda seq: PointCloud2Msg(points=array, header=Header(frame_id=str(seq)))
        inp, out = TOPICS[payload]
        self._pub = bus.create_publisher(Topic(inp, type_name))
        self._sub = bus.create_subscription(Topic(out, type_name), self._on_value, inline=True)

    def send(self, seq: int) -> None:
        self._pub.publish(self._make(seq))

    def _on_value(self, value: Any) -> None:
        self.on_reply(int(value.header.frame_id))

    def close(self) -> None:
        self._sub.close()
        self._pub.close()


class _RawChannel:
    def __init__(self, session: Any, namespace: str, payload: str, array: Any, mode: str) -> None:
        import numpy as np  # noqa: PLC0415
        import zenoh  # noqa: PLC0415

        self.payload = payload
        self.on_reply: Any = lambda seq: None
        self._np, self._dtype = np, array.dtype
        self._flat = array.reshape(-1).view(np.uint8)
        self._buffer = bytearray(8 + self._flat.nbytes)
        inp, out = TOPICS[payload]
        self._putter = _Putter(session.declare_publisher(f"{namespace}/{inp}",
                                                         congestion_control=zenoh.CongestionControl.BLOCK), mode)
        self._sub = session.declare_subscriber(f"{namespace}/{out}", self._on_sample)

    def send(self, seq: int) -> None:
        memoryview(self._buffer)[8:] = self._flat
        struct.pack_into("<Q", self._buffer, 0, seq)
        self._putter.put(self._buffer)

    def _on_sample(self, sample: Any) -> None:
        data = sample.payload.to_bytes()
        view = self._np.frombuffer(data, self._dtype, offset=8)
        if view.nbytes == self._flat.nbytes:
            self.on_reply(struct.unpack_from("<Q", data)[0])

    def close(self) -> None:
        self._sub.undeclare()


def _pinger(mode: str, connect: str, namespace: str, counts: tuple[int, int], seconds: float) -> None:
    arrays = _arrays()
    closers: list[Any] = []
    channels: list[Any] = []
    try:
        if mode.startswith("fw"):
            from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

            bus = resolve_transport("zenoh", **_fw_options(mode, [], [connect], namespace))
            closers.append(bus.close)
            channels = [_FwChannel(bus, p, arrays[p]) for p in TOPICS]
        else:
            import zenoh  # noqa: PLC0415

            session = zenoh.open(_raw_config(mode, [], [connect]))
            closers.append(session.close)
            channels = [_RawChannel(session, namespace, p, arrays[p], mode) for p in TOPICS]
        for channel in channels:
            await_echo(channel)
            lat = measure_latency(channel, warmup=counts[0], count=counts[1], max_seconds=60.0)
            emit({"suite": "shm_hop", "payload": channel.payload, "median_us": lat["rtt"]["median_us"],
                  "p99_us": lat["rtt"]["p99_us"], "lost": lat["lost"]})
        import benchmarks.throughput as tp  # noqa: PLC0415

        tp.PAYLOADS.update(SIZES)
        for channel in channels:
            res = measure_throughput(channel, seconds=seconds, max_messages=1_000_000, warmup_seconds=0.3,
                                     base_seq=10_000_000)
            emit({"suite": "shm_throughput", "payload": channel.payload, "mb_per_s": res["mb_per_s"],
                  "lost": res["lost"]})
    finally:
        for channel in channels:
            channel.close()
        for close in reversed(closers):
            close()


# -- orchestration --------------------------------------------------------------------------------


def run(rounds: int, counts: tuple[int, int], seconds: float, log_dir: Path,
        modes: tuple[str, ...] = MODES) -> list[dict[str, Any]]:
    """Every mode once per round (the order rotating), each in a fresh relay + pinger pair; the records."""
    records: list[dict[str, Any]] = []
    children = Children(log_dir)
    try:
        for round_no in range(rounds):
            order = modes[round_no % len(modes):] + modes[:round_no % len(modes)]
            for mode in order:
                port = free_tcp_port()
                endpoint, namespace = f"tcp/127.0.0.1:{port}", f"shmbench{port}"
                env = child_env()
                relay = children.start(f"relay-{mode}-{round_no}", ["-m", "benchmarks.shm", "relay", mode,
                                                                    endpoint, namespace], env)
                try:
                    relay.wait_ready(60.0)
                    pinger = children.start(f"pinger-{mode}-{round_no}", [
                        "-m", "benchmarks.shm", "pinger", mode, endpoint, namespace,
                        f"{counts[0]},{counts[1]}", str(seconds)], env)
                    for record in pinger.records(timeout=120.0):
                        record.update(mode=mode, round=round_no)
                        records.append(record)
                        print(json.dumps(record), file=sys.stderr, flush=True)
                    children.stop(pinger)
                finally:
                    children.stop(relay)
    finally:
        children.stop_all()
    return records


def summarize(records: list[dict[str, Any]]) -> list[str]:
    """Lines: each mode's median and range per figure, then the framework ÷ each baseline."""
    lines = []
    for suite, key, better in (("shm_hop", "median_us", "lower"), ("shm_throughput", "mb_per_s", "higher")):
        for payload in TOPICS:
            per_mode: dict[str, list[float]] = {}
            per_round: dict[int, dict[str, float]] = {}
            for r in records:
                if r["suite"] == suite and r["payload"] == payload:
                    per_mode.setdefault(r["mode"], []).append(r[key])
                    per_round.setdefault(r["round"], {})[r["mode"]] = r[key]
            for mode, vals in per_mode.items():
                lines.append(f"{suite} {payload} {mode}: median {statistics.median(vals):.1f} "
                             f"range {min(vals):.1f}..{max(vals):.1f} {key} ({better} is better)")
            for fw in ("fw", "fw_noshm", "fw_pool"):
                for base in ("raw_noshm", "raw_default", "raw_shm"):
                    ratios = [v[fw] / v[base] for v in per_round.values() if fw in v and base in v]
                    if ratios:
                        lines.append(f"  {suite} {payload} {fw} / {base}: median {statistics.median(ratios):.2f} "
                                     f"range {min(ratios):.2f}..{max(ratios):.2f}")
    return lines


#: (framework mode, raw baseline) pairs the runner reports as framework ÷ raw.
PAIRS = (("fw", "raw_noshm"), ("fw", "raw_default"), ("fw", "raw_shm"), ("fw_pool", "raw_shm"),
         ("fw_noshm", "raw_noshm"))


def as_figures(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records in the runner's form: per (framework mode, baseline) and payload one framework and one raw
    record (``payload`` names both, e.g. ``image_fw_vs_raw_noshm``), medians over the rounds."""
    out = []
    for fw, base in PAIRS:
        for payload in TOPICS:
            for mode, source in (("framework", fw), ("raw", base)):
                hops = [r["median_us"] for r in records if r["suite"] == "shm_hop" and r["mode"] == source
                        and r["payload"] == payload]
                rates = [r["mb_per_s"] for r in records if r["suite"] == "shm_throughput" and r["mode"] == source
                         and r["payload"] == payload]
                if hops and rates:
                    out.append({"suite": "shm", "transport": "zenoh", "payload": f"{payload}_{fw}_vs_{base}",
                                "mode": mode, "rtt_median_us": statistics.median(hops),
                                "mb_per_s": statistics.median(rates), "rounds": len(hops), "source_mode": source})
    return out


def run_suite(settings: dict[str, Any], children: Children,
              progress: Any) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """What ``benchmarks.run`` calls: every mode, ``settings["rounds"]`` rounds; (records, skipped)."""
    from .common import ChildFailed, available  # noqa: PLC0415

    if not available("zenoh"):
        return [], [{"suite": "shm", "transport": "zenoh", "mode": "both", "reason": "zenoh is not installed"}]
    quick = settings.get("rounds", 1) <= 1
    counts, seconds = ((10, 60), 1.0) if quick else ((30, 300), 3.0)
    try:
        raw_records = run(int(settings.get("rounds", 1)), counts, seconds, children.log_dir)
    except ChildFailed as exc:
        progress(f"shm: FAILED: {str(exc).splitlines()[0]}")
        return [], [{"suite": "shm", "transport": "zenoh", "mode": "both", "reason": str(exc)[-1500:]}]
    for line in summarize(raw_records):
        progress(f"shm        {line}")
    return as_figures(raw_records), []


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] == "relay":
        _relay(args[1], args[2], args[3])
        return 0
    if args and args[0] == "pinger":
        warm, count = (int(x) for x in args[4].split(","))
        _pinger(args[1], args[2], args[3], (warm, count), float(args[5]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--rounds", type=int)
    parser.add_argument("--modes", default=",".join(MODES), help="comma-separated subset of " + ",".join(MODES))
    opts = parser.parse_args(args)
    rounds = opts.rounds or (1 if opts.quick else 3)
    counts, seconds = ((10, 60), 1.0) if opts.quick else ((30, 300), 3.0)
    with tempfile.TemporaryDirectory(prefix="shm-bench-") as logs:
        records = run(rounds, counts, seconds, Path(logs), tuple(opts.modes.split(",")))
    for line in summarize(records):
        print(line)
    return 0


if __name__ == "__main__":
    threading.current_thread().name = "shm-bench"
    sys.exit(main())
