"""Episode hooks for an evaluation: one recorded episode per evaluated episode.

The evaluation runner (:mod:`agents_core.evals`) calls, in its own process, each hook's
``on_episode_start(episode, seed)`` right after it resets the world and ``on_episode_end(result)``
with the episode's ``results.jsonl`` line. :class:`EpisodeRecordingHooks` starts an episode of its
:class:`~agents_core.episodes.recorder.EpisodeRecorder` at the first and stops it at the second,
with the result's ``success`` as the episode's outcome and the rest of the line (less its
per-step lists) in the sidecar's ``extra``, so the exported dataset knows which seed each episode ran.

The recorder may be the hooks' own (:meth:`EpisodeRecordingHooks.attached`: subscribed on a transport
the caller has), or an :class:`~agents_core.episodes.component.EpisodeRecorderComponent` in the
evaluation's recipe (:meth:`EpisodeRecordingHooks.for_component`), driven directly in this process or
through its ``execute_method`` service when it runs in a process of its own.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import ConfigError
from .recorder import EpisodeLimits, EpisodeRecorder

if TYPE_CHECKING:
    from ..topics import Topic
    from ..transport.contract import Transport
    from .component import EpisodeRecorderComponent

__all__ = ["EpisodeRecordingHooks"]

logger = logging.getLogger(__name__)

#: The result fields that are per-step lists or file names: left out of the sidecar.
_BULKY = ("rewards", "frames")


class _Target(Protocol):
    def start(self, task: str, before_s: float, extra: dict[str, Any]) -> None: ...
    def stop(self, success: bool | None, extra: dict[str, Any]) -> dict[str, Any]: ...
    def recording(self) -> bool: ...
    def close(self) -> None: ...


class _Local:
    """An :class:`EpisodeRecorder` in this process."""

    def __init__(self, recorder: EpisodeRecorder, owned: bool) -> None:
        self.recorder, self.owned = recorder, owned

    def start(self, task: str, before_s: float, extra: dict[str, Any]) -> None:
        self.recorder.start_episode(task, before_s=before_s, extra=extra)

    def stop(self, success: bool | None, extra: dict[str, Any]) -> dict[str, Any]:
        return self.recorder.stop_episode(success, extra=extra).to_json()

    def recording(self) -> bool:
        return self.recorder.recording is not None

    def close(self) -> None:
        if self.owned:
            self.recorder.close()


class _Remote:
    """An :class:`~agents_core.episodes.component.EpisodeRecorderComponent`, through its ``execute_method``."""

    def __init__(self, transport: Transport, component: str, timeout: float) -> None:
        self.transport, self.service, self.timeout = transport, f"{component}/execute_method", timeout

    def _call(self, method: str, **kwargs: Any) -> Any:
        reply = self.transport.request(self.service, {"method": method, "kwargs": kwargs, "timeout": self.timeout},
                                       timeout=self.timeout + 5.0)
        return reply.get("result") if isinstance(reply, dict) else None

    def start(self, task: str, before_s: float, extra: dict[str, Any]) -> None:
        self._call("start_episode", task=task, before_s=before_s, extra=extra)

    def stop(self, success: bool | None, extra: dict[str, Any]) -> dict[str, Any]:
        result = self._call("stop_episode", success=success, extra=extra)
        return result if isinstance(result, dict) else {}

    def recording(self) -> bool:
        status = self._call("episode_status")
        return isinstance(status, dict) and status.get("recording") is not None

    def close(self) -> None:
        return None


class EpisodeRecordingHooks:
    """Start / stop episodes around an evaluation's episodes (the runner's ``EpisodeHooks``).

    :param recorder: the :class:`EpisodeRecorder` to drive (made and attached by :meth:`attached`, or the
        recipe's component's, see :meth:`for_component`).
    :param task: the task text of every episode (LeRobot's ``task``).
    :param before_s: seconds of the pre-buffer each episode keeps from before its start.
    """

    def __init__(self, recorder: EpisodeRecorder | None = None, *, task: str = "", before_s: float = 0.0,
                 _target: _Target | None = None) -> None:
        if _target is None:
            if recorder is None:
                raise ConfigError("EpisodeRecordingHooks: give a recorder (or use attached() / for_component())")
            _target = _Local(recorder, owned=False)
        self._target = _target
        self.task = task
        self.before_s = before_s
        #: The sidecar documents of the episodes recorded, in order.
        self.recorded: list[dict[str, Any]] = []

    @classmethod
    def attached(cls, transport: Transport, topics: Sequence[Topic], directory: str | os.PathLike[str], *,
                 task: str = "", limits: EpisodeLimits | None = None, **options: Any) -> EpisodeRecordingHooks:
        """Hooks with a recorder of their own subscribed to ``topics`` on ``transport``; :meth:`close` ends it."""
        recorder = EpisodeRecorder(directory, limits=limits, **options).attach(transport, topics)
        return cls(task=task, _target=_Local(recorder, owned=True))

    @classmethod
    def for_component(cls, component: EpisodeRecorderComponent | str, *, transport: Transport | None = None,
                      task: str = "", before_s: float = 0.0, timeout: float = 60.0) -> EpisodeRecordingHooks:
        """Hooks that drive a recipe's :class:`~agents_core.episodes.component.EpisodeRecorderComponent`.

        Give the component itself when it runs in this process (the evaluation's recipe without
        ``world_process``), or its name and a ``transport`` on which its ``execute_method`` service is
        reached (a component in a process of its own, on Zenoh or ROS 2).
        """
        if isinstance(component, str):
            if transport is None:
                raise ConfigError(f"EpisodeRecordingHooks.for_component({component!r}): a component name needs "
                                  "the transport to reach it on")
            return cls(task=task, before_s=before_s, _target=_Remote(transport, component, timeout))
        return cls(task=task, before_s=before_s, _target=_Component(component))

    def on_episode_start(self, episode: int, seed: int) -> None:
        """The runner's hook: start recording (ending a previous episode left running)."""
        if self._target.recording():
            logger.warning("episode hooks: the previous episode was still recording at the start of episode %d; "
                           "it is stopped with an unknown outcome", episode)
            self.recorded.append(self._target.stop(None, {}))
        self._target.start(self.task, self.before_s, {"evaluation_episode": int(episode), "seed": int(seed)})

    def on_episode_end(self, result: Mapping[str, Any]) -> None:
        """The runner's hook: stop recording with the result's ``success``."""
        if not self._target.recording():
            logger.warning("episode hooks: episode %s ended with nothing recording", result.get("episode"))
            return
        success = result.get("success")
        kept = {k: v for k, v in result.items() if k not in _BULKY}
        self.recorded.append(self._target.stop(success if isinstance(success, bool) else None, {"result": kept}))

    def close(self) -> None:
        """Close a recorder the hooks made (a running episode ends as ``"closed"``)."""
        self._target.close()


class _Component:
    """A recipe's recorder component in this process (its recorder exists while it is active)."""

    def __init__(self, component: EpisodeRecorderComponent) -> None:
        self.component = component

    def _recorder(self) -> EpisodeRecorder:
        recorder = self.component.recorder
        if recorder is None:
            raise ConfigError(f"episode hooks: component {self.component.component_name!r} is not active here "
                              "(in a process of its own? give its name and a transport to for_component)")
        return recorder

    def start(self, task: str, before_s: float, extra: dict[str, Any]) -> None:
        self._recorder().start_episode(task, before_s=before_s, extra=extra)

    def stop(self, success: bool | None, extra: dict[str, Any]) -> dict[str, Any]:
        return self._recorder().stop_episode(success, extra=extra).to_json()

    def recording(self) -> bool:
        return self._recorder().recording is not None

    def close(self) -> None:
        return None
