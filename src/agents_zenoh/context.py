"""What the Zenoh driver's handles share: the session, where names live in the key space, the priorities.

:class:`~agents_zenoh.transport.ZenohDriver` opens the session and builds one :class:`ZenohContext`;
every handle it creates (publishers and subscribers in :mod:`agents_zenoh.pubsub`, services and
presence in :mod:`agents_zenoh.queryables`, goals in :mod:`agents_zenoh.goals`, graph tokens in
:mod:`agents_zenoh.graph`) gets the context, not the driver. So the handles depend on this module
only, and none of them reaches into the driver.
"""

from __future__ import annotations

import logging
from typing import Any

import zenoh

from agents_core.errors import TransportClosedError
from agents_core.topics import Topic

from .config import ZenohConfig
from .keys import goal_key, topic_key
from .shm import ShmPool

__all__ = ["CONTROL_PRIORITY", "ZenohContext", "undeclare"]

logger = logging.getLogger(__name__)

#: The priority of requests, lifecycle queries and goal traffic, so they never queue behind bulk data.
CONTROL_PRIORITY = zenoh.Priority.INTERACTIVE_HIGH


class ZenohContext:
    """One driver's session and settings, as its handles use them.

    :param session: the driver's open Zenoh session.
    :param config: the driver's :class:`~agents_zenoh.config.ZenohConfig` (read when a key or a
        priority is asked for, as the driver reads it).
    """

    def __init__(self, session: zenoh.Session, config: ZenohConfig) -> None:
        self._session: zenoh.Session | None = session
        self._config = config
        #: Where large payloads are put from (see :mod:`agents_zenoh.shm`); None unless ``shm_threshold`` is set.
        self.shm: ShmPool | None = None
        if config.shared_memory and config.shm_threshold is not None:
            self.shm = ShmPool(config.shm_pool_size, config.shm_threshold)

    @property
    def session(self) -> zenoh.Session:
        """The Zenoh session; :class:`~agents_core.errors.TransportClosedError` once the driver closed it."""
        session = self._session
        if session is None:
            raise TransportClosedError("the zenoh transport is closed")
        return session

    @property
    def closed(self) -> bool:
        """Whether the driver has closed (or is closing) the session."""
        return self._session is None

    def check_open(self, what: str) -> None:
        """Raise :class:`~agents_core.errors.TransportClosedError` naming ``what`` if the session is closed."""
        if self._session is None:
            raise TransportClosedError(f"{what}: the zenoh transport is closed")

    def close(self) -> None:
        """Mark the session closed and drop this reference to it (the driver closes the session itself).

        Zenoh unlinks its shared-memory segment only when the last reference to the session goes,
        and a handle may outlive the driver (a step still running on a daemon thread at exit).
        """
        self._session = None

    @property
    def namespace(self) -> str:
        """The key-space prefix of every key of this driver ('' for none)."""
        return self._config.namespace

    @property
    def match_timeout(self) -> float:
        """How long a new publisher waits (at most) for its first subscriber before its first put."""
        return self._config.match_timeout

    def key(self, name: str, what: str = "topic") -> str:
        """The key expression of a topic, service or action ``name`` (see :mod:`agents_zenoh.keys`)."""
        return topic_key(self._config.namespace, name, what)

    def goal_key(self, name: str, *parts: str) -> str:
        """The key ``<ns>/<name>/@action/<parts...>`` of the goals of action ``name``."""
        return goal_key(self._config.namespace, name, *parts)

    def priority(self, topic: Topic) -> zenoh.Priority:
        """The Zenoh priority of ``topic``'s samples: :attr:`ZenohConfig.priorities`, else ``data``."""
        name = self._config.priorities.get(topic.name, "data")
        priority: zenoh.Priority = getattr(zenoh.Priority, name.upper())
        return priority


def undeclare(entity: Any) -> None:
    """Undeclare a Zenoh entity, tolerating a session that is already closed."""
    try:
        entity.undeclare()
    except zenoh.ZError as exc:
        # Fails harmlessly once the session is closed; keep a trace at debug level anyway.
        logger.debug("undeclare failed: %s", exc)
