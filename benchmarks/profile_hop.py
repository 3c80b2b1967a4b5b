"""Where a round trip's time goes: a stage-by-stage timeline of the hop, framework and raw.

``python -m benchmarks.profile_hop --transport zenoh --payload string64 [--count 3000] [--out FILE]``

Runs a relay and a pinger (two processes, as the hop benchmark does) with the stage tracing of
:mod:`benchmarks.trace` on, merges both processes' events on the host's monotonic clock, cuts
them into round trips at each send, keeps the round trips that took the most common path, and
prints, for each stage, the median time since the send and since the previous stage.

Why a timeline and not a sampling profiler: a round trip here is a few hundred microseconds, most
of it spent waiting (on the network, on a thread being woken), which CPU samplers do not see;
py-spy attached to these processes showed mostly ``Condition.wait`` and, in its blocking mode,
slowed the round trip several times over. Timestamps at the stage boundaries show the waits too.

It is a diagnostic, not a benchmark: tracing adds a little time to every stage.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from . import trace
from .common import ChildFailed, Children, child_env, emit, free_tcp_port, log


def pinger(args: argparse.Namespace) -> int:
    """The pinger child: ``--count`` traced round trips, events written to ``BENCH_TRACE``."""
    from .channels import open_endpoint  # noqa: PLC0415
    from .hop import ReplyBook, await_echo  # noqa: PLC0415

    if args.mode == "framework":
        trace.install_framework(args.transport)
    endpoint = open_endpoint(args.transport, args.mode, args.connect, args.namespace)
    try:
        channel = endpoint.channels[args.payload]
        await_echo(channel)
        book = ReplyBook()
        channel.on_reply = trace.wrapped(book, "reply")
        trace.EVENTS.clear()
        for seq in range(args.warmup + args.count):
            trace.mark("send>")
            channel.send(seq)
            trace.mark("send<")
            book.wait_for(seq, 5.0)
            trace.mark("wake")
    finally:
        endpoint.close()
    trace.dump(os.environ[trace.ENV_VAR], "process" if args.transport == "memory" else "pinger")
    emit({"done": True})
    return 0


def timeline(events: list[tuple[int, str]], warmup: int) -> dict[str, Any]:
    """Median stage times of the round trips that took the most common path."""
    events.sort()
    trips: list[list[tuple[int, str]]] = []
    for t, label in events:
        if label.endswith(":send>"):
            trips.append([])
        if trips:
            trips[-1].append((t, label))
    trips = trips[warmup:]
    paths = collections.Counter(tuple(label for _, label in trip) for trip in trips)
    if not paths:
        raise RuntimeError("no round trip was traced")
    path, kept = paths.most_common(1)[0]
    chosen = [trip for trip in trips if tuple(label for _, label in trip) == path]
    stages = []
    for i, label in enumerate(path):
        since_send = statistics.median((trip[i][0] - trip[0][0]) / 1000 for trip in chosen)
        since_prev = statistics.median((trip[i][0] - trip[i - 1][0]) / 1000 for trip in chosen) if i else 0.0
        stages.append({"stage": label, "since_send_us": since_send, "since_previous_us": since_prev})
    return {"round_trips": len(trips), "kept": kept, "stages": stages}


def _print_timeline(mode: str, result: dict[str, Any]) -> None:
    print(f"\n### {mode}: {result['kept']} of {result['round_trips']} round trips took this path\n")
    print("| stage | since send (us) | since previous stage (us) |")
    print("|---|---:|---:|")
    for s in result["stages"]:
        print(f"| {s['stage']} | {s['since_send_us']:.1f} | {s['since_previous_us']:.1f} |")


def profile_mode(args: argparse.Namespace, mode: str, children: Children, work: Path) -> dict[str, Any]:
    env = child_env(args.ros_domain if args.transport == "ros2" else None)
    relay_argv = ["-m", "benchmarks.relay", "--transport", args.transport, "--mode", mode]
    pinger_argv = ["-m", "benchmarks.profile_hop", "--role", "pinger", "--transport", args.transport,
                   "--mode", mode, "--payload", args.payload, "--count", str(args.count),
                   "--warmup", str(args.warmup)]
    if args.transport == "zenoh":
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        relay_argv += ["--listen", endpoint, "--namespace", f"prof_{mode}"]
        pinger_argv += ["--connect", endpoint, "--namespace", f"prof_{mode}"]
    relay_events, pinger_events = work / f"relay-{mode}.json", work / f"pinger-{mode}.json"
    relay = None
    try:
        if args.transport != "memory":  # on memory the relay is a component in the pinger's process
            relay = children.start(f"prof-relay-{mode}", relay_argv, {**env, trace.ENV_VAR: str(relay_events)})
            relay.wait_ready(60.0)
        ping = children.start(f"prof-pinger-{mode}", pinger_argv, {**env, trace.ENV_VAR: str(pinger_events)})
        for _ in ping.records(timeout=300.0):
            pass
        if children.stop(ping) != 0:
            raise ChildFailed(f"the pinger failed\n{ping.log_tail()}")
    finally:
        if relay is not None:
            children.stop(relay)
    events = [(int(t), str(label)) for t, label in json.loads(pinger_events.read_text())]
    if relay is not None:
        events += [(int(t), str(label)) for t, label in json.loads(relay_events.read_text())]
    result = timeline(events, args.warmup)
    _print_timeline(mode, result)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", choices=["memory", "zenoh", "ros2"], required=True)
    parser.add_argument("--payload", choices=["string64", "image640x480"], default="string64")
    parser.add_argument("--count", type=int, default=3000)
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--modes", default="raw,framework")
    parser.add_argument("--ros-domain", type=int, default=1 + os.getpid() % 101)
    parser.add_argument("--out", type=Path, help="write the timelines as JSON here")
    parser.add_argument("--role", choices=["driver", "pinger"], default="driver", help=argparse.SUPPRESS)
    parser.add_argument("--mode", choices=["framework", "raw"], help=argparse.SUPPRESS)
    parser.add_argument("--connect", help=argparse.SUPPRESS)
    parser.add_argument("--namespace", default="", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.role == "pinger":
        return pinger(args)
    results = {}
    with tempfile.TemporaryDirectory(prefix="bench-profile-") as tmp:
        children = Children(Path(tmp))
        try:
            for mode in args.modes.split(","):
                log(f"profiling the {args.payload} hop on {args.transport}, {mode} ...")
                start = time.monotonic()
                results[mode] = profile_mode(args, mode, children, Path(tmp))
                log(f"... {time.monotonic() - start:.0f} s")
        finally:
            children.stop_all()
    if args.out is not None:
        args.out.write_text(json.dumps({"transport": args.transport, "payload": args.payload, **results}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
