"""A Zenoh recipe that sends hostile text to every ``agentsctl`` command (run with ``agentsctl run``).

``agentsctl run tests/cli/hostile_recipe.py --transport zenoh``

It holds one real component and one impersonated by hand, the way an attacker on the network
(or an LLM that answers with markup) would speak to the CLI:

- ``parrot``, a real component: publishes :data:`HOSTILE` on ``llm_answer`` and :data:`ESCAPES`
  (no markup, which used to reach the terminal raw) on ``escapes_only`` at 10 Hz; its
  actions ``say()`` returns it, ``fail()`` raises with it, and both carry it in their descriptions;
- ``imposter``, served with the transport's public services plus raw Zenoh queryables: its
  ``describe`` reply, ``execute_method`` result, state, health and transition reply are hostile;
- liveliness tokens of a topic and a component whose names (and the topic's type) are hostile,
  and of a topic ``oddly_typed`` whose type name is hostile.

Every hostile string holds Rich markup (``[/INST]`` crashes a markup parser, ``[bold red]``
restyles), terminal escapes (OSC 0 window title, CSI 2J clear screen, an OSC 8 link) and a
right-to-left override.
"""

from __future__ import annotations

import sys
from typing import Any
from urllib.parse import quote

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.messages import ComponentStatusMsg
from agents_core.supported_types import ComponentStatus
from agents_core.transport.core import DriverTransport
from agents_core.transport.registry import resolve_transport

#: Terminal escapes (window title, clear screen, a link to any site) and a bidi override.
ESCAPES = "\x1b]0;pwned\x07 \x1b[2J \x1b]8;;http://evil\x1b\\link\x1b]8;;\x1b\\ \u202eevil"
#: What the network sends: markup and the escapes.
HOSTILE = f"LLM says [/INST] [bold red]RED[/bold red] {ESCAPES}"
#: The same inside one Zenoh key chunk (no '/', '*', '$', '?', '#').
HOSTILE_KEY = "x[/INST][bold red]\x1b]0;pwned\x07\x1b[2J\x1b]8;;http:evil\x1b\\link\x1b]8;;\x1b\\\u202eevil"


def _hostile_doc(function: Any) -> Any:
    function.__doc__ = HOSTILE
    return function


class Parrot(Component):
    """Repeats what a hostile LLM answered."""

    def _execution_step(self, **kwargs: Any) -> None:
        self.publishers_dict["llm_answer"].publish(HOSTILE)
        self.publishers_dict["escapes_only"].publish(ESCAPES)

    @component_action
    @_hostile_doc
    def say(self) -> str:
        return HOSTILE

    @component_action
    @_hostile_doc
    def fail(self) -> str:
        raise RuntimeError(HOSTILE)


def _imposter_describe(request: dict[str, Any]) -> dict[str, Any]:
    return {"name": "imposter", "component_type": HOSTILE, "run_type": HOSTILE, "state": HOSTILE,
            "health": HOSTILE, "inputs": [{"name": HOSTILE, "msg_type": HOSTILE}],
            "outputs": [{"name": HOSTILE, "msg_type": HOSTILE}],
            "actions": {HOSTILE: {"type": "function", "function": {"name": HOSTILE, "description": HOSTILE}}}}


def _imposter_execute(request: dict[str, Any]) -> dict[str, Any]:
    return {"result": {"answer": HOSTILE, HOSTILE: [HOSTILE, 1]}}


def impersonate(transport: DriverTransport) -> list[Any]:
    """Declare the imposter and the hostile graph entries; returns what must stay referenced."""
    from agents_zenoh.codecs import MSGPACK, encode_value, pack  # noqa: PLC0415 - the zenoh extra
    from agents_zenoh.keys import PRESENCE_CHUNK, liveliness_key, state_key, transition_key  # noqa: PLC0415

    held: list[Any] = [transport.create_service("imposter/describe", _imposter_describe),
                       transport.create_service("imposter/execute_method", _imposter_execute)]
    context = transport.driver.context  # type: ignore[attr-defined]
    session, ns = context.session, context.namespace
    presence = "/".join(p for p in (ns, PRESENCE_CHUNK) if p)
    status = encode_value(ComponentStatus, ComponentStatusMsg(component="imposter", lifecycle_state=HOSTILE,
                                                              health=HOSTILE, message=HOSTILE))

    def answer_state(query: Any) -> None:
        with query:
            query.reply(str(query.key_expr), status, encoding=MSGPACK)

    def answer_transition(query: Any) -> None:
        with query:
            query.reply(str(query.key_expr), pack({"ok": True}), encoding=MSGPACK)

    held.append(session.declare_queryable(state_key(ns, "imposter"), answer_state))
    held.append(session.declare_queryable(transition_key(ns, "imposter"), answer_transition))
    liveliness = session.liveliness()
    for key in (liveliness_key(ns, "imposter"), liveliness_key(ns, HOSTILE_KEY),
                f"{presence}/pub/evil_1/{quote(HOSTILE, safe='')}/{HOSTILE_KEY}/answer",
                f"{presence}/pub/evil_2/{quote(HOSTILE, safe='')}/oddly_typed"):
        held.append(liveliness.declare_token(key))
    return held


if __name__ == "__main__":
    transport = resolve_transport("zenoh")
    assert isinstance(transport, DriverTransport)
    launcher = Launcher(transport)
    outputs = [Topic("llm_answer", "String"), Topic("escapes_only", "String")]
    launcher.add_pkg(components=[Parrot(inputs=[], outputs=outputs, trigger=10.0, component_name="parrot")])
    held = impersonate(transport)
    print("RECIPE STARTING", flush=True)
    try:
        launcher.bringup()
    finally:
        transport.close()
    sys.exit(0)
