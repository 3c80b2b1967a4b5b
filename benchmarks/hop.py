"""Hop latency (ping -> relay -> pong) and throughput, framework and raw, per transport.

Two processes per measurement on Zenoh and ROS 2: the relay (``python -m benchmarks.relay``) and
the pinger (``python -m benchmarks.hop``, this module's :func:`main`), which measures and prints
JSON records. On the memory transport the relay is a component in the pinger's own process.

Latency is the **round trip** (RTT) from just before the pinger publishes a message to the moment
its echo has been handed to the pinger's main thread: two hops through the relay, each with the
publishing, delivery and decoding that side does. One message is in flight at a time. The first
``warmup`` round trips of each payload are not counted. Medians and 99th percentiles are reported.

:func:`run_suite` is what the runner calls: it starts the relay and the pinger for each
transport and mode, reads the records, and stops both by PID whatever happens.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from .channels import Channel, open_endpoint
from .common import (
    ChildFailed,
    Children,
    child_env,
    emit,
    free_tcp_port,
    summarize_ns,
)
from .throughput import measure_throughput

#: Sequence numbers of discovery probes (never mistaken for measured messages).
PROBE_BASE = 9_000_000_000
#: How long the pinger tries to get a first echo through (discovery included).
CONNECT_TIMEOUT = 30.0
#: One round trip that takes longer than this is counted as lost.
REPLY_TIMEOUT = 5.0


class ReplyBook:
    """The sequence numbers echoed back so far; a waiter wakes when its own arrives."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._seen: set[int] = set()

    def __call__(self, seq: int) -> None:
        with self._cond:
            self._seen.add(seq)
            self._cond.notify_all()

    def wait_for(self, seq: int, timeout: float) -> bool:
        with self._cond:
            ok = self._cond.wait_for(lambda: seq in self._seen, timeout)
            self._seen.discard(seq)
            return ok

    def wait_any(self, timeout: float) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: bool(self._seen), timeout)

    def clear(self) -> None:
        with self._cond:
            self._seen.clear()


def await_echo(channel: Channel, timeout: float = CONNECT_TIMEOUT) -> float:
    """Send probes until one comes back (discovery may swallow the first); seconds it took."""
    book = ReplyBook()
    channel.on_reply = book
    start = time.monotonic()
    probe = PROBE_BASE
    while time.monotonic() - start < timeout:
        channel.send(probe)
        probe += 1
        if book.wait_any(0.25):
            took = time.monotonic() - start
            time.sleep(0.3)  # let late probe echoes arrive before anything is counted
            return took
    raise TimeoutError(f"no echo on {channel.payload} within {timeout:g} s")


def measure_latency(channel: Channel, *, warmup: int, count: int, max_seconds: float) -> dict[str, Any]:
    """``warmup`` + ``count`` round trips, one at a time (bounded by ``max_seconds``); RTT statistics."""
    book = ReplyBook()
    channel.on_reply = book
    samples: list[int] = []
    lost = 0
    deadline = time.monotonic() + max_seconds
    for seq in range(warmup + count):
        if time.monotonic() > deadline:
            break
        start = time.perf_counter_ns()
        channel.send(seq)
        if not book.wait_for(seq, REPLY_TIMEOUT):
            lost += 1
            continue
        elapsed = time.perf_counter_ns() - start
        if seq >= warmup:
            samples.append(elapsed)
    if not samples:
        raise RuntimeError(f"no round trip of {channel.payload} came back ({lost} lost)")
    return {"rtt": summarize_ns(samples), "lost": lost, "warmup": warmup, "truncated": len(samples) < count}


# -- the pinger process ---------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="The pinger: measures latency and throughput against a relay.")
    parser.add_argument("--transport", choices=["memory", "zenoh", "ros2", "rmw_zenoh"], required=True)
    parser.add_argument("--mode", choices=["framework", "raw"], required=True)
    parser.add_argument("--connect", help="the relay's Zenoh endpoint")
    parser.add_argument("--namespace", default="")
    parser.add_argument("--counts", required=True,
                        help="string_warmup,string_count,image_warmup,image_count")
    parser.add_argument("--throughput-seconds", type=float, required=True)
    parser.add_argument("--max-seconds", type=float, default=120.0, help="bound of each latency loop")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    sw, sc, iw, ic = (int(x) for x in args.counts.split(","))
    counts = {"string64": (sw, sc), "image640x480": (iw, ic)}
    endpoint = open_endpoint(args.transport, args.mode, args.connect, args.namespace)
    try:
        for payload, channel in endpoint.channels.items():
            connect_s = await_echo(channel)
            warmup, count = counts[payload]
            latency = measure_latency(channel, warmup=warmup, count=count, max_seconds=args.max_seconds)
            emit({"suite": "hop", "payload": payload, "connect_s": connect_s, **latency})
        for payload, channel in endpoint.channels.items():
            result = measure_throughput(channel, seconds=args.throughput_seconds, max_messages=1_000_000,
                                        warmup_seconds=min(0.5, args.throughput_seconds / 3), base_seq=10_000_000)
            emit({"suite": "throughput", "payload": payload, **result})
    finally:
        endpoint.close()
    return 0


# -- orchestration --------------------------------------------------------------------------------


def _describe(record: dict[str, Any]) -> str:
    if record["suite"] == "hop":
        rtt = record["rtt"]
        return (f"RTT median {rtt['median_us']:9.1f} us   p99 {rtt['p99_us']:9.1f} us   "
                f"(n={rtt['n']}, lost {record['lost']})")
    return (f"{record['msgs_per_s']:10.0f} msg/s  {record['mb_per_s']:9.1f} MB/s   "
            f"({record['received']} msgs in {record['seconds']:.2f} s, lost {record['lost']})")


def run_suite(transports: list[str], settings: dict[str, Any], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Relay + pinger for each transport and mode, ``settings["rounds"]`` times; (records, skipped).

    Rounds alternate which mode goes first, so that a slow spell of the machine does not land on
    one mode only; the figures are medians over rounds.
    """
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    rounds = int(settings.get("rounds", 1))
    for transport in transports:
        for round_no in range(rounds):
            for mode in ("raw", "framework") if round_no % 2 == 0 else ("framework", "raw"):
                failure = _run_pair(transport, mode, round_no, settings, children, ros_domain, progress, records)
                if failure is not None:
                    progress(f"hop/throughput {transport} {mode}: FAILED: {failure.splitlines()[0]}")
                    skipped.append({"suite": "hop+throughput", "transport": transport, "mode": mode,
                                    "reason": failure[-1500:]})
    return records, skipped


def _run_pair(transport: str, mode: str, round_no: int, settings: dict[str, Any], children: Children,
              ros_domain: int, progress: Callable[[str], None], records: list[dict[str, Any]],
              extra_env: dict[str, str] | None = None) -> str | None:
    """One relay and one pinger; records appended as they come; the failure's text, or None.

    ``extra_env``: variables set for both children (the telemetry suite's OTEL_* ones).
    """
    counts = ",".join(str(settings[k]) for k in ("string_warmup", "string_count", "image_warmup", "image_count"))
    env = {**child_env(ros_domain if transport == "ros2" else None), **(extra_env or {})}
    argv = ["-m", "benchmarks.hop", "--transport", transport, "--mode", mode, "--counts", counts,
            "--throughput-seconds", str(settings["throughput_seconds"]),
            "--max-seconds", str(settings["latency_max_seconds"])]
    tag = f"{transport}-{mode}-{round_no}"
    relay = None
    try:
        if transport != "memory":
            relay_argv = ["-m", "benchmarks.relay", "--transport", transport, "--mode", mode]
            if transport == "zenoh":
                endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
                namespace = f"bench_{mode}_{endpoint.rsplit(':', 1)[1]}"
                relay_argv += ["--listen", endpoint, "--namespace", namespace]
                argv += ["--connect", endpoint, "--namespace", namespace]
            elif transport == "rmw_zenoh":  # the relay process hosts the router it and the pinger meet through
                endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
                relay_argv += ["--listen", endpoint]
                argv += ["--connect", endpoint]
            relay = children.start(f"relay-{tag}", relay_argv, env)
            relay.wait_ready(60.0)
        pinger = children.start(f"pinger-{tag}", argv, env)
        for record in pinger.records(timeout=settings["latency_max_seconds"] + 60.0):
            record.update(transport=transport, mode=mode, round=round_no)
            records.append(record)
            progress(f"{record['suite']:<10} {transport:<6} {mode:<9} {record['payload']:<12} {_describe(record)}"
                     + (f"  [round {round_no + 1}]" if settings.get("rounds", 1) > 1 else ""))
        rc = children.stop(pinger)
        if rc != 0:
            raise ChildFailed(f"the pinger exited with {rc}\n{pinger.log_tail()}")
    except ChildFailed as exc:
        return str(exc).strip()
    finally:
        if relay is not None:
            children.stop(relay)
    return None


if __name__ == "__main__":
    sys.exit(main())
