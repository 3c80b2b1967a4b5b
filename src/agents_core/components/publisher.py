"""``ComponentPublisher``: a component's publisher for one output topic.

Its pre-processors run before the value is validated and sent; a pre-processor that returns None
means "nothing to publish" (as upstream), and an output of a step that a deactivate overtook is
discarded: both are counted, neither is an error.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..errors import ComponentError, TransportClosedError
from ..topics import Topic
from ..types.base import convert_published

if TYPE_CHECKING:
    from ..runtime.component_runtime import ComponentRuntime
    from ..transport.contract import Publisher

__all__ = ["ComponentPublisher"]

logger = logging.getLogger(__name__)


class ComponentPublisher:
    """A component's publisher for one output topic, applying its pre-processors before sending."""

    def __init__(self, topic: Topic, component_name: str, runtime: ComponentRuntime) -> None:
        self.topic = topic
        self._component_name = component_name
        self._runtime = runtime
        self._preprocessors: list[Callable[[Any], Any]] = []
        self._publisher: Publisher | None = None
        self._skipped = 0

    @property
    def skipped_outputs(self) -> int:
        """Values a pre-processor turned into None, so not published."""
        return self._skipped

    def attach(self, publisher: Publisher) -> None:
        """Publish through ``publisher`` from now on (at activate)."""
        self._publisher = publisher

    def detach(self) -> None:
        """Close the transport publisher (at deactivate); publishing is refused until attached again."""
        publisher, self._publisher = self._publisher, None
        if publisher is not None:
            publisher.close()

    @property
    def has_preprocessors(self) -> bool:
        """Whether values are transformed before publishing (so any value may be given to :meth:`publish`)."""
        return bool(self._preprocessors)

    def add_preprocessor(self, func: Callable[[Any], Any]) -> None:
        """Transform every value with ``func`` before it is published (in the order added)."""
        self._preprocessors.append(func)

    def publish(self, value: Any, **kwargs: Any) -> None:
        """Apply pre-processors, validate against the topic type and send.

        Keyword arguments (``stream=``, ``done=``, ``frame_id=``, ...) reach the topic type's
        ``convert(output, **kwargs)`` (see :func:`~agents_core.types.base.convert_published`).

        An output of a step that a deactivate overtook is discarded and counted
        (``Component.discarded_outputs``), not an error: the component was asked to stop.
        """
        runtime = self._runtime
        publisher = self._publisher
        if publisher is None:
            if runtime.in_overtaken_step():
                runtime.discard_output(self.topic.name)
                return
            raise ComponentError(f"component {self._component_name!r}: output {self.topic.name!r} is not active")
        for func in self._preprocessors:
            value = func(value)
            if value is None:
                self._skipped += 1
                logger.debug("component %r: a pre-processor of %r returned None; nothing published",
                             self._component_name, self.topic.name)
                return
        if kwargs:
            value = convert_published(self.topic.msg_type, value, **kwargs)
        try:
            publisher.publish(value)
        except TransportClosedError:
            if runtime.in_overtaken_step():
                runtime.discard_output(self.topic.name)
                return
            raise
