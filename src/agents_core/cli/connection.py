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
from ..transport.registry import TRANSPORT_ENV_VAR, resolve_transport
from .output import safe_text
from .values import ArgumentError

__all__ = ["DEFAULT_TRANSPORT", "USAGE_ERROR", "discovery_timeout", "fail", "one_line_errors", "open_transport",
           "transport_default"]

F = TypeVar("F", bound=Callable[..., Any])

#: The exit status of a usage error (Typer's, and ours for argument values that cannot be used).
USAGE_ERROR = 2

#: What the inspection commands use when neither --transport nor AGENTS_TRANSPORT says.
DEFAULT_TRANSPORT = "zenoh"


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


def discovery_timeout(transport: Transport, given: float | None) -> float:
    """``given``, else the transport's default discovery wait (``capabilities.discovery_settle_s``)."""
    return given if given is not None else transport.capabilities.discovery_settle_s


def zenoh_options(connect: list[str] | None) -> dict[str, Any]:
    """Options for an observer's Zenoh session: a client of ``connect`` if given, else the loopback default."""
    options: dict[str, Any] = {"zenoh_options": {"scouting/delay": 100}}
    if connect:
        options.update(mode="client", connect=list(connect), listen=[])
    return options


@contextlib.contextmanager
def open_transport(name: str | None, connect: list[str] | None = None) -> Iterator[Transport]:
    """Open transport ``name`` (None: :func:`transport_default`) as an observer of other processes' graph."""
    name = (name or transport_default()).strip().lower()
    if name == "memory":
        raise ConfigError("the memory transport lives inside one process, so there is nothing to inspect from "
                          "outside; use --transport zenoh or --transport ros2")
    if connect and name != "zenoh":
        raise ConfigError(f"--connect is a Zenoh option; the {name} transport does not take it")
    transport = resolve_transport(name, **(zenoh_options(connect) if name == "zenoh" else {}))
    try:
        yield transport
    finally:
        transport.close()
