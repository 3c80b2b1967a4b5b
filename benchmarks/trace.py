"""Stage timestamps for the hop profile: where a round trip spends its time, stage by stage.

Only :mod:`benchmarks.profile_hop` turns this on (``BENCH_TRACE=<file>`` in a relay's
environment); the measured benchmarks never do. When on, the methods a message passes through
are wrapped to append ``(time.perf_counter_ns(), label)`` to :data:`EVENTS` on entry (``label>``)
and exit (``label<``). ``perf_counter_ns`` is ``CLOCK_MONOTONIC`` on Linux, one clock for every
process of the host, so the events of the pinger and of the relay can be merged into one timeline.
Each event costs well under a microsecond; the traced round trip is slightly slower than the
untraced one, so the profile reports stage shares, and the benchmark reports the times.
"""

from __future__ import annotations

import functools
import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: (perf_counter_ns, label) in the order they happened (list.append is atomic under the GIL).
EVENTS: list[tuple[int, str]] = []

ENV_VAR = "BENCH_TRACE"


def enabled() -> bool:
    return bool(os.environ.get(ENV_VAR))


def mark(label: str) -> None:
    EVENTS.append((time.perf_counter_ns(), label))


def wrapped(func: Callable[..., Any], label: str, only: Callable[[tuple[Any, ...]], bool] | None = None,
            ) -> Callable[..., Any]:
    """``func`` with an event on entry and exit (when ``only(args)`` holds)."""
    append, clock = EVENTS.append, time.perf_counter_ns

    @functools.wraps(func)
    def traced(*args: Any, **kwargs: Any) -> Any:
        keep = only is None or only(args)
        if keep:
            append((clock(), label + ">"))
        try:
            return func(*args, **kwargs)
        finally:
            if keep:
                append((clock(), label + "<"))

    return traced


def maybe_wrapped(func: Callable[..., Any], label: str) -> Callable[..., Any]:
    """``func`` traced when tracing is on, else ``func`` itself."""
    return wrapped(func, label) if enabled() else func


def _patch(owner: Any, name: str, label: str, only: Callable[[tuple[Any, ...]], bool] | None = None) -> None:
    setattr(owner, name, wrapped(getattr(owner, name), label, only))


def _bench_topic(args: tuple[Any, ...]) -> bool:
    topic = getattr(args[0], "topic", None) or getattr(args[0], "input_topic", None)
    return topic is not None and topic.name.startswith("bench/")


def _bench_type(args: tuple[Any, ...]) -> bool:
    return args[0].type_name() in ("String", "Image")


def install_framework(transport: str) -> None:
    """Wrap the framework's message path (core, and the ``transport`` adapter)."""
    from agents_core.callbacks import GenericCallback  # noqa: PLC0415
    from agents_core.components.component_base import Component  # noqa: PLC0415
    from agents_core.runtime.worker import StepWorker  # noqa: PLC0415
    from agents_core.transport.core import CorePublisher  # noqa: PLC0415
    from agents_core.transport.delivery import BoundedDelivery, InlineDelivery  # noqa: PLC0415

    _patch(BoundedDelivery, "offer", "queue_to_delivery_thread", _bench_topic)
    _patch(InlineDelivery, "offer", "inline_delivery", _bench_topic)
    _patch(CorePublisher, "publish", "publish", _bench_topic)
    _patch(GenericCallback, "_receive", "component_callback", _bench_topic)
    _patch(StepWorker, "submit_step", "queue_to_worker")
    _patch(Component, "_run_step", "step", lambda args: args[2] is not None)
    if transport == "zenoh":
        from agents_zenoh import pubsub  # noqa: PLC0415

        _patch(pubsub.ZenohSubscription, "_on_sample", "zenoh_callback", _bench_topic)
        from agents_zenoh.codecs import registry  # noqa: PLC0415

        _patch(registry, "unpack", "decode")  # where decode_value and decoder_for look it up
        _patch(pubsub.ZenohPublisher, "send", "send", _bench_topic)
        _patch(pubsub, "encode_value", "encode", _bench_type)
    elif transport == "ros2":
        import rclpy.publisher  # noqa: PLC0415

        from agents_ros2 import transport as ros  # noqa: PLC0415

        _patch(ros._Ros2Subscription, "_on_message", "rclpy_callback", _bench_topic)
        _patch(ros._Ros2Publisher, "send", "send", _bench_topic)
        _patch(rclpy.publisher.Publisher, "publish", "rclpy_publish",
               lambda args: str(getattr(args[0], "topic_name", "")).startswith("/bench/"))


def dump(path: str | Path, role: str) -> None:
    """Write the events, labels prefixed with ``role:``, as JSON."""
    Path(path).write_text(json.dumps([[t, f"{role}:{label}"] for t, label in EVENTS]))
