"""Episodes as data: record a recipe's topics as episodes and export them as a LeRobot dataset.

- :class:`EpisodeRecorder`: values in, episodes out (an MCAP file and a JSON sidecar each), with a
  pre-buffer bounded in bytes and seconds, event-triggered (``record_episode(before_s, after_s)``)
  or explicit (``start_episode`` / ``stop_episode``) episodes, and size / duration caps
  (:mod:`.recorder`, :mod:`.buffer`).
- :class:`EpisodeRecorderComponent`: the same as a recipe component whose actions drive it
  (:mod:`.component`).
- :class:`EpisodeRecordingHooks`: one recorded episode per evaluated episode (:mod:`.hooks`).
- :func:`export_lerobot_dataset`: episodes to a LeRobotDataset v3.0 folder (parquet, mp4, ``meta/``),
  with ``pip install 'agents-core[dataset]'`` (pyarrow, PyAV); no LeRobot or torch needed
  (:mod:`.lerobot_export`).

Recording needs the ``record`` extra (the MCAP writer). See ``docs/episodes.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade
from .buffer import PreBuffer as PreBuffer
from .buffer import value_bytes as value_bytes
from .hooks import EpisodeRecordingHooks as EpisodeRecordingHooks
from .recorder import EpisodeError as EpisodeError
from .recorder import EpisodeInfo as EpisodeInfo
from .recorder import EpisodeLimits as EpisodeLimits
from .recorder import EpisodeRecorder as EpisodeRecorder
from .recorder import EpisodeRecorderStatistics as EpisodeRecorderStatistics
from .recorder import load_episodes as load_episodes

# The component pulls in the component runtime, the export pyarrow / PyAV: loaded when first used.
if TYPE_CHECKING:
    from .component import EpisodeRecorderComponent as EpisodeRecorderComponent
    from .component import EpisodeRecorderConfig as EpisodeRecorderConfig
    from .lerobot_export import ExportSummary as ExportSummary
    from .lerobot_export import LeRobotFeature as LeRobotFeature
    from .lerobot_export import export_lerobot_dataset as export_lerobot_dataset
else:
    __getattr__, __dir__ = lazy_facade(__name__)
