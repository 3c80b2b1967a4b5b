"""``EpisodeRecorderComponent``: episode recording as a component of a recipe, driven by actions.

Its inputs are the topics to record (any types the MCAP recorder can write); it has no trigger
and no outputs. Every value of an input goes, on the middleware's thread, to an
:class:`~agents_core.episodes.recorder.EpisodeRecorder` made when the component activates and
closed when it deactivates. Three component actions drive it, callable from an ``Action`` on an
event, from another component's ``execute_method`` service, or from the Cortex planner:

- ``record_episode(before_s, after_s, task)``: the last ``before_s`` seconds and the next ``after_s``;
- ``start_episode(task)`` / ``stop_episode(success)``: an episode of explicit bounds.

Each returns a small JSON document (the episode's number and file, and for ``stop_episode`` what
was written). Example::

    recorder = EpisodeRecorderComponent(inputs=[joints, camera, command],
                                        config=EpisodeRecorderConfig(directory="episodes"),
                                        component_name="episodes")
    launcher.add_pkg(components=[recorder, ...])
    launcher.on_event(gripper_dropped, Action(recorder.record_episode, kwargs={"before_s": 5, "after_s": 2}))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from attrs import define, field

from .. import base_validators
from ..actions import component_action
from ..components.component_base import Component
from ..config import BaseComponentConfig
from ..errors import ConfigError
from ..topics import Topic
from .recorder import EpisodeInfo, EpisodeLimits, EpisodeRecorder

__all__ = ["EpisodeRecorderComponent", "EpisodeRecorderConfig"]

_MiB = 2**20


def _optional_positive(instance: Any, attribute: Any, value: Any) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int | float) or not value > 0):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name}: expected a number > 0 or None, got {value!r}")


@define(kw_only=True)
class EpisodeRecorderConfig(BaseComponentConfig):
    """Settings of the :class:`EpisodeRecorderComponent`.

    :param directory: where the episode files go.
    :param buffer_s: seconds the pre-buffer reaches back (the most ``before_s`` may ask).
    :param buffer_mb: MiB the pre-buffer may hold.
    :param queue_mb: MiB of values waiting for the writer before new ones are dropped.
    :param max_episode_mb: an episode is cut past this many MiB written (None: no cap).
    :param max_episode_s: an episode is cut past this many seconds (None: no cap).
    :param encoding: ``cdr`` or ``msgpack`` (see :mod:`agents_core.recording.encodings`).
    """

    directory: str = field(default="episodes")
    buffer_s: float = field(default=10.0, validator=base_validators.in_range(0.0, 3600.0))
    buffer_mb: float = field(default=256.0, validator=base_validators.in_range(0.01, 1_000_000.0))
    queue_mb: float = field(default=128.0, validator=base_validators.in_range(0.01, 1_000_000.0))
    max_episode_mb: float | None = field(default=2048.0, validator=_optional_positive)
    max_episode_s: float | None = field(default=3600.0, validator=_optional_positive)
    encoding: str = field(default="cdr", validator=base_validators.in_(["cdr", "msgpack"]))

    def limits(self) -> EpisodeLimits:
        """These settings as :class:`~agents_core.episodes.recorder.EpisodeLimits`."""
        return EpisodeLimits(buffer_s=self.buffer_s, buffer_bytes=int(self.buffer_mb * _MiB),
                             queue_bytes=int(self.queue_mb * _MiB),
                             max_episode_bytes=None if self.max_episode_mb is None else int(self.max_episode_mb * _MiB),
                             max_episode_s=self.max_episode_s)


def _summary(info: EpisodeInfo) -> dict[str, Any]:
    return {"episode": info.episode, "mcap": str(info.mcap), "task": info.task, "trigger": info.trigger,
            "ended": info.ended if info.ended_ns != 0 else None, "reason": info.reason,
            "messages": info.messages, "bytes": info.bytes, "dropped": info.dropped, "success": info.success}


class EpisodeRecorderComponent(Component):
    """Records its inputs into episodes (see the module docstring).

    :param inputs: the topics to record.
    :param config: an :class:`EpisodeRecorderConfig`.
    :param component_name: the component's name (its actions are ``<name>/execute_method``).
    """

    config_class = EpisodeRecorderConfig

    def __init__(self, inputs: Sequence[Topic] | None = None, config: EpisodeRecorderConfig | None = None,
                 component_name: str = "episode_recorder", **kwargs: Any) -> None:
        if not inputs:
            raise ConfigError(f"component {component_name!r}: give the topics to record as inputs")
        super().__init__(inputs=inputs, outputs=None, config=config, trigger=None, component_name=component_name,
                         run_type="Server", **kwargs)
        self.config: EpisodeRecorderConfig
        self.recorder: EpisodeRecorder | None = None
        for topic in self.inputs:
            callback = self.callbacks.get(topic.name) or self.trig_callbacks[topic.name]
            callback.on_callback_execute(self._offer_for(topic))

    @classmethod
    def _server_capable(cls) -> bool:
        return True

    def _offer_for(self, topic: Topic) -> Callable[[Any], None]:
        def offer(value: Any) -> None:
            recorder = self.recorder
            if recorder is not None:
                recorder.offer(topic.name, topic.msg_type, value)
        return offer

    def custom_on_activate(self) -> None:
        self.recorder = EpisodeRecorder(self.config.directory, limits=self.config.limits(),
                                        encoding="msgpack" if self.config.encoding == "msgpack" else "cdr",
                                        name=self.component_name)

    def custom_on_deactivate(self) -> None:
        recorder, self.recorder = self.recorder, None
        if recorder is not None:
            recorder.close()

    def _require(self) -> EpisodeRecorder:
        if self.recorder is None:
            raise ConfigError(f"component {self.component_name!r} is not active: no recorder")
        return self.recorder

    def _execution_step(self, **kwargs: Any) -> None:
        return None

    @component_action(description={
        "description": "Save the last before_s seconds and the next after_s seconds of the recorded topics "
                       "as one episode.",
        "parameters": {"type": "object", "properties": {
            "before_s": {"type": "number", "description": "seconds before now to keep"},
            "after_s": {"type": "number", "description": "seconds after now to record"},
            "task": {"type": "string", "description": "what the episode is about"}}, "required": []}})
    def record_episode(self, before_s: float = 5.0, after_s: float = 5.0, task: str = "") -> dict[str, Any]:
        """Save the last ``before_s`` seconds and the next ``after_s`` seconds as one episode."""
        return _summary(self._require().record_episode(float(before_s), float(after_s), str(task)))

    @component_action(description={
        "description": "Start recording an episode now.",
        "parameters": {"type": "object", "properties": {
            "task": {"type": "string", "description": "what the episode is about"},
            "before_s": {"type": "number", "description": "seconds of the pre-buffer to keep (default 0)"}},
            "required": []}})
    def start_episode(self, task: str = "", before_s: float = 0.0, extra: dict[str, Any] | None = None
                      ) -> dict[str, Any]:
        """Start recording an episode now (an error if one is running); ``extra`` goes into its sidecar."""
        return _summary(self._require().start_episode(str(task), before_s=float(before_s), extra=_extra(extra)))

    @component_action(description={
        "description": "End the running episode and write its file.",
        "parameters": {"type": "object", "properties": {
            "success": {"type": ["boolean", "null"], "description": "whether the episode's task succeeded"}},
            "required": []}})
    def stop_episode(self, success: bool | None = None, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """End the running episode, write its file; returns what was written."""
        if success is not None and not isinstance(success, bool):
            raise ConfigError(f"component {self.component_name!r}: success must be true, false or null")
        return _summary(self._require().stop_episode(success, extra=_extra(extra)))

    @component_action(description={
        "description": "The episode being recorded now (null when none), and how many were written.",
        "parameters": {"type": "object", "properties": {}, "required": []}})
    def episode_status(self) -> dict[str, Any]:
        """The running episode (None when none runs), the episodes written, the pre-buffer's fill."""
        recorder = self._require()
        running = recorder.recording
        stats = recorder.statistics()
        return {"recording": None if running is None else _summary(running), "episodes": stats.episodes,
                "buffered_bytes": stats.buffered_bytes, "received": stats.received}


def _extra(extra: Any) -> dict[str, Any] | None:
    if extra is None:
        return None
    if not isinstance(extra, dict) or not all(isinstance(k, str) for k in extra):
        raise ConfigError("extra must be a JSON object (a dict with string keys)")
    return extra
