"""Record a recipe's topics into MCAP and play them back, on any transport (``pip install 'agents-core[record]'``).

- :class:`Recorder`: chosen topics (or all) and the components' status topics into an MCAP file
  (or a split series), through a bounded queue that never blocks the recipe; crash-safe up to the
  last flushed chunk (:mod:`.recorder`, :mod:`.writer`).
- :class:`Player`: a recording published into a recipe at the recorded pace, faster, or stepwise,
  with topic remapping and looping (:mod:`.player`).
- :func:`read_recording`: the recorded values, for tests and tools (:mod:`.reader`).
- How values are encoded: ROS 2 CDR with ``.msg`` schemas where a type has a ROS form, the
  framework's msgpack wire form otherwise (:mod:`.encodings`).

The test helper that turns a recording into a regression test is
:func:`agents_core.testing.replay.replay_recording`. See ``docs/recording.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade
from .player import PlaybackStatistics as PlaybackStatistics
from .player import Player as Player
from .reader import ReadSummary as ReadSummary
from .reader import RecordedMessage as RecordedMessage
from .reader import RecordingError as RecordingError
from .reader import read_recording as read_recording
from .recorder import Recorder as Recorder
from .recorder import RecorderStatistics as RecorderStatistics
from .writer import RecordingLimits as RecordingLimits

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__)
