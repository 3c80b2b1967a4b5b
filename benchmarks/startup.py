"""Start-up: from ``Launcher.start()`` to all five components of a recipe active, per transport.

The recipe is a chain of five String stages (:func:`benchmarks.parts.five_stage_recipe`). The
clock starts just before ``Launcher.start()`` (which opens the transport: a Zenoh session, a ROS 2
context) and stops when every component reports ``active``. Each repetition builds a new
launcher and new components; the first one in the process is a warm-up and is not counted.

The raw counterpart does what the same graph needs from the library alone: Zenoh, open a session
and declare one publisher and one subscriber per stage; ROS 2, start a context and create five
nodes with one publisher and one subscription each, added to a running executor. (The
framework does more: lifecycle nodes or liveliness tokens and queryables, status publishers,
services.) The memory transport has no raw counterpart.

``python -m benchmarks.startup --transport T --mode framework|raw --reps N`` prints one record.
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from .common import ChildFailed, Children, child_env, emit

STAGES = 5


def framework_once(transport: str, rep: int) -> float:
    from agents_core import Launcher  # noqa: PLC0415

    from .common import zenoh_framework_options  # noqa: PLC0415
    from .parts import five_stage_recipe  # noqa: PLC0415

    options: dict[str, Any] = {}
    if transport == "zenoh":
        options = zenoh_framework_options(["tcp/127.0.0.1:0"], [], f"startup_{os.getpid()}_{rep}")
    launcher = Launcher(transport=transport, transport_options=options)
    launcher.add_pkg(components=five_stage_recipe(f"startup{rep}"))
    start = time.perf_counter()
    launcher.start()
    while not launcher.all_active():
        time.sleep(0.001)
    took = time.perf_counter() - start
    launcher.stop()
    return took


def threads_of_one_component(transport: str) -> int:
    """Threads a component with three inputs adds once it is active (its transport's own excluded)."""
    from agents_core import Launcher  # noqa: PLC0415
    from agents_core.transport import resolve_transport  # noqa: PLC0415

    from .common import zenoh_framework_options  # noqa: PLC0415
    from .parts import Merge  # noqa: PLC0415

    options: dict[str, Any] = {}
    if transport == "zenoh":
        options = zenoh_framework_options(["tcp/127.0.0.1:0"], [], f"threads_{os.getpid()}")
    opened = resolve_transport(transport, **options)
    launcher = Launcher(transport=opened)
    launcher.add_pkg(components=[Merge(f"threads{os.getpid()}")])
    try:
        before = threading.active_count()
        launcher.start()
        while not launcher.all_active():
            time.sleep(0.001)
        time.sleep(0.05)  # let every thread the component starts be running
        return threading.active_count() - before
    finally:
        launcher.stop()
        opened.close()


def raw_zenoh_once(rep: int) -> float:
    import zenoh  # noqa: PLC0415

    from .common import zenoh_raw_config  # noqa: PLC0415

    start = time.perf_counter()
    session = zenoh.open(zenoh_raw_config(["tcp/127.0.0.1:0"], []))
    entities: list[Any] = []
    for i in range(STAGES):
        pub = session.declare_publisher(f"startup{rep}/t{i + 1}")

        def forward(sample: zenoh.Sample, pub: zenoh.Publisher = pub) -> None:
            pub.put(sample.payload)

        entities += [pub, session.declare_subscriber(f"startup{rep}/t{i}", forward)]
    took = time.perf_counter() - start
    session.close()
    return took


def raw_ros2_once(rep: int) -> float:
    import rclpy  # noqa: PLC0415
    from rclpy.context import Context  # noqa: PLC0415
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415
    from std_msgs.msg import String  # noqa: PLC0415

    start = time.perf_counter()
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    executor = SingleThreadedExecutor(context=context)
    nodes = []
    for i in range(STAGES):
        node = rclpy.create_node(f"stage{i}", context=context)
        pub = node.create_publisher(String, f"/startup{rep}/t{i + 1}", 10)
        node.create_subscription(String, f"/startup{rep}/t{i}", pub.publish, 10)
        executor.add_node(node)
        nodes.append(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    took = time.perf_counter() - start
    executor.shutdown()
    spinner.join(timeout=5.0)
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=context)
    return took


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", choices=["memory", "zenoh", "ros2"], required=True)
    parser.add_argument("--mode", choices=["framework", "raw"], required=True)
    parser.add_argument("--reps", type=int, default=3)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    once: Callable[[int], float]
    if args.mode == "framework":
        def once(rep: int) -> float:
            return framework_once(args.transport, rep)
    elif args.transport == "zenoh":
        once = raw_zenoh_once
    elif args.transport == "ros2":
        once = raw_ros2_once
    else:
        raise SystemExit("the memory transport has no raw counterpart")
    once(0)  # warm-up: imports, first-use initialisation
    times = [once(rep) for rep in range(1, args.reps + 1)]
    record: dict[str, Any] = {"suite": "startup", "payload": "five_components", "times_s": times,
                              "median_ms": statistics.median(times) * 1000.0, "min_ms": min(times) * 1000.0,
                              "max_ms": max(times) * 1000.0}
    if args.mode == "framework":
        record["threads_3_inputs"] = threads_of_one_component(args.transport)
    emit(record)
    return 0


def run_suite(transports: list[str], settings: dict[str, Any], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """One child per transport and mode; (records, skipped)."""
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    for transport in transports:
        for mode in ("raw", "framework"):
            if transport == "memory" and mode == "raw":
                continue
            env = child_env(ros_domain if transport == "ros2" else None)
            child = children.start(f"startup-{transport}-{mode}", [
                "-m", "benchmarks.startup", "--transport", transport, "--mode", mode,
                "--reps", str(settings["startup_reps"])], env)
            try:
                for record in child.records(timeout=120.0):
                    record.update(transport=transport, mode=mode)
                    records.append(record)
                    progress(f"{'startup':<10} {transport:<6} {mode:<9} {'5 comps':<12} start -> active "
                             f"median {record['median_ms']:8.1f} ms  (min {record['min_ms']:.1f}, "
                             f"max {record['max_ms']:.1f}, n={len(record['times_s'])})"
                             + (f"; a 3-input component starts {record['threads_3_inputs']} thread(s)"
                                if "threads_3_inputs" in record else ""))
                rc = children.stop(child)
                if rc != 0:
                    raise ChildFailed(f"exited with {rc}\n{child.log_tail()}")
            except ChildFailed as exc:
                progress(f"startup {transport} {mode}: FAILED: {str(exc).splitlines()[0]}")
                skipped.append({"suite": "startup", "transport": transport, "mode": mode,
                                "reason": str(exc)[-1500:]})
            finally:
                children.stop(child)
    return records, skipped


if __name__ == "__main__":
    sys.exit(main())
