"""Key expressions: where topics, services and component presence live in the Zenoh key space.

=====================================  ==================================================
``<ns>/<topic>``                       a topic's samples (a leading ``/`` of the name is dropped)
``<ns>/<service>``                     a service's queryable (e.g. ``<component>/set_param``)
``<ns>/@agents/components/<name>``     a component's liveliness token
``<ns>/@agents/state/<name>``          queryable: the component's lifecycle state and health
``<ns>/@agents/transition/<name>``     queryable: ask the component to run a lifecycle transition
``<ns>/<action>/@action/...``          an action's stream, goal, cancel and result queryables and its
                                       feedback / status / result samples (:mod:`agents_zenoh.goals`)
=====================================  ==================================================

``<ns>/`` is left out when the namespace is empty. Topic, service and component names are
already restricted by the core (:func:`agents_core.topics.validate_topic_name`) to chunks of
letters, digits and ``_``, so they never hold Zenoh wildcards (``*``, ``$*``, ``**``) or the
``@`` that starts the presence keys: a ``<ns>/**`` subscriber sees every topic and none of the
presence keys (a ``**`` never matches a chunk that starts with ``@``).
"""

from __future__ import annotations

from agents_core.topics import validate_topic_name

__all__ = ["ACTION_CHUNK", "PRESENCE_CHUNK", "goal_key", "liveliness_key", "state_key", "topic_key", "transition_key"]

#: The verbatim chunk under which component presence lives.
PRESENCE_CHUNK = "@agents"
#: The verbatim chunk under an action name where its goal keys live (out of ``<ns>/**`` topic subscriptions).
ACTION_CHUNK = "@action"


def _join(namespace: str, *parts: str) -> str:
    return "/".join(p for p in (namespace, *parts) if p)


def topic_key(namespace: str, name: str, what: str = "topic") -> str:
    """The key expression of a topic or service ``name`` under ``namespace``."""
    validate_topic_name(name, what)
    return _join(namespace, name.lstrip("/"))


def goal_key(namespace: str, action: str, *parts: str) -> str:
    """The key ``<ns>/<action>/@action/<parts...>`` of one goal queryable or sample stream."""
    return "/".join((topic_key(namespace, action, "action"), ACTION_CHUNK, *parts))


def liveliness_key(namespace: str, component: str) -> str:
    """Where the component's liveliness token is declared."""
    return _join(namespace, PRESENCE_CHUNK, "components", component.lstrip("/"))


def state_key(namespace: str, component: str) -> str:
    """The queryable that answers the component's lifecycle state and health."""
    return _join(namespace, PRESENCE_CHUNK, "state", component.lstrip("/"))


def transition_key(namespace: str, component: str) -> str:
    """The queryable that runs lifecycle transitions of the component."""
    return _join(namespace, PRESENCE_CHUNK, "transition", component.lstrip("/"))
