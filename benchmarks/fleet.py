"""A fleet through one Zenoh router: N robot processes (1, 5, 20), each a namespaced recipe, against raw zenoh clients.

For each fleet size N and each mode, on this machine's loopback:

- a **router** child (a plain zenoh-python session in router mode: the same router for both modes);
- an **observer** child (plain zenoh-python, the same for both modes): a client of the router that polls
  the liveliness tokens ``@agents/components/**`` until it sees N components, then counts every robot's
  ``<robot>/seq`` samples over a window;
- N **robot** children, clients of the router. framework: ``Launcher(transport="zenoh", namespace="robot<i>")``
  with one ``counter`` component publishing a String on ``seq`` at 100 Hz (``robot<i>/seq`` and the component
  ``robot<i>/counter`` on the wire); raw: a zenoh client that declares the same liveliness token and puts the
  same text on ``robot<i>/seq`` at 100 Hz.

Figures: ``discover_s``, from spawning the N robot processes to the observer seeing all N components
(process start and imports included: what an operator waits for when a fleet boots); ``msgs_per_s_per_robot``,
the median over robots of the rate the observer received (100 when every robot keeps its pace); ``router_cpu``,
the router's CPU (cores) while counting. Fleet sizes: 1 and 5 (``--quick``), 1, 5 and 20 (full); on a shared
two-core machine 20 processes of either kind contend for the CPU, which the rates show.
``python -m benchmarks.fleet router|observer|robot ...`` are the children; :func:`run_suite` runs them.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import READY, ChildFailed, Children, available, child_env, free_tcp_port, log

RATE_HZ = 100.0
WARMUP_S = 0.5


def _config(mode: str, listen: list[str], connect: list[str]) -> Any:
    import zenoh  # noqa: PLC0415  (children only)

    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return conf


def router(endpoint: str) -> None:
    """A plain zenoh router until SIGTERM."""
    import zenoh  # noqa: PLC0415

    from .common import StopFlag  # noqa: PLC0415

    stop = StopFlag()
    session = zenoh.open(_config("router", [endpoint], []))
    print(READY, flush=True)
    while not stop.wait(0.2):
        pass
    session.close()


def observer(endpoint: str, robots: int, window: float) -> None:
    """Wait for N component tokens (emit when), then count each robot's samples over ``window`` (emit rates)."""
    import zenoh  # noqa: PLC0415

    session = zenoh.open(_config("client", [], [endpoint]))
    counts: dict[str, int] = {}
    counting = threading.Event()
    lock = threading.Lock()

    def on_sample(sample: Any) -> None:
        if counting.is_set():
            robot = str(sample.key_expr).split("/", 1)[0]
            with lock:
                counts[robot] = counts.get(robot, 0) + 1

    subscriber = session.declare_subscriber("*/seq", on_sample)
    print(READY, flush=True)
    deadline = time.monotonic() + 600.0
    seen: set[str] = set()
    while len(seen) < robots and time.monotonic() < deadline:
        replies = session.liveliness().get("@agents/components/**", timeout=1.0)
        seen = {str(r.ok.key_expr) for r in replies if r.ok is not None}
        if len(seen) < robots:
            time.sleep(0.05)
    print(json.dumps({"all_seen_at": time.time(), "seen": len(seen)}), flush=True)
    time.sleep(WARMUP_S)
    counting.set()
    time.sleep(window)
    counting.clear()
    with lock:
        rates = [counts.get(f"robot{i}", 0) / window for i in range(robots)]
    print(json.dumps({"rates": rates}), flush=True)
    subscriber.undeclare()
    session.close()


def robot_raw(endpoint: str, index: int) -> None:
    """A raw zenoh robot: the component's liveliness token and its 100 Hz topic, until SIGTERM."""
    import zenoh  # noqa: PLC0415

    from .common import StopFlag  # noqa: PLC0415

    stop = StopFlag()
    session = zenoh.open(_config("client", [], [endpoint]))
    token = session.liveliness().declare_token(f"@agents/components/robot{index}/counter")
    publisher = session.declare_publisher(f"robot{index}/seq")
    seq = 0
    next_at = time.monotonic()
    while not stop.event.is_set():
        publisher.put(f"{seq} {time.time():.6f}")
        seq += 1
        next_at += 1.0 / RATE_HZ
        delay = next_at - time.monotonic()
        if delay > 0:
            stop.wait(delay)
    publisher.undeclare()
    token.undeclare()
    session.close()


def robot_framework(endpoint: str, index: int) -> None:
    """A framework robot: the counter recipe under ``robot<index>``, until SIGTERM."""
    from agents_core import Launcher, Topic  # noqa: PLC0415
    from agents_core.components import Component  # noqa: PLC0415

    class Counter(Component):
        def __init__(self, **kwargs: Any) -> None:
            self.seq = 0
            super().__init__(**kwargs)

        def _execution_step(self, **kwargs: Any) -> None:
            self.publishers_dict["seq"].publish(f"{self.seq} {time.time():.6f}")
            self.seq += 1

    launcher = Launcher(transport="zenoh", transport_options={"mode": "client", "connect": [endpoint],
                                                               "multicast_scouting": False},
                        namespace=f"robot{index}", quiet=True)
    launcher.add_pkg(components=[Counter(inputs=[], outputs=[Topic("seq", "String")], trigger=RATE_HZ,
                                         component_name="counter")])
    launcher.bringup()


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(size: int, mode: str, window: float, children: Children, env: dict[str, str]) -> dict[str, Any]:
    """One fleet of ``size`` robots in ``mode``: its record."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    started = []
    try:
        hub = children.start(f"fleet-router-{mode}-{size}", ["-m", "benchmarks.fleet", "router", endpoint], env)
        started.append(hub)
        hub.wait_ready(60.0)
        watcher = children.start(f"fleet-observer-{mode}-{size}", ["-m", "benchmarks.fleet", "observer", endpoint,
                                                                   str(size), str(window)], env)
        started.append(watcher)
        watcher.wait_ready(60.0)
        spawned_at = time.time()
        for i in range(size):
            started.append(children.start(f"fleet-robot-{mode}-{size}-{i}", ["-m", "benchmarks.fleet", f"robot-{mode}",
                                                                              endpoint, str(i)], env))
        records = watcher.records(timeout=600.0)
        seen = next(records)
        cpu_before, at_before = _cpu_seconds(hub.pid), time.monotonic()
        rates = next(records)["rates"]
        cpu = (_cpu_seconds(hub.pid) - cpu_before) / (time.monotonic() - at_before)
        if seen["seen"] < size:
            raise ChildFailed(f"the observer saw {seen['seen']} of {size} components")
        return {"suite": "fleet", "transport": "zenoh", "payload": f"{size}_robots", "mode": mode,
                "discover_s": seen["all_seen_at"] - spawned_at, "msgs_per_s_per_robot": statistics.median(rates),
                "min_robot_rate": min(rates), "router_cpu": cpu, "robots": size, "rate_hz": RATE_HZ}
    finally:
        for child in reversed(started):
            children.stop(child, grace=10.0)


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Each fleet size, raw then framework; (records, skipped)."""
    if not available("zenoh"):
        reason = "the zenoh extra is not installed"
        progress(f"fleet: skipped: {reason}")
        return [], [{"suite": "fleet", "transport": "zenoh", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    env = child_env()
    for size in settings.get("fleet_sizes", (1, 5)):
        for mode in ("raw", "framework"):
            try:
                r = measure(int(size), mode, float(settings.get("fleet_window", 2.0)), children, env)
            except ChildFailed as exc:
                progress(f"fleet: {size} robots {mode}: FAILED: {str(exc).splitlines()[0]}")
                skipped.append({"suite": "fleet", "transport": "zenoh", "mode": mode, "reason": str(exc)[-1500:]})
                continue
            records.append(r)
            progress(f"{'fleet':<10} {size:>3} robots {mode:<9} discovered in {r['discover_s']:6.2f} s, "
                     f"{r['msgs_per_s_per_robot']:6.1f} msg/s per robot (min {r['min_robot_rate']:.1f}), "
                     f"router {r['router_cpu']:.3f} cores")
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="role", required=True)
    sub.add_parser("router").add_argument("endpoint")
    watch = sub.add_parser("observer")
    watch.add_argument("endpoint")
    watch.add_argument("robots", type=int)
    watch.add_argument("window", type=float)
    for role in ("robot-raw", "robot-framework"):
        p = sub.add_parser(role)
        p.add_argument("endpoint")
        p.add_argument("index", type=int)
    args = parser.parse_args(argv)
    if args.role == "router":
        router(args.endpoint)
    elif args.role == "observer":
        observer(args.endpoint, args.robots, args.window)
    elif args.role == "robot-raw":
        robot_raw(args.endpoint, args.index)
    else:
        robot_framework(args.endpoint, args.index)
    log(f"fleet {args.role} done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
