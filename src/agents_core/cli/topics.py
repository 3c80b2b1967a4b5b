"""``agentsctl topics list | echo | pub | hz``."""

from __future__ import annotations

import contextlib
import math
import queue
import sys
import threading
import time
from typing import Annotated, Any

import typer

from ..errors import ConfigError, UnknownTypeError
from ..topics import Topic, validate_topic_name
from ..transport.core import DriverTransport
from ..transport.requests import MAX_TIMEOUT_S
from ..types.base import SupportedType, get_type
from .connection import discovery_timeout, in_namespace, one_line_errors, open_transport, under_namespace
from .output import print_json, print_table, print_value, say
from .values import parse_value, summarize

__all__ = ["app"]

app = typer.Typer(help="List, print, publish and measure topics.", no_args_is_help=True)

TransportOpt = Annotated[str | None, typer.Option("--transport", "-t", help="zenoh or ros2 (default: "
                                                                              "AGENTS_TRANSPORT, else zenoh)")]
ConnectOpt = Annotated[list[str] | None, typer.Option(
    "--connect", "-c", help="Zenoh endpoint to connect to as a client (e.g. a router's tcp/HOST:7447)")]
JsonOpt = Annotated[bool, typer.Option("--json", help="print JSON instead of tables")]
DiscoveryOpt = Annotated[float | None, typer.Option(
    "--discovery-timeout", help="seconds to wait for discovery (default: 1, on ROS 2: 4)", min=0.01)]
NamespaceOpt = Annotated[str | None, typer.Option(
    "--namespace", "-N", help="resolve names in this namespace (a robot's, e.g. robot1: 'arm' is robot1/arm, "
                              "'/map' stays map); lists show only what is under it")]


def _topic_name(name: str, namespace: str | None = None) -> str:
    return validate_topic_name(in_namespace(namespace, name), "topic")


def _resolve_type(transport: DriverTransport, name: str, type_name: str | None,
                  timeout: float | None) -> type[SupportedType]:
    """The message type of topic ``name``: ``--type`` if given, else what discovery reports."""
    if type_name is None:
        info = transport.discover(timeout=discovery_timeout(transport, timeout)).topic(name)
        if info is None:
            raise ConfigError(f"unknown topic {name!r}: no publisher or subscriber of it was found on the "
                              f"{transport.name} transport (give --type to wait for one anyway)")
        type_name = info.msg_type
    try:
        return get_type(type_name)
    except UnknownTypeError:
        raise ConfigError(f"topic {name!r} carries {type_name}, which has no agents_core message type") from None


@app.command("list")
@one_line_errors
def list_topics(transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
                timeout: DiscoveryOpt = None, namespace: NamespaceOpt = None) -> None:
    """Every topic with its type and how many publishers and subscribers it has."""
    with open_transport(transport, connect) as t:
        graph = t.discover(timeout=discovery_timeout(t, timeout))
    shown = [i for i in graph.topics if i.name in under_namespace(namespace, [i.name])]
    if json_out:
        print_json([info.to_dict() for info in shown])
        return
    print_table("topics", ["topic", "type", "publishers", "subscribers"],
                [(i.name, i.msg_type, i.publishers, i.subscribers) for i in shown])


@app.command("echo")
@one_line_errors
def echo(name: Annotated[str, typer.Argument(help="topic name")], transport: TransportOpt = None,
         connect: ConnectOpt = None, json_out: JsonOpt = False,
         count: Annotated[int, typer.Option("--count", "-n", help="stop after N messages (0: no limit)", min=0)] = 0,
         timeout: Annotated[float, typer.Option("--timeout", help="stop after this many seconds", min=0.01)] = 10.0,
         type_name: Annotated[str | None, typer.Option("--type", help="message type (default: discovered)")] = None,
         discovery_wait: DiscoveryOpt = None, namespace: NamespaceOpt = None) -> None:
    """Print the messages of a topic (arrays and images as shape and dtype, never raw bytes)."""
    name = _topic_name(name, namespace)
    received: queue.Queue[Any] = queue.Queue(maxsize=1000)
    deadline = time.monotonic() + timeout
    shown = 0
    with open_transport(transport, connect) as t:
        msg_type = _resolve_type(t, name, type_name, discovery_wait)
        subscription = t.create_subscription(Topic(name, msg_type), lambda v: _offer(received, v))
        try:
            while (not count or shown < count) and (left := deadline - time.monotonic()) > 0:
                try:
                    value = received.get(timeout=min(left, 0.2))
                except queue.Empty:
                    continue
                doc = summarize(value)
                if json_out:
                    print_json({"topic": name, "msg_type": msg_type.type_name(), "value": doc})
                else:
                    say((name, "bold"), f" ({msg_type.type_name()})")
                    print_value(doc)
                shown += 1
        finally:
            subscription.close()
    if not shown:
        raise ConfigError(f"no message on {name!r} within {timeout:g} s")


@app.command("pub")
@one_line_errors
def pub(name: Annotated[str, typer.Argument(help="topic name")],
        type_name: Annotated[str, typer.Argument(help="message type, e.g. String")],
        value: Annotated[str, typer.Argument(help="the value: JSON, or a bare string")],
        transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
        count: Annotated[int, typer.Option("--count", "-n", help="how many times to publish", min=1)] = 1,
        rate: Annotated[float, typer.Option("--rate", "-r", help="messages per second", min=0.001)] = 10.0,
        wait: Annotated[float, typer.Option("--wait", help="seconds to wait for a subscriber first", min=0.0,
                                            max=MAX_TIMEOUT_S)] = 5.0,
        namespace: NamespaceOpt = None) -> None:
    """Publish a value on a topic."""
    name = _topic_name(name, namespace)
    msg_type = get_type(type_name)
    message = parse_value(msg_type, value)
    with open_transport(transport, connect) as t:
        warning = _subscriber_warning(_wait_for_subscriber(t, name, wait), name, msg_type.type_name(), wait)
        if warning:
            print(f"warning: {warning}", file=sys.stderr, flush=True)
        publisher = t.create_publisher(Topic(name, msg_type))
        try:
            for i in range(count):
                publisher.publish(message)
                if i + 1 < count:
                    time.sleep(1.0 / rate)
        finally:
            publisher.close()
        # Give a networked middleware a moment to flush before the session closes.
        time.sleep(0.2)
    if json_out:
        print_json({"topic": name, "msg_type": msg_type.type_name(), "published": count})
    else:
        say(f"published {count} x {msg_type.type_name()} on {name}")


def _offer(received: queue.Queue[Any], value: Any) -> None:
    # Never blocks the delivery thread: when printing falls behind, newer values are dropped.
    with contextlib.suppress(queue.Full):
        received.put_nowait(value)


def _wait_for_subscriber(transport: DriverTransport, name: str, wait: float) -> Any:
    """The topic's graph entry once it has a subscriber (or the last one seen, None if none, after ``wait`` s)."""
    deadline = time.monotonic() + wait
    info = None
    while time.monotonic() < deadline:
        info = transport.discover(timeout=min(0.5, max(0.01, deadline - time.monotonic()))).topic(name) or info
        if info is not None and info.subscribers > 0:
            return info
        time.sleep(0.05)
    return info


def _subscriber_warning(info: Any, name: str, type_name: str, wait: float) -> str:
    """What to warn about before publishing: no subscriber (nothing will hear it), or another type on the topic."""
    if info is None or info.subscribers == 0:
        return (f"no subscriber of {name!r} appeared within {wait:g} s: publishing anyway, but nothing may hear it "
                "(a typo in the name? --wait N waits longer)")
    if info.msg_type and info.msg_type != type_name:
        return (f"{name!r} carries {info.msg_type} (its subscribers expect it), not {type_name}: they may drop "
                "or reject this value")
    return ""


class _RateMeter:
    """Counts arrivals in constant memory: count, first and last time, shortest and longest gap."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.count = 0
        self.first = self.last = 0.0
        self.min_gap, self.max_gap = math.inf, 0.0

    def tick(self, _value: Any) -> None:
        now = time.monotonic()
        with self._lock:
            if self.count:
                gap = now - self.last
                self.min_gap, self.max_gap = min(self.min_gap, gap), max(self.max_gap, gap)
            else:
                self.first = now
            self.last = now
            self.count += 1

    def result(self) -> tuple[int, float, float, float]:
        """(messages, rate in Hz, shortest gap, longest gap); rate 0 below two messages."""
        with self._lock:
            if self.count < 2:
                return self.count, 0.0, 0.0, 0.0
            return self.count, (self.count - 1) / (self.last - self.first), self.min_gap, self.max_gap


@app.command("hz")
@one_line_errors
def hz(name: Annotated[str, typer.Argument(help="topic name")], transport: TransportOpt = None,
       connect: ConnectOpt = None, json_out: JsonOpt = False,
       window: Annotated[float, typer.Option("--window", "-w", help="seconds to measure over",
                                             min=0.1, max=MAX_TIMEOUT_S)] = 5.0,
       type_name: Annotated[str | None, typer.Option("--type", help="message type (default: discovered)")] = None,
       discovery_wait: DiscoveryOpt = None, namespace: NamespaceOpt = None) -> None:
    """Measure a topic's message rate over a window."""
    name = _topic_name(name, namespace)
    meter = _RateMeter()
    with open_transport(transport, connect) as t:
        msg_type = _resolve_type(t, name, type_name, discovery_wait)
        subscription = t.create_subscription(Topic(name, msg_type), meter.tick)
        try:
            time.sleep(window)
        finally:
            subscription.close()
    count, rate, min_gap, max_gap = meter.result()
    if count < 2:
        raise ConfigError(f"fewer than two messages on {name!r} in {window:g} s: no rate to measure")
    doc = {"topic": name, "msg_type": msg_type.type_name(), "messages": count, "rate_hz": rate,
           "min_gap_s": min_gap, "max_gap_s": max_gap, "window_s": window}
    if json_out:
        print_json(doc)
    else:
        print_table(f"rate of {name}", ["messages", "rate (Hz)", "min gap (s)", "max gap (s)"],
                    [(count, f"{rate:.2f}", f"{min_gap:.4f}", f"{max_gap:.4f}")])
