"""A recording as a regression test: play its inputs into a recipe on memory and compare the outputs.

A field failure recorded with ``agentsctl record`` becomes a test in a few lines::

    from agents_core.testing.replay import replay_recording

    def test_the_camera_run_of_tuesday():
        report = replay_recording("tuesday.mcap", build_components, inputs=["camera"],
                                  outputs=["detections"], compare=lambda old, new: old.labels == new.labels)
        report.assert_ok()

``replay_recording`` brings the components up on a fresh memory transport, publishes the
recorded values of ``inputs`` one at a time in recorded order, and after each waits (bounded) for
the outputs recorded for it. Outputs are paired with the recorded ones by their header stamp (a
component stamps its outputs with its input's stamp) and, for values without a header, by order.

``compare`` is ``"exact"`` (:func:`values_equal`: every field, arrays by dtype, shape and content),
a predicate ``(recorded, replayed) -> bool`` (for models whose outputs may vary), or a mapping of
output topic to either. A recorded output with no replayed partner is *missing* (a failure);
a replayed output for an input that had no recorded output (the recipe had lost that input
while recording) is *extra*, a failure only with ``strict=True``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np
from attrs import define, field

from ..errors import ConfigError
from ..launch import Launcher
from ..recording.reader import RecordedMessage, read_recording
from ..topics import Topic
from ..transport.contract import Transport

__all__ = ["Compare", "ReplayReport", "replay_into", "replay_recording", "values_equal"]

Compare = str | Callable[[Any, Any], bool]


def values_equal(a: Any, b: Any) -> bool:
    """Whether two values are the same: attrs classes field by field, numpy arrays by dtype, shape and content."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.dtype == b.dtype
                and a.shape == b.shape and bool(np.array_equal(a, b)))
    if attrs.has(type(a)):
        return type(a) is type(b) and all(values_equal(getattr(a, f.name), getattr(b, f.name))
                                          for f in attrs.fields(type(a)))
    if isinstance(a, (list, tuple)):
        return isinstance(b, (list, tuple)) and len(a) == len(b) and all(map(values_equal, a, b))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(values_equal(a[k], b[k]) for k in a)
    return bool(a == b)


def _stamp(value: Any) -> int | None:
    stamp = getattr(getattr(value, "header", None), "stamp_ns", None)
    return stamp if isinstance(stamp, int) else None


@define
class ReplayReport:
    """What a replay found: pairs compared, mismatches, missing and extra outputs (see the module docstring)."""

    compared: int = 0
    mismatches: list[tuple[str, Any, Any, Any]] = field(factory=list)
    missing: list[tuple[str, Any]] = field(factory=list)
    extra: list[tuple[str, Any]] = field(factory=list)
    inputs: int = 0
    strict: bool = False

    @property
    def ok(self) -> bool:
        """No mismatch, nothing missing, and (with ``strict``) nothing extra."""
        return not self.mismatches and not self.missing and not (self.strict and self.extra)

    def assert_ok(self) -> None:
        """Raise AssertionError describing the first differences unless :attr:`ok`."""
        if self.ok:
            return
        lines = [f"replay of {self.inputs} inputs: {self.compared} outputs compared, {len(self.mismatches)} "
                 f"differ, {len(self.missing)} missing, {len(self.extra)} extra"]
        lines += [f"  differs on {t} at {k}: recorded {r!r:.200} replayed {n!r:.200}" for t, k, r, n in
                  self.mismatches[:5]]
        lines += [f"  missing on {t} at {k}" for t, k in self.missing[:5]]
        raise AssertionError("\n".join(lines))


def _comparer(compare: Compare | Mapping[str, Compare], topic: str) -> Callable[[Any, Any], bool]:
    chosen = compare.get(topic, "exact") if isinstance(compare, Mapping) else compare
    if chosen == "exact":
        return values_equal
    if callable(chosen):
        return chosen
    raise ConfigError(f"compare must be 'exact' or a predicate, got {chosen!r}")


def replay_recording(recording: str | Path, components: Sequence[Any] | Callable[[], Any], *,
                     inputs: Sequence[str], outputs: Sequence[str],
                     compare: Compare | Mapping[str, Compare] = "exact", strict: bool = False,
                     timeout_per_input: float = 10.0, remap: Mapping[str, str] | None = None) -> ReplayReport:
    """Play ``inputs`` of ``recording`` into ``components`` on memory and compare ``outputs`` (module docstring).

    :param components: the recipe's components, or a function that builds them or one (called once).
    :param remap: recorded input topic -> the topic the recipe reads now (a renamed input).
    """
    launcher = Launcher("memory")
    built: Any = components() if callable(components) else components
    launcher.add_pkg(components=list(built) if isinstance(built, (list, tuple)) else [built])
    with launcher:
        return replay_into(launcher.transport, recording, inputs=inputs, outputs=outputs, compare=compare,
                           strict=strict, timeout_per_input=timeout_per_input, remap=remap)


def replay_into(transport: Transport, recording: str | Path, *, inputs: Sequence[str], outputs: Sequence[str],
                compare: Compare | Mapping[str, Compare] = "exact", strict: bool = False,
                timeout_per_input: float = 10.0, remap: Mapping[str, str] | None = None) -> ReplayReport:
    """Play ``inputs`` of ``recording`` into a recipe that is already running on ``transport``; compare ``outputs``.

    The recipe may run in another process (Zenoh, ROS 2): ``transport`` is this process's view of
    it. A new publisher there may not be matched with the recipe's subscription yet (ROS 2 and
    Zenoh discover peers in the background), so on a cross-process transport the first input is
    sent again every second until its outputs arrive (within ``timeout_per_input``); the outputs
    of the copies beyond those recorded are not counted as extra. Otherwise as :func:`replay_recording`.
    """
    recorded_inputs, expected, out_types = _read_expected(recording, inputs, outputs)
    replayed: dict[tuple[str, int | None], list[Any]] = {}
    arrived = threading.Condition()

    def collect(topic: str) -> Callable[[Any], None]:
        def on_value(value: Any) -> None:
            with arrived:
                replayed.setdefault((topic, _stamp(value)), []).append(value)
                arrived.notify_all()
        return on_value

    def have(key: tuple[str, int | None]) -> bool:
        return len(replayed.get(key, ())) >= len(expected.get(key, ()))

    report = ReplayReport(inputs=len(recorded_inputs), strict=strict)
    rename = {k.lstrip("/"): v.lstrip("/") for k, v in (remap or {}).items()}
    resend_first = transport.capabilities.cross_process
    primed: list[tuple[str, int | None]] = []
    subs = [transport.create_subscription(Topic(t, out_types[t]), collect(t)) for t in out_types]
    publishers: dict[str, Any] = {}
    try:
        for index, message in enumerate(recorded_inputs):
            name = rename.get(message.topic, message.topic)
            if name not in publishers:
                publishers[name] = transport.create_publisher(Topic(name, message.msg_type))
            keys = [(t, _stamp(message.value)) for t in out_types]
            deadline = time.monotonic() + timeout_per_input
            resend = resend_first and index == 0
            primed = keys if resend else primed
            while True:
                publishers[name].publish(message.value)
                until = min(deadline, time.monotonic() + 1.0) if resend else deadline
                with arrived:
                    while not all(have(k) for k in keys) and (left := until - time.monotonic()) > 0:
                        arrived.wait(left)
                    done = all(have(k) for k in keys)
                if done or not resend or time.monotonic() >= deadline:
                    break
        deadline = time.monotonic() + timeout_per_input
        with arrived:
            while not all(have(k) for k in expected) and (left := deadline - time.monotonic()) > 0:
                arrived.wait(left)
    finally:
        for sub in subs:
            sub.close()
        for publisher in publishers.values():
            publisher.close()
    with arrived:
        got = {k: list(v) for k, v in replayed.items()}
    for key in primed:  # the copies of the first input answered more than once
        if key in got:
            got[key] = got[key][:max(1, len(expected.get(key, ())))]
    _compare_into(report, expected, got, compare)
    return report


_Keyed = dict[tuple[str, int | None], list[Any]]


def _read_expected(recording: str | Path, inputs: Sequence[str], outputs: Sequence[str],
                   ) -> tuple[list[RecordedMessage], _Keyed, dict[str, Any]]:
    """(the recorded inputs in order, the recorded outputs by (topic, stamp), each output topic's type)."""
    wanted_in = {t.lstrip("/") for t in inputs}
    wanted_out = {t.lstrip("/") for t in outputs}
    recorded_inputs: list[RecordedMessage] = []
    expected: _Keyed = {}
    out_types: dict[str, Any] = {}
    for message in read_recording(recording, topics=wanted_in | wanted_out):
        if message.topic in wanted_in:
            recorded_inputs.append(message)
        if message.topic in wanted_out:
            out_types[message.topic] = message.msg_type
            expected.setdefault((message.topic, _stamp(message.value)), []).append(message.value)
    if not recorded_inputs:
        raise ConfigError(f"{recording}: no recorded message on the inputs {sorted(wanted_in)}")
    return recorded_inputs, expected, out_types


def _compare_into(report: ReplayReport, expected: _Keyed, got: _Keyed,
                  compare: Compare | Mapping[str, Compare]) -> None:
    for key, olds in expected.items():
        news = got.get(key, [])
        same = _comparer(compare, key[0])
        for old, new in zip(olds, news, strict=False):
            report.compared += 1
            if not same(old, new):
                report.mismatches.append((key[0], key[1], old, new))
        report.missing += [key] * max(0, len(olds) - len(news))
    for key, news in got.items():
        report.extra += [key] * max(0, len(news) - len(expected.get(key, ())))
