"""Graph discovery on Zenoh: a liveliness token per publisher and subscriber, read back by any peer.

Each publisher and subscriber of a :class:`~agents_zenoh.transport.ZenohDriver` declares a token

``<ns>/@agents/pub/<entity>/<type>/<topic>`` or ``<ns>/@agents/sub/<entity>/<type>/<topic>``

where ``<entity>`` is ``<session zid>_<n>`` (unique, so two publishers of one topic are two
tokens), ``<type>`` the agents_core type name (percent-encoded where it holds a character that
Zenoh key expressions reserve) and ``<topic>`` the topic name, one or more chunks. Components
already have ``<ns>/@agents/components/<name>`` (:mod:`agents_zenoh.keys`). A liveliness
``get`` on ``<ns>/@agents/**`` therefore lists the whole graph, and a token vanishes when its
entity is closed or its process dies (within milliseconds when the TCP link drops).
"""

from __future__ import annotations

import itertools
import logging
from typing import TYPE_CHECKING, Any
from urllib.parse import quote, unquote

import zenoh

from agents_core.errors import TransportError
from agents_core.topics import Topic
from agents_core.transport.graph import Graph, merge_topic_counts

from .keys import PRESENCE_CHUNK

if TYPE_CHECKING:
    from .context import ZenohContext

__all__ = ["EntityToken", "discover_graph", "entity_token_key"]

logger = logging.getLogger(__name__)

_entity_ids = itertools.count()

#: Which role chunk a token has, for a publisher and for a subscriber.
ROLES = ("pub", "sub")


def _join(*parts: str) -> str:
    return "/".join(p for p in parts if p)


def entity_token_key(namespace: str, role: str, entity: str, type_name: str, topic: str) -> str:
    """The liveliness key of one publisher (``role="pub"``) or subscriber (``"sub"``) of ``topic``."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {ROLES}, got {role!r}")
    # Type names are identifiers for the built-in types; a user's type name is encoded so that no
    # '/', '*', '$', '?' or '#' can change the key's shape.
    return _join(namespace, PRESENCE_CHUNK, role, entity, quote(type_name, safe="_.-~"), topic.lstrip("/"))


class EntityToken:
    """The liveliness token of one publisher or subscriber (undeclared by :meth:`close`)."""

    def __init__(self, context: ZenohContext, role: str, topic: Topic) -> None:
        session = context.session
        entity = f"{session.info.zid()}_{next(_entity_ids)}"
        self._token: Any = session.liveliness().declare_token(
            entity_token_key(context.namespace, role, entity, topic.type_name, topic.name))

    def close(self) -> None:
        """Withdraw the token; idempotent, tolerant of a closed session."""
        token, self._token = self._token, None
        if token is None:
            return
        try:
            token.undeclare()
        except zenoh.ZError as exc:
            logger.debug("undeclaring a graph token failed: %s", exc)


def _parse(key: str, namespace: str) -> tuple[str, str, str] | None:
    """``(kind, name, type)`` of a token key: kind "pub" / "sub" / "component"; None if not ours."""
    prefix = _join(namespace, PRESENCE_CHUNK) + "/"
    if not key.startswith(prefix):
        return None
    chunks = key[len(prefix):].split("/")
    if len(chunks) >= 2 and chunks[0] == "components":
        return "component", "/".join(chunks[1:]), ""
    if len(chunks) >= 4 and chunks[0] in ROLES:
        return chunks[0], "/".join(chunks[3:]), unquote(chunks[2])
    return None


def discover_graph(session: zenoh.Session, namespace: str, timeout: float) -> Graph:
    """Every publisher, subscriber and component token under ``namespace`` that answers within ``timeout``."""
    entries: list[tuple[str, str, str]] = []
    components: list[str] = []
    try:
        replies = session.liveliness().get(_join(namespace, PRESENCE_CHUNK, "**"), timeout=timeout)
        for reply in replies:
            if reply.ok is None:
                continue
            parsed = _parse(str(reply.ok.key_expr), namespace)
            if parsed is None:
                continue
            kind, name, type_name = parsed
            if kind == "component":
                components.append(name)
            else:
                entries.append((name, type_name, kind))
    except zenoh.ZError as exc:
        raise TransportError(f"discovering the Zenoh graph failed: {exc}") from exc
    return Graph(topics=merge_topic_counts(entries), components=components)
