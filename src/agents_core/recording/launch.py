"""What ``Launcher.record`` runs: a :class:`~.recorder.Recorder` started with the recipe and finished with it.

:meth:`agents_core.launch.Launcher.record` only stores a :class:`RecipeRecording`; the launcher
calls :meth:`RecipeRecording.start` once its transport is up (before the components activate, so
their first outputs are kept) and :meth:`RecipeRecording.stop` after the components shut down and
before the transport closes, so the queue is written and the file finished (summary and footer).
With no topics given it records every input and output of the recipe's components and their
status topics, which needs no discovery and so works on the memory transport too.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError
from ..topics import Topic
from ..transport.core import status_topic
from .recorder import Recorder, RecorderStatistics
from .writer import RecordingLimits, require_mcap

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..transport.contract import Transport

__all__ = ["RecipeRecording", "recipe_topics"]

logger = logging.getLogger(__name__)


def recipe_topics(components: Sequence[Component]) -> list[Topic]:
    """Every input and output of ``components`` (each name once), then each component's status topic."""
    chosen: dict[str, Topic] = {}
    for topic in [t for c in components for t in (*c.inputs, *c.outputs)]:
        chosen.setdefault(topic.name, topic)
    for c in components:
        chosen.setdefault(status_topic(c.component_name).name, status_topic(c.component_name))
    return list(chosen.values())


class RecipeRecording:
    """A recording tied to a launcher's life (see the module docstring).

    :param path: the MCAP file (a split series gets ``_1``, ``_2``, ... before the suffix).
    :param topics: Topics or names to record; None: the components' inputs, outputs and status topics.
    :param limits: size and duration limits.
    :param recorder_options: further :class:`~.recorder.Recorder` keywords (``queue_depth``, ``encoding``, ...).
    """

    def __init__(self, path: str | os.PathLike[str], *, topics: Sequence[Topic | str] | None = None,
                 limits: RecordingLimits | None = None, **recorder_options: Any) -> None:
        require_mcap()  # fail in record(), where the user wrote it, not at start
        unknown = set(recorder_options) - {"include_status", "queue_depth", "queue_bytes", "encoding",
                                           "flush_interval_s", "discover_every_s", "chunk_size", "compression"}
        if unknown:
            raise ConfigError(f"record(): unknown option(s) {sorted(unknown)}")
        self.path = Path(path)
        self._topics = list(topics) if topics is not None else None
        self._limits = limits
        self._options = recorder_options
        self._recorder: Recorder | None = None
        self._final: RecorderStatistics | None = None

    def start(self, components: Sequence[Component], transport: Transport) -> None:
        """Start recording on ``transport`` (the launcher calls it)."""
        topics = self._topics if self._topics is not None else recipe_topics(components)
        self._recorder = Recorder(transport, self.path, topics=topics, limits=self._limits, **self._options)
        self._recorder.start()

    def stop(self) -> RecorderStatistics | None:
        """Write what is queued and finish the file (the launcher calls it); never raises. Idempotent."""
        recorder, self._recorder = self._recorder, None
        if recorder is not None:
            try:
                self._final = recorder.stop()
            except Exception as exc:  # the recipe's own shutdown must go on
                logger.warning("the recording into %s did not finish cleanly: %s", self.path, exc)
        return self._final

    def statistics(self) -> RecorderStatistics | None:
        """The recorder's counters: live while the recipe runs, final after it stopped; None before it started."""
        return self._recorder.statistics() if self._recorder is not None else self._final
