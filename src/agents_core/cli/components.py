"""``agentsctl components list | status | transition`` and ``agentsctl call``."""

from __future__ import annotations

import json
from typing import Annotated, Any

import typer

from ..declarations.action_schema import parameters_text
from ..errors import AgentsError, ConfigError, ServiceUnavailableError
from ..topics import validate_topic_name
from ..transport.graph import describe_component
from .connection import discovery_timeout, in_namespace, one_line_errors, open_transport, under_namespace
from .output import print_json, print_table, print_value, say
from .topics import ConnectOpt, DiscoveryOpt, JsonOpt, NamespaceOpt, TransportOpt
from .values import ArgumentError, parse_call_argument, parse_json_argument, summarize

__all__ = ["app", "call"]

app = typer.Typer(help="List components, show their state, drive their lifecycle.", no_args_is_help=True)

#: The lifecycle transitions a component accepts from outside.
TRANSITIONS = ("configure", "activate", "deactivate", "cleanup", "shutdown")
TimeoutOpt = Annotated[float, typer.Option("--timeout", help="seconds to wait for the reply", min=0.01)]


def _component_name(name: str, namespace: str | None = None) -> str:
    return validate_topic_name(in_namespace(namespace, name), "component")


@app.command("list")
@one_line_errors
def list_components(transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
                    timeout: DiscoveryOpt = None, namespace: NamespaceOpt = None) -> None:
    """Every live agents_core component with its lifecycle state and health."""
    rows: list[dict[str, Any]] = []
    with open_transport(transport, connect) as t:
        for name in under_namespace(namespace, list(t.discover(timeout=discovery_timeout(t, timeout)).components)):
            status = _state_of(t, name)
            rows.append({"name": name, "state": status.lifecycle_state if status else "unknown",
                         "health": status.health if status else "unknown"})
    if json_out:
        print_json(rows)
    else:
        print_table("components", ["component", "state", "health"],
                    [(r["name"], r["state"], r["health"]) for r in rows])


def _state_of(transport: Any, name: str) -> Any:
    """The state of one listed component, None when unknown: one odd or broken peer never fails the list."""
    try:
        # A name that is no component name (a hostile token, a wildcard) is not queried: its state
        # key could match other components' keys.
        validate_topic_name(name, "component")
        return transport.get_component_state(name, timeout=2.0)
    except AgentsError:  # an invalid name (TopicNameError) included
        return None


@app.command("status")
@one_line_errors
def status(name: Annotated[str, typer.Argument(help="component name")], transport: TransportOpt = None,
           connect: ConnectOpt = None, json_out: JsonOpt = False, timeout: TimeoutOpt = 5.0,
           namespace: NamespaceOpt = None) -> None:
    """What a component is: type, run type, state, health, inputs, outputs and actions."""
    name = _component_name(name, namespace)
    with open_transport(transport, connect) as t:
        try:
            described = describe_component(t, name, timeout=timeout)
        except ServiceUnavailableError:
            raise ConfigError(f"unreachable component {name!r}: nothing answers {name}/describe on the "
                              f"{t.name} transport") from None
    if json_out:
        print_json(described)
        return
    print_table(f"component {name}", ["field", "value"],
                [(k, described[k]) for k in ("component_type", "run_type", "state", "health")])
    print_table("inputs", ["topic", "type"], _topic_rows(described["inputs"]))
    print_table("outputs", ["topic", "type"], _topic_rows(described["outputs"]))
    actions = described["actions"] if isinstance(described["actions"], dict) else {}
    print_table("actions", ["method", "parameters", "description"],
                [(m, parameters_text(d), _action_text(d))
                 for m, d in sorted(actions.items(), key=lambda item: str(item[0]))])


def _topic_rows(entries: Any) -> list[tuple[Any, Any]]:
    # A describe reply comes from the network: a malformed list shows as empty, not as a KeyError.
    if not isinstance(entries, list):
        return []
    return [(e.get("name", "?"), e.get("msg_type", "?")) for e in entries if isinstance(e, dict)]


def _action_text(description: Any) -> str:
    if isinstance(description, dict):
        inner = description.get("function", description)
        if isinstance(inner, dict):
            return str(inner.get("description", ""))
    return ""


@app.command("transition")
@one_line_errors
def transition(name: Annotated[str, typer.Argument(help="component name")],
               which: Annotated[str, typer.Argument(help=f"one of {', '.join(TRANSITIONS)}")],
               transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
               timeout: TimeoutOpt = 10.0, namespace: NamespaceOpt = None) -> None:
    """Ask a component to run a lifecycle transition (e.g. activate)."""
    name = _component_name(name, namespace)
    if which not in TRANSITIONS:
        raise ConfigError(f"unknown transition {which!r}; use one of {', '.join(TRANSITIONS)}")
    with open_transport(transport, connect) as t:
        try:
            ok = t.request_transition(name, which, timeout=timeout)
        except ServiceUnavailableError:
            raise ConfigError(f"unreachable component {name!r} on the {t.name} transport") from None
        state = t.get_component_state(name, timeout=2.0)
    doc = {"component": name, "transition": which, "ok": ok, "state": state.lifecycle_state if state else None}
    if json_out:
        print_json(doc)
    else:
        say(f"{name}: {which} {'done' if ok else 'refused'} (state: ", doc["state"], ")")
    if not ok:
        raise typer.Exit(1)


@one_line_errors
def call(name: Annotated[str, typer.Argument(help="component name")],
         method: Annotated[str, typer.Argument(help="a method marked @component_action")],
         args: Annotated[list[str] | None,
                         typer.Argument(help="positional arguments (JSON literals or strings)")] = None,
         transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
         kwargs: Annotated[str | None, typer.Option("--kwargs", help="keyword arguments as a JSON object")] = None,
         timeout: TimeoutOpt = 30.0, namespace: NamespaceOpt = None) -> None:
    """Run one of a component's @component_action methods and print the result.

    It is sent to the component's execute_method service as {"method": METHOD, "args": [ARGS...],
    "kwargs": {...}, "timeout": SECONDS}. A robot's component: robot1/arm, or arm --namespace robot1.
    """
    name = _component_name(name, namespace)
    keyword: Any = {}
    if kwargs is not None:
        try:
            keyword = parse_json_argument(kwargs, "--kwargs")
        except json.JSONDecodeError as exc:
            raise ArgumentError("--kwargs", f"is not valid JSON: {exc}") from None
        if not isinstance(keyword, dict):
            raise ArgumentError("--kwargs", "must be a JSON object")
    request = {"method": method, "kwargs": keyword, "timeout": timeout,
               "args": [parse_call_argument(a, f"argument {i} ({_shorten(a)!r})") for i, a in enumerate(args or [], 1)]}
    with open_transport(transport, connect) as t:
        try:
            reply = t.request(f"{name}/execute_method", request, timeout=timeout)
        except ServiceUnavailableError:
            raise ConfigError(f"unreachable component {name!r}: nothing answers {name}/execute_method on the "
                              f"{t.name} transport") from None
    result = summarize(reply.get("result"))
    if json_out:
        print_json({"component": name, "method": method, "result": result})
    else:
        print_value(result)


def _shorten(text: str, limit: int = 20) -> str:
    return text if len(text) <= limit else f"{text[:limit]}..."
