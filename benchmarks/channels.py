"""The pinger's side of a relay: send numbered messages, hear their echoes.

A :class:`Channel` carries one payload kind (``string64`` or ``image640x480``) to the relay and
calls ``on_reply(seq)`` for each echo, on whatever thread the library delivers it. What each
mode does per message:

- ``framework``: a publisher and a subscription of the framework's transport (the same
  ``Transport`` API a recipe's components use): values are validated, encoded (msgpack on Zenoh,
  ROS messages on ROS 2), decoded and handed to the callback by the transport's delivery thread.
  A String is a ``str``; an image is a new ``ImageMsg`` around the same pixel array, sequence
  number in ``header.frame_id``.
- ``raw``: the library alone. Zenoh: bytes (UTF-8 text, or an 8-byte sequence number followed by
  the pixels copied from the frame into a reused buffer), a numpy view of the echoed pixels.
  ROS 2: ``std_msgs/String`` and a new ``sensor_msgs/Image`` per frame (pixels copied once into
  an ``array.array``), an rclpy single-threaded executor spinning on a thread.
- ``memory`` (``raw``): an echo thread that takes ``(seq, value)`` from a queue and answers with
  a call, the least any in-process hand-off between two threads costs.
"""

from __future__ import annotations

import array
import queue
import struct
import threading
from collections.abc import Callable
from typing import Any

from .common import IMAGE_BYTES, IMAGE_SHAPE, TOPICS, image_pixels, string_payload, string_seq

ReplyCallback = Callable[[int], None]


def _ignore(seq: int) -> None:
    """The reply callback until a measurement installs its own."""


class Channel:
    """Sends numbered messages of one payload kind; ``on_reply(seq)`` hears each echo."""

    payload: str
    on_reply: ReplyCallback = staticmethod(_ignore)

    def send(self, seq: int) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Release what the channel declared."""


# -- framework ------------------------------------------------------------------------------------


class FrameworkChannel(Channel):
    """A publisher and a subscription of a framework transport."""

    def __init__(self, transport: Any, payload: str) -> None:
        from agents_core import Topic  # noqa: PLC0415
        from agents_core.messages import Header, ImageMsg  # noqa: PLC0415

        self.payload = payload
        type_name = "String" if payload == "string64" else "Image"
        inp, out = TOPICS[payload]
        if payload == "string64":
            self._make: Callable[[int], Any] = string_payload
            self._seq_of: Callable[[Any], int] = string_seq
        else:
            pixels = image_pixels()
            self._make = lambda seq: ImageMsg(data=pixels, encoding="rgb8", header=Header(frame_id=str(seq)))
            self._seq_of = lambda msg: int(msg.header.frame_id)
        self._pub = transport.create_publisher(Topic(inp, type_name))
        # Inline: the callback only wakes the waiting thread, so it may run on the middleware's
        # thread (what a component input does too); no delivery thread in between.
        self._sub = transport.create_subscription(Topic(out, type_name), self._on_value, inline=True)

    def send(self, seq: int) -> None:
        self._pub.publish(self._make(seq))

    def _on_value(self, value: Any) -> None:
        self.on_reply(self._seq_of(value))

    def close(self) -> None:
        self._sub.close()
        self._pub.close()


# -- raw Zenoh ------------------------------------------------------------------------------------


class RawZenohChannel(Channel):
    """A zenoh publisher and subscriber of plain bytes."""

    def __init__(self, session: Any, prefix: str, payload: str) -> None:
        import numpy as np  # noqa: PLC0415
        import zenoh  # noqa: PLC0415

        self.payload = payload
        self._np = np
        inp, out = TOPICS[payload]
        self._pub = session.declare_publisher(prefix + inp, congestion_control=zenoh.CongestionControl.BLOCK)
        if payload == "image640x480":
            self._pixels = image_pixels().reshape(-1)
            self._buffer = bytearray(8 + IMAGE_BYTES)
        self._sub = session.declare_subscriber(prefix + out, self._on_sample)

    def send(self, seq: int) -> None:
        if self.payload == "string64":
            self._pub.put(string_payload(seq).encode())
            return
        view = memoryview(self._buffer)
        view[8:] = self._pixels  # the frame, copied once into the outgoing buffer
        struct.pack_into("<Q", self._buffer, 0, seq)
        self._pub.put(self._buffer)

    def _on_sample(self, sample: Any) -> None:
        data = sample.payload.to_bytes()
        if self.payload == "string64":
            self.on_reply(string_seq(data.decode()))
            return
        pixels = self._np.frombuffer(data, self._np.uint8, offset=8).reshape(IMAGE_SHAPE)
        if pixels.shape == IMAGE_SHAPE:
            self.on_reply(struct.unpack_from("<Q", data)[0])

    def close(self) -> None:
        self._sub.undeclare()
        self._pub.undeclare()


# -- raw ROS 2 ------------------------------------------------------------------------------------


class RawRos2Channel(Channel):
    """An rclpy publisher and subscription (``std_msgs/String`` or ``sensor_msgs/Image``)."""

    def __init__(self, node: Any, payload: str) -> None:
        import numpy as np  # noqa: PLC0415
        from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: PLC0415
        from sensor_msgs.msg import Image  # noqa: PLC0415
        from std_msgs.msg import String  # noqa: PLC0415

        self.payload = payload
        self._np = np
        self._String, self._Image = String, Image
        inp, out = TOPICS[payload]
        msg_type = String if payload == "string64" else Image
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        if payload == "image640x480":
            self._pixels = image_pixels()
        self._pub = node.create_publisher(msg_type, "/" + inp, qos)
        self._sub = node.create_subscription(msg_type, "/" + out, self._on_message, qos)
        self._node = node

    def send(self, seq: int) -> None:
        if self.payload == "string64":
            self._pub.publish(self._String(data=string_payload(seq)))
            return
        height, width, channels = IMAGE_SHAPE
        msg = self._Image(height=height, width=width, encoding="rgb8", is_bigendian=0, step=width * channels)
        msg.header.frame_id = str(seq)
        data = array.array("B")
        data.frombytes(self._pixels)  # the frame, copied once into the message
        msg.data = data
        self._pub.publish(msg)

    def _on_message(self, msg: Any) -> None:
        if self.payload == "string64":
            self.on_reply(string_seq(msg.data))
            return
        pixels = self._np.frombuffer(msg.data, self._np.uint8).reshape(IMAGE_SHAPE)
        if pixels.shape == IMAGE_SHAPE:
            self.on_reply(int(msg.header.frame_id))

    def close(self) -> None:
        """Nothing: the endpoint stops the executor, then destroys the node with all it holds."""


# -- raw in-process -------------------------------------------------------------------------------


class ThreadEchoChannel(Channel):
    """An echo thread fed through a queue: the floor of an in-process hand-off between threads."""

    def __init__(self, payload: str) -> None:
        from agents_core.messages import Header, ImageMsg  # noqa: PLC0415

        self.payload = payload
        if payload == "string64":
            self._make: Callable[[int], Any] = string_payload
        else:
            pixels = image_pixels()
            self._make = lambda seq: ImageMsg(data=pixels, encoding="rgb8", header=Header(frame_id=str(seq)))
        self._queue: queue.SimpleQueue[tuple[int, Any] | None] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._echo, name=f"echo:{payload}", daemon=True)
        self._thread.start()

    def send(self, seq: int) -> None:
        self._queue.put((seq, self._make(seq)))

    def _echo(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            self.on_reply(item[0])

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join(timeout=5.0)


# -- opening a pair of channels -------------------------------------------------------------------


class Endpoint:
    """The pinger's connection to a relay: one channel per payload kind, and what to close after."""

    def __init__(self) -> None:
        self.channels: dict[str, Channel] = {}
        self._closers: list[Callable[[], None]] = []

    def on_close(self, func: Callable[[], None]) -> None:
        self._closers.append(func)

    def close(self) -> None:
        for channel in self.channels.values():
            channel.close()
        while self._closers:
            self._closers.pop()()


def open_endpoint(transport: str, mode: str, connect: str | None, namespace: str) -> Endpoint:
    """Connect to the relay of ``transport`` / ``mode`` (for memory: start it in this process)."""
    endpoint = Endpoint()
    try:
        if mode == "framework":
            _open_framework(endpoint, transport, connect, namespace)
        elif transport == "memory":
            for payload in TOPICS:
                endpoint.channels[payload] = ThreadEchoChannel(payload)
        elif transport == "zenoh":
            import zenoh  # noqa: PLC0415

            from .common import zenoh_raw_config  # noqa: PLC0415

            assert connect is not None
            session = zenoh.open(zenoh_raw_config([], [connect]))
            endpoint.on_close(session.close)
            prefix = f"{namespace}/" if namespace else ""
            for payload in TOPICS:
                endpoint.channels[payload] = RawZenohChannel(session, prefix, payload)
        else:
            _open_raw_ros2(endpoint)
    except BaseException:
        endpoint.close()
        raise
    return endpoint


def _open_framework(endpoint: Endpoint, transport: str, connect: str | None, namespace: str) -> None:
    from agents_core import Launcher  # noqa: PLC0415
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

    if transport == "memory":
        from .parts import EchoRelay  # noqa: PLC0415

        launcher = Launcher(transport="memory")
        launcher.add_pkg(components=[EchoRelay()])
        launcher.start()
        endpoint.on_close(launcher.stop)
        bus = launcher.transport
    elif transport == "zenoh":
        from .common import zenoh_framework_options  # noqa: PLC0415

        assert connect is not None
        bus = resolve_transport("zenoh", **zenoh_framework_options([], [connect], namespace))
        endpoint.on_close(bus.close)
    elif transport == "rmw_zenoh":
        assert connect is not None
        bus = resolve_transport("rmw_zenoh", connect=[connect], listen=["tcp/127.0.0.1:0"])
        endpoint.on_close(bus.close)
    else:
        bus = resolve_transport("ros2", node_name="bench_pinger")
        endpoint.on_close(bus.close)
    for payload in TOPICS:
        endpoint.channels[payload] = FrameworkChannel(bus, payload)


def _open_raw_ros2(endpoint: Endpoint) -> None:
    import rclpy  # noqa: PLC0415
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_raw_pinger")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, name="rclpy-spin", daemon=True)

    def close() -> None:
        executor.shutdown()
        spinner.join(timeout=5.0)
        node.destroy_node()
        rclpy.try_shutdown()

    endpoint.on_close(close)
    for payload in TOPICS:
        endpoint.channels[payload] = RawRos2Channel(node, payload)
    spinner.start()
