"""``agentsctl components list | status | transition`` and ``agentsctl call``."""

from __future__ import annotations

import json
from typing import Annotated, Any

import typer

from ..errors import ConfigError, ServiceUnavailableError
from ..topics import validate_topic_name
from ..transport.graph import describe_component
from .connection import discovery_timeout, one_line_errors, open_transport
from .output import console, print_json, print_table
from .topics import ConnectOpt, DiscoveryOpt, JsonOpt, TransportOpt
from .values import parse_call_argument, summarize

__all__ = ["app", "call"]

app = typer.Typer(help="List components, show their state, drive their lifecycle.", no_args_is_help=True)

#: The lifecycle transitions a component accepts from outside.
TRANSITIONS = ("configure", "activate", "deactivate", "cleanup", "shutdown")
TimeoutOpt = Annotated[float, typer.Option("--timeout", help="seconds to wait for the reply", min=0.01)]


def _component_name(name: str) -> str:
    return validate_topic_name(name.lstrip("/"), "component")


@app.command("list")
@one_line_errors
def list_components(transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
                    timeout: DiscoveryOpt = None) -> None:
    """Every live agents_core component with its lifecycle state and health."""
    rows: list[dict[str, Any]] = []
    with open_transport(transport, connect) as t:
        for name in t.discover(timeout=discovery_timeout(t, timeout)).components:
            status = t.get_component_state(name, timeout=2.0)
            rows.append({"name": name, "state": status.lifecycle_state if status else "unknown",
                         "health": status.health if status else "unknown"})
    if json_out:
        print_json(rows)
    else:
        print_table("components", ["component", "state", "health"],
                    [(r["name"], r["state"], r["health"]) for r in rows])


@app.command("status")
@one_line_errors
def status(name: Annotated[str, typer.Argument(help="component name")], transport: TransportOpt = None,
           connect: ConnectOpt = None, json_out: JsonOpt = False, timeout: TimeoutOpt = 5.0) -> None:
    """What a component is: type, run type, state, health, inputs, outputs and actions."""
    name = _component_name(name)
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
    print_table("inputs", ["topic", "type"], [(i["name"], i["msg_type"]) for i in described["inputs"]])
    print_table("outputs", ["topic", "type"], [(o["name"], o["msg_type"]) for o in described["outputs"]])
    print_table("actions", ["method", "description"],
                [(m, _action_text(d)) for m, d in sorted(described["actions"].items())])


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
               timeout: TimeoutOpt = 10.0) -> None:
    """Ask a component to run a lifecycle transition (e.g. ``activate``)."""
    name = _component_name(name)
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
        console.print(f"{name}: {which} {'done' if ok else 'refused'} (state: {doc['state']})")
    if not ok:
        raise typer.Exit(1)


@one_line_errors
def call(name: Annotated[str, typer.Argument(help="component name")],
         method: Annotated[str, typer.Argument(help="a method marked @component_action")],
         args: Annotated[list[str] | None,
                         typer.Argument(help="positional arguments (JSON literals or strings)")] = None,
         transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
         kwargs: Annotated[str | None, typer.Option("--kwargs", help="keyword arguments as a JSON object")] = None,
         timeout: TimeoutOpt = 30.0) -> None:
    """Run one of a component's actions through its ``execute_method`` service and print the result."""
    name = _component_name(name)
    keyword: Any = {}
    if kwargs is not None:
        try:
            keyword = json.loads(kwargs)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"--kwargs is not valid JSON: {exc}") from None
        if not isinstance(keyword, dict):
            raise ConfigError("--kwargs must be a JSON object")
    request = {"method": method, "args": [parse_call_argument(a) for a in args or []], "kwargs": keyword,
               "timeout": timeout}
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
        console.print(result)
