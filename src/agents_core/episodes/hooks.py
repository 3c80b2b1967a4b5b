"""Episode hooks for an evaluation: one recorded episode per evaluated episode.

The evaluation runner (:mod:`agents_core.evals`) calls, in its own process, each hook's
``on_episode_start(episode, seed)`` right after it resets the world and ``on_episode_end(result)``
with the episode's ``results.jsonl`` line. :class:`EpisodeRecordingHooks` starts an episode of its
:class:`~agents_core.episodes.recorder.EpisodeRecorder` at the first and stops it at the second,
with the result's ``success`` as the episode's outcome and the rest of the line (less its
per-step lists) in the sidecar's ``extra``, so the exported dataset knows which seed each episode ran.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from .recorder import EpisodeInfo, EpisodeLimits, EpisodeRecorder

if TYPE_CHECKING:
    from ..topics import Topic
    from ..transport.contract import Transport

__all__ = ["EpisodeRecordingHooks"]

logger = logging.getLogger(__name__)

#: The result fields that are per-step lists or file names: left out of the sidecar.
_BULKY = ("rewards", "frames")


class EpisodeRecordingHooks:
    """Start / stop ``recorder``'s episodes around an evaluation's episodes (the runner's ``EpisodeHooks``).

    :param recorder: the recorder (attached to the evaluation's transport, see :meth:`attached`).
    :param task: the task text of every episode (LeRobot's ``task``).
    :param before_s: seconds of the pre-buffer each episode keeps from before its start.
    """

    def __init__(self, recorder: EpisodeRecorder, *, task: str = "", before_s: float = 0.0) -> None:
        self.recorder = recorder
        self.task = task
        self.before_s = before_s
        #: The episodes recorded, in order.
        self.recorded: list[EpisodeInfo] = []

    @classmethod
    def attached(cls, transport: Transport, topics: Sequence[Topic], directory: str | os.PathLike[str], *,
                 task: str = "", limits: EpisodeLimits | None = None, **options: Any) -> EpisodeRecordingHooks:
        """Hooks with a recorder of their own subscribed to ``topics`` on ``transport``; :meth:`close` ends it."""
        recorder = EpisodeRecorder(directory, limits=limits, **options).attach(transport, topics)
        return cls(recorder, task=task)

    def on_episode_start(self, episode: int, seed: int) -> None:
        """The runner's hook: start recording (ending a previous episode left running)."""
        if self.recorder.recording is not None:
            logger.warning("episode hooks: the previous episode was still recording at the start of episode %d; "
                           "it is stopped with an unknown outcome", episode)
            self.recorded.append(self.recorder.stop_episode(None))
        self.recorder.start_episode(self.task, before_s=self.before_s,
                                    extra={"evaluation_episode": int(episode), "seed": int(seed)})

    def on_episode_end(self, result: Mapping[str, Any]) -> None:
        """The runner's hook: stop recording with the result's ``success``."""
        if self.recorder.recording is None:
            logger.warning("episode hooks: episode %s ended with nothing recording", result.get("episode"))
            return
        success = result.get("success")
        kept = {k: v for k, v in result.items() if k not in _BULKY}
        self.recorded.append(self.recorder.stop_episode(success if isinstance(success, bool) else None,
                                                        extra={"result": kept}))

    def close(self) -> None:
        """Close the recorder (a running episode ends as ``"closed"``)."""
        self.recorder.close()
