"""The echo process of the hop and throughput benchmarks.

``python -m benchmarks.relay --transport zenoh|ros2 --mode framework|raw [--listen tcp/127.0.0.1:PORT]
[--namespace NS]`` sends every String on ``bench/str_in`` back on ``bench/str_out`` and every image on
``bench/img_in`` back on ``bench/img_out``, prints ``READY`` once it serves, and runs until SIGTERM.

- ``framework``: an :class:`~benchmarks.parts.EchoRelay` component under ``Launcher``.
- ``raw``: the library alone. Zenoh: a subscriber callback that takes the payload as bytes and
  puts those bytes back (no decoding). ROS 2: an rclpy node whose subscription callbacks publish the received
  message (``std_msgs/String``, ``sensor_msgs/Image``) on a single-threaded executor, the
  executor the framework's ROS 2 transport uses too.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys

from . import trace
from .common import READY, TOPICS, StopFlag, log, zenoh_framework_options, zenoh_raw_config


def serve_framework(transport: str, listen: str | None, namespace: str, stop: StopFlag) -> None:
    from agents_core import Launcher  # noqa: PLC0415

    from .parts import EchoRelay  # noqa: PLC0415

    options = zenoh_framework_options([listen or "tcp/127.0.0.1:0"], [], namespace) if transport == "zenoh" else {}
    router = None
    if transport == "rmw_zenoh":  # a router on the given endpoint, in this process; the recipe a peer of it
        from agents_zenoh.router import open_router  # noqa: PLC0415

        assert listen is not None
        router = open_router([listen])
        options = {"connect": [listen], "listen": ["tcp/127.0.0.1:0"]}
    try:
        launcher = Launcher(transport=transport, transport_options=options)
        launcher.add_pkg(components=[EchoRelay()])
        launcher.start()
        try:
            print(READY, flush=True)
            while not stop.wait(0.5):
                pass
        finally:
            launcher.stop()
    finally:
        if router is not None:
            router.close()


def serve_raw_zenoh(listen: str | None, namespace: str, stop: StopFlag) -> None:
    import zenoh  # noqa: PLC0415

    prefix = f"{namespace}/" if namespace else ""
    session = zenoh.open(zenoh_raw_config([listen or "tcp/127.0.0.1:0"], []))
    try:
        subscribers = []
        for inp, out in TOPICS.values():
            pub = session.declare_publisher(prefix + out, congestion_control=zenoh.CongestionControl.BLOCK)

            def echo(sample: zenoh.Sample, pub: zenoh.Publisher = pub) -> None:
                # Into Python and back out, as anything that looks at the data must; putting the
                # received ZBytes itself would forward Zenoh's buffer without ever reading it.
                pub.put(sample.payload.to_bytes())

            subscribers.append(session.declare_subscriber(prefix + inp, trace.maybe_wrapped(echo, "echo")))
        print(READY, flush=True)
        while not stop.wait(0.5):
            pass
    finally:
        session.close()


def serve_raw_ros2(stop: StopFlag) -> None:
    import rclpy  # noqa: PLC0415
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
    from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415
    from sensor_msgs.msg import Image  # noqa: PLC0415
    from std_msgs.msg import String  # noqa: PLC0415

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_raw_relay")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    for msg_type, (inp, out) in ((String, TOPICS["string64"]), (Image, TOPICS["image640x480"])):
        pub = node.create_publisher(msg_type, "/" + out, qos)
        node.create_subscription(msg_type, "/" + inp, trace.maybe_wrapped(pub.publish, "echo"), qos)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        print(READY, flush=True)
        while not stop.event.is_set():
            executor.spin_once(timeout_sec=0.2)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", choices=["zenoh", "ros2", "rmw_zenoh"], required=True)
    parser.add_argument("--mode", choices=["framework", "raw"], required=True)
    parser.add_argument("--listen", help="Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7500")
    parser.add_argument("--namespace", default="")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    stop = StopFlag()
    if trace.enabled() and args.mode == "framework":
        trace.install_framework(args.transport)
    if args.mode == "framework":
        serve_framework(args.transport, args.listen, args.namespace, stop)
    elif args.transport == "zenoh":
        serve_raw_zenoh(args.listen, args.namespace, stop)
    else:
        serve_raw_ros2(stop)
    if trace.enabled():
        trace.dump(os.environ[trace.ENV_VAR], "relay")
    log(f"relay ({args.transport}, {args.mode}) stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
