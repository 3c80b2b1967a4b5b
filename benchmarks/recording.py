"""What recording costs a recipe, and how faithfully a recording plays back.

- **Overhead**: the throughput of a hop (``EchoRelay`` on the memory transport, in this process: a
  value in, the same value out, a window of 8 in flight) without a recorder (``raw``) and with a
  :class:`~agents_core.recording.Recorder` writing every topic of the hop and the relay's status
  into MCAP (``framework``), for the 64-byte String and the 640x480x3 Image. The two modes alternate
  round by round; the ratio framework / raw is the throughput kept (target ≥ 0.95). Memory is the
  hardest case: the recorder shares the recipe's process, its GIL and (here) two cores.
- **Playback**: 300 Strings recorded at 100 Hz, played back at the recorded pace by
  :class:`~agents_core.recording.Player`; p50 / p99 lateness against the recorded schedule (ms).

``python -m benchmarks.recording [--seconds 2] [--rounds 3]`` prints the figures; ``benchmarks.run``
runs it as the ``recording`` suite.
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import REPO, TOPICS, available, child_env, free_tcp_port, image_pixels, string_payload

WINDOW = 8
#: The paced runs: no recorder, then a recorder with each chunk compression.
PACED_MODES = ["raw", "recorder-zstd", "recorder-lz4", "recorder-none"]


def unavailable_reason() -> str | None:
    """Why the suite cannot run here, or None."""
    if not available("mcap"):
        return "the record extra is not installed (pip install 'agents-core[record]')"
    return None


def _hop_throughput(payload: str, seconds: float, record_to: Path | None, transport_name: str = "memory") -> float:
    """Messages per second through the relay, with a recorder writing to ``record_to`` if given.

    Memory: the recorder runs in this process on the launcher's transport. Zenoh: the recipe listens
    on a loopback endpoint and ``agentsctl record`` runs in a process of its own, connected to it.
    """
    from agents_core import Launcher, Topic  # noqa: PLC0415
    from agents_core.messages import Header, ImageMsg  # noqa: PLC0415
    from agents_core.recording import Recorder  # noqa: PLC0415

    from .parts import EchoRelay  # noqa: PLC0415

    topic_in, topic_out = TOPICS[payload]
    msg_type = "String" if payload == "string64" else "Image"
    value: Any = string_payload(0) if payload == "string64" else ImageMsg(data=image_pixels(), encoding="rgb8",
                                                                          header=Header(stamp_ns=1))
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    options = ({"mode": "peer", "listen": [endpoint], "connect": [], "multicast_scouting": False}
               if transport_name == "zenoh" else {})
    launcher = Launcher(transport_name, transport_options=options)
    launcher.add_pkg(components=[EchoRelay()])
    child: subprocess.Popen[bytes] | None = None
    slots = threading.Semaphore(WINDOW)
    done = [0]

    def back(_value: Any) -> None:
        done[0] += 1
        slots.release()

    with launcher:
        transport = launcher.transport
        recorder = None
        if record_to is not None and transport_name == "memory":
            recorder = Recorder(transport, record_to, discover_every_s=0.5).start()
        elif record_to is not None:
            child = subprocess.Popen([sys.executable, "-m", "agents_core.cli", "record", str(record_to), "-t", "zenoh",
                                      "--connect", endpoint, "-T", topic_in, "-T", topic_out, "--json"],
                                     cwd=REPO, env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        if transport_name == "zenoh":
            time.sleep(3.0)  # both modes: discovery settles (and the recorder subscribes) before measuring
        sub = transport.create_subscription(Topic(topic_out, msg_type), back, inline=True)
        pub = transport.create_publisher(Topic(topic_in, msg_type))
        try:
            for warm_up in (True, False):
                done[0] = 0
                start = time.monotonic()
                until = start + (0.3 if warm_up else seconds)
                while time.monotonic() < until:
                    if slots.acquire(timeout=1.0):
                        pub.publish(value)
                rate = done[0] / (time.monotonic() - start)
        finally:
            sub.close()
            pub.close()
            if recorder is not None:
                stats = recorder.stop()
                if stats.dropped:
                    print(f"recording: the recorder dropped {stats.dropped} values", file=sys.stderr)
            if child is not None:
                child.send_signal(signal.SIGINT)
                out, _ = child.communicate(timeout=60)
                print(f"recording: agentsctl record: {out.decode().strip()[-300:]}", file=sys.stderr)
        # Let the last window drain before the next round starts.
        for _ in range(WINDOW):
            slots.acquire(timeout=1.0)
    return rate


def _paced_hop(seconds: float, record_to: Path | None, compression: str = "lz4") -> dict[str, float]:
    """A realistic load through the relay on memory: a 30 Hz 640x480 camera and a 100 Hz String.

    Returns the share of the values that came back (``kept``), the camera hop's p50 / p99 latency
    (ms) and the process's CPU use (``cpu``, in cores) over the run, with a recorder of every topic
    (``compression`` per chunk) when ``record_to`` is given. At this pace the hop is not saturated,
    so the recorder's cost shows as CPU and latency, not as lost throughput.
    """
    from agents_core import Launcher, Topic  # noqa: PLC0415
    from agents_core.messages import Header, ImageMsg  # noqa: PLC0415
    from agents_core.recording import Recorder  # noqa: PLC0415

    from .parts import EchoRelay  # noqa: PLC0415

    (str_in, str_out), (img_in, img_out) = TOPICS["string64"], TOPICS["image640x480"]
    pixels = image_pixels()
    latencies: list[float] = []
    back = [0]

    def image_back(value: Any) -> None:
        latencies.append(time.monotonic_ns() - value.header.stamp_ns)
        back[0] += 1

    def string_back(_value: Any) -> None:
        back[0] += 1

    launcher = Launcher("memory")
    launcher.add_pkg(components=[EchoRelay()])
    with launcher:
        transport = launcher.transport
        recorder = (Recorder(transport, record_to, discover_every_s=0.5,
                             compression=compression).start()  # type: ignore[arg-type]  # a Compression name
                    if record_to is not None else None)
        subs = [transport.create_subscription(Topic(img_out, "Image"), image_back, inline=True),
                transport.create_subscription(Topic(str_out, "String"), string_back, inline=True)]
        img_pub = transport.create_publisher(Topic(img_in, "Image"))
        str_pub = transport.create_publisher(Topic(str_in, "String"))
        sent = 0
        try:
            start, cpu_start = time.monotonic(), time.process_time()
            # A 300 Hz clock: every 10th tick a camera frame (30 Hz), every 3rd a String (100 Hz).
            for tick in range(round(seconds * 300)):
                if tick % 10 == 0:
                    img_pub.publish(ImageMsg(data=pixels, encoding="rgb8", header=Header(stamp_ns=time.monotonic_ns())))
                    sent += 1
                if tick % 3 == 0:
                    str_pub.publish(string_payload(tick))
                    sent += 1
                time.sleep(max(0.0, start + (tick + 1) / 300 - time.monotonic()))
            time.sleep(0.3)  # the last values come back
            cpu = (time.process_time() - cpu_start) / (time.monotonic() - start)
        finally:
            for sub in subs:
                sub.close()
            img_pub.close()
            str_pub.close()
            if recorder is not None:
                recorder.stop()
    ordered = sorted(latencies) or [0.0]
    return {"kept": back[0] / sent, "p50_ms": ordered[len(ordered) // 2] / 1e6,
            "p99_ms": ordered[min(len(ordered) - 1, int(len(ordered) * 0.99))] / 1e6, "cpu": cpu}


def _playback(folder: Path, count: int = 300, hz: float = 100.0) -> dict[str, float]:
    from agents_core import Topic  # noqa: PLC0415
    from agents_core.recording import Player, Recorder  # noqa: PLC0415
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

    path = folder / "paced.mcap"
    topic = Topic("paced", "String")
    with resolve_transport("memory") as transport:
        pub = transport.create_publisher(topic)
        with Recorder(transport, path, topics=[topic]):
            next_at = time.monotonic()
            for i in range(count):
                pub.publish(string_payload(i))
                next_at += 1.0 / hz
                time.sleep(max(0.0, next_at - time.monotonic()))
    with resolve_transport("memory") as transport:
        transport.create_subscription(topic, lambda _v: None, inline=True)
        with Player(transport, path, rate=1.0) as player:
            stats = player.play()
    return {"p50_ms": stats.p50_lateness_s * 1e3, "p99_ms": stats.p99_lateness_s * 1e3,
            "published": float(stats.published)}


def run_suite(settings: dict[str, Any], progress: Callable[[str], None],
              ) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Both modes interleaved per payload, then the playback; (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"recording: skipped: {reason}")
        return [], [{"suite": "recording", "transport": "memory", "mode": "both", "reason": reason}]
    seconds = float(settings.get("recording_seconds", 1.5))
    rounds = int(settings.get("rounds", 1))
    records: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as folder:
        transports = ["memory"] + (["zenoh"] if available("zenoh") else [])
        for name, payload in ((t, p) for t in transports for p in ("string64", "image640x480")):
            rates: dict[str, list[float]] = {"raw": [], "framework": []}
            for r in range(rounds):
                order = ("raw", "framework") if r % 2 == 0 else ("framework", "raw")
                for mode in order:
                    target = Path(folder) / f"{name}-{payload}-{r}.mcap" if mode == "framework" else None
                    rates[mode].append(_hop_throughput(payload, seconds, target, name))
            for mode, got in rates.items():
                rate = sorted(got)[len(got) // 2]
                records.append({"suite": "recording", "transport": name, "payload": payload, "mode": mode,
                                "msgs_per_s": rate})
                progress(f"{'recording':<10} {name:<6} {mode:<9} {payload:<13} {rate:10.1f} msg/s")
        paced: dict[str, list[dict[str, float]]] = {m: [] for m in PACED_MODES}
        for r in range(rounds):
            for mode in PACED_MODES[r % 2::] + PACED_MODES[:r % 2]:  # the order turns round by round
                target = None if mode == "raw" else Path(folder) / f"paced-{mode}-{r}.mcap"
                paced[mode].append(_paced_hop(seconds * 2, target, mode.partition("-")[2] or "lz4"))
        for mode, runs in paced.items():
            median = {k: sorted(run[k] for run in runs)[len(runs) // 2] for k in runs[0]}
            records.append({"suite": "recording", "transport": "memory", "payload": "paced30hz_image_100hz_string",
                            "mode": mode, **median})
            progress(f"{'recording':<10} paced  {mode:<14} kept {median['kept']:.3f}  p50 {median['p50_ms']:.2f} ms  "
                     f"p99 {median['p99_ms']:.2f} ms  cpu {median['cpu']:.3f} cores")
        lateness = _playback(Path(folder))
        records.append({"suite": "recording", "transport": "memory", "payload": "playback100hz",
                        "mode": "framework", "lateness_ms": {"p50": lateness["p50_ms"], "p99": lateness["p99_ms"]}})
        progress(f"{'recording':<10} playback  p50 {lateness['p50_ms']:.2f} ms  p99 {lateness['p99_ms']:.2f} ms")
    return records, []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    records, skipped = run_suite({"recording_seconds": args.seconds, "rounds": args.rounds}, print)
    for name in ("memory", "zenoh"):
        for payload in ("string64", "image640x480"):
            by_mode = {r["mode"]: r["msgs_per_s"] for r in records if (r["transport"], r["payload"]) == (name, payload)}
            if len(by_mode) == 2:
                print(f"{name} {payload}: with recorder / without = {by_mode['framework'] / by_mode['raw']:.3f}")
    return 1 if skipped else 0


if __name__ == "__main__":
    sys.exit(main())
