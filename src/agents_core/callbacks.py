"""Input callbacks: what a component reads its inputs from.

A component has one callback per input topic (``self.callbacks`` / ``self.trig_callbacks``,
keyed by topic name). The transport thread only stores the received value (and enqueues a step
for a trigger topic); ``_execution_step`` reads it with :meth:`GenericCallback.get_output`.

During a step fired by a trigger topic, that topic's ``get_output()`` returns the very message
that fired the step, even if newer ones arrived meanwhile, so every triggering message is
processed once, in order. Other inputs give their latest value.

A message type may name its own callback class (``SupportedType.callback``, the upstream hook):
a :class:`GenericCallback` subclass overriding :meth:`GenericCallback._msg_to_output` (value ->
what ``get_output()`` returns) or :meth:`GenericCallback._get_output`. :func:`callback_for` creates
it for every input of that type.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from .errors import ConfigError
from .topics import FixedInput, Topic

__all__ = ["DetectionsCallback", "FixedCallback", "GenericCallback", "StreamingStringCallback", "callback_for"]

_UNSET: Any = object()


class GenericCallback:
    """Buffers the latest value of one input topic."""

    def __init__(self, topic: Topic, node_name: str | None = None) -> None:
        self.input_topic = topic
        #: The component that owns this callback (upstream passes it; informational here).
        self.node_name = node_name
        self._lock = threading.Lock()
        self._latest: Any = None
        self._step_value: Any = _UNSET
        self._received = 0
        self._post_callbacks: list[Callable[[Any], None]] = []
        self._postprocessors: list[Callable[[Any], Any]] = []

    @property
    def got_msg(self) -> bool:
        """True once any value has been received."""
        return self._received > 0

    @property
    def received(self) -> int:
        """How many values arrived so far."""
        return self._received

    @property
    def msg(self) -> Any:
        """The latest received value in its message form (e.g. an ImageMsg with its header)."""
        if self._step_value is not _UNSET:
            return self._step_value
        return self._latest

    def on_callback_execute(self, func: Callable[[Any], None]) -> None:
        """Also call ``func(value)`` on every arrival (on the transport's thread: keep it short)."""
        self._post_callbacks.append(func)

    def add_post_processor(self, func: Callable[[Any], Any]) -> None:
        """Transform the output of :meth:`get_output` with ``func`` (applied in the order added)."""
        self._postprocessors.append(func)

    def _receive(self, value: Any) -> None:
        with self._lock:
            self._latest = value
            self._received += 1
        for func in self._post_callbacks:
            func(value)

    def _clear(self) -> None:
        with self._lock:
            self._latest = None

    def _begin_step(self, value: Any) -> None:
        """Pin the value that fired the current step (read by ``get_output`` until ``_end_step``)."""
        self._step_value = value

    def _end_step(self) -> None:
        self._step_value = _UNSET

    def get_output(self, clear_last: bool = False) -> Any:
        """The value for the current step, converted for use (e.g. an Image as an RGB array).

        None until a value has arrived. ``clear_last`` forgets the latest value after reading
        it, so the next step sees None unless a new one arrives.
        """
        if self.msg is None:
            return None
        out = self._get_output()
        if clear_last and self._step_value is _UNSET:
            self._clear()
        for func in self._postprocessors:
            out = func(out)
        return out

    def _get_output(self, **_: Any) -> Any:
        """The output for the current value (:attr:`msg`, not None); override for more than :meth:`_msg_to_output`."""
        return self._msg_to_output(self.msg)

    def _msg_to_output(self, msg: Any) -> Any:
        """A received value as the component uses it; default: the type's ``to_output`` (an Image as an array)."""
        return self.input_topic.msg_type.to_output(msg)


class FixedCallback(GenericCallback):
    """The callback of a :class:`~agents_core.topics.FixedInput`: always has its fixed value."""

    def __init__(self, topic: FixedInput, node_name: str | None = None) -> None:
        super().__init__(topic, node_name)
        self._latest = topic.fixed
        self._received = 1

    def _clear(self) -> None:
        """A fixed input never forgets its value."""


class StreamingStringCallback(GenericCallback):
    """The callback of ``StreamingString`` inputs: ``get_output()`` is the chunk's text (a ``str``).

    ``msg`` keeps the whole chunk, with its ``stream`` and ``done`` flags.
    """

    def _msg_to_output(self, msg: Any) -> Any:
        return msg if isinstance(msg, str) else msg.data


class DetectionsCallback(GenericCallback):
    """The callback of ``Detections`` inputs: ``get_output()`` gives one dict per detected object.

    Each dict is ``{"label": str, "score": float, "box": [x1, y1, x2, y2]}`` (pixels), in the
    message's order (messages.md: "For Detections, it parses bounding boxes into Python dicts").
    ``msg`` keeps the whole :class:`~agents_core.messages.DetectionsMsg` (image, depth, header).
    """

    def _msg_to_output(self, msg: Any) -> Any:
        return [{"label": str(label), "score": float(score), "box": [float(x) for x in box]}
                for label, score, box in zip(msg.labels, msg.scores, msg.boxes, strict=True)]


def callback_for(topic: Topic, node_name: str | None = None) -> GenericCallback:
    """The callback that fits ``topic``: its type's ``callback`` class if it names one, else GenericCallback."""
    own = getattr(topic.msg_type, "callback", None)
    if own is GenericCallback:
        own = None  # a type naming no callback of its own
    if own is not None and not (isinstance(own, type) and issubclass(own, GenericCallback)):
        raise ConfigError(f"{topic.type_name}.callback must be a GenericCallback subclass, got {own!r}")
    if isinstance(topic, FixedInput):
        if own is None or issubclass(own, FixedCallback):
            return FixedCallback(topic, node_name)
        return _fixed_variant(own)(topic, node_name)
    return (own or GenericCallback)(topic, node_name)


def _fixed_variant(callback: type[GenericCallback]) -> type[FixedCallback]:
    """``callback`` with a fixed value (a FixedInput of a type with its own callback class)."""
    return type(f"Fixed{callback.__name__}", (FixedCallback, callback), {})
