"""The client of a LeRobot policy server and its wire format.

:mod:`.client` holds :class:`LeRobotClient`; :mod:`.protocol` the gRPC service and the messages
LeRobot's async inference exchanges (needs grpcio and protobuf, imported when a client first
talks); :mod:`.restricted_pickle` the unpickler that accepts only the globals those messages need.
``LeRobotClient`` is imported on first use (PEP 562).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...support.lazy import lazy_facade

if TYPE_CHECKING:
    from .client import LeRobotClient as LeRobotClient
else:
    __getattr__, __dir__ = lazy_facade(__name__)
