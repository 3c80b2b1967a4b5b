"""How the CLI opens a transport to look at a running graph, and the one-line error exit."""

from __future__ import annotations

import contextlib
import functools
import os
import sys
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import typer

from ..errors import AgentsError, ConfigError
from ..transport.contract import Transport
from ..transport.registry import (
    DEFAULT_CROSS_PROCESS,
    TRANSPORT_ENV_VAR,
    describe_transport_kind,
    known_transports,
    resolve_transport,
)
from .output import safe_text
from .values import ArgumentError

__all__ = ["DEFAULT_TRANSPORT", "USAGE_ERROR", "attachable_transports", "discovery_timeout", "fail", "in_namespace",
           "observer_options", "one_line_errors", "open_transport", "transport_default", "under_namespace"]

F = TypeVar("F", bound=Callable[..., Any])

#: The exit status of a usage error (Typer's, and ours for argument values that cannot be used).
USAGE_ERROR = 2

#: What the inspection commands use when neither --transport nor AGENTS_TRANSPORT says (the registry's choice).
DEFAULT_TRANSPORT = DEFAULT_CROSS_PROCESS


def transport_default() -> str:
    """``AGENTS_TRANSPORT`` if set, else :data:`DEFAULT_TRANSPORT`."""
    return os.environ.get(TRANSPORT_ENV_VAR, "").strip() or DEFAULT_TRANSPORT


def fail(message: str, code: int = 1) -> typer.Exit:
    """Print ``error: <message>`` (one line, control characters escaped) on stderr; the caller raises what this returns.

    Messages often quote what a remote sent (its error, a type name), so they go through
    :func:`~agents_core.cli.output.safe_text`.
    """
    print(f"error: {safe_text(' '.join(str(message).split()), one_line=True)}", file=sys.stderr, flush=True)
    return typer.Exit(code)


def one_line_errors(func: F) -> F:
    """Turn the framework's errors (and bad input) into one line on stderr: exit status 2 for an argument, else 1.

    OverflowError and RecursionError are caught too: a value built from the user's or a remote's
    input (a huge number, a deeply nested document) must end in a message, never a traceback.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except ArgumentError as exc:
            raise fail(str(exc), USAGE_ERROR) from None
        except (AgentsError, ValueError, TypeError, LookupError, OverflowError) as exc:
            raise fail(str(exc) or type(exc).__name__) from None
        except RecursionError:
            raise fail("a value is nested too deeply to handle") from None

    return wrapper  # type: ignore[return-value]


def in_namespace(namespace: str | None, name: str) -> str:
    """``name`` as given on the command line, resolved in ``--namespace`` as ROS 2 resolves it (``arm`` ->
    ``robot1/arm``; ``/map`` -> ``map``, shared); without one, the name with any leading ``/`` dropped."""
    from ..transport.namespace import resolve_name, validate_namespace  # noqa: PLC0415

    return resolve_name(validate_namespace(namespace, "--namespace"), name) if namespace else name.lstrip("/")


def under_namespace(namespace: str | None, names: list[str]) -> list[str]:
    """The ``names`` under ``--namespace`` (all of them without one)."""
    from ..transport.namespace import validate_namespace  # noqa: PLC0415

    prefix = validate_namespace(namespace, "--namespace")
    return [n for n in names if not prefix or n.startswith(prefix + "/")]


def discovery_timeout(transport: Transport, given: float | None) -> float:
    """``given``, else the transport's default discovery wait (``capabilities.discovery_settle_s``)."""
    return given if given is not None else transport.capabilities.discovery_settle_s


def attachable_transports() -> list[str]:
    """The transports whose descriptors say another process can reach a running recipe (``attach``)."""
    names = []
    for name in known_transports():
        try:
            if describe_transport_kind(name).attachable:
                names.append(name)
        except AgentsError:
            continue
    return names


def endpoint_option_error(option: str, name: str) -> ConfigError:
    """``--connect`` (or another endpoint option) given for a transport that takes no endpoints."""
    takers = [d.shown_name for d in map(describe_transport_kind, attachable_transports()) if d.endpoints]
    return ConfigError(f"{option} is a {' / '.join(takers) or 'endpoint'} option; the {name} transport does not "
                       "take it")


def observer_options(name: str, connect: list[str] | None, mode: str | None = None, *,
                     what: str = "inspect") -> dict[str, Any]:
    """Options for transport ``name`` opened by an observer of other processes' graph (its descriptor's).

    ConfigError for a transport nothing outside its process can reach, or ``connect`` given to one
    that takes no endpoints.
    """
    descriptor = describe_transport_kind(name)
    if not descriptor.attachable:
        others = " or ".join(f"--transport {n}" for n in attachable_transports())
        raise ConfigError(f"the {descriptor.name} transport lives inside one process, so there is nothing to "
                          f"{what} from outside; use {others or 'a cross-process transport'}")
    if connect and not descriptor.endpoints:
        raise endpoint_option_error("--connect", descriptor.name)
    return descriptor.reach(connect, mode)


@contextlib.contextmanager
def open_transport(name: str | None, connect: list[str] | None = None) -> Iterator[Transport]:
    """Open transport ``name`` (None: :func:`transport_default`) as an observer of other processes' graph."""
    name = (name or transport_default()).strip().lower()
    transport = resolve_transport(name, **observer_options(name, connect))
    try:
        yield transport
    finally:
        transport.close()
