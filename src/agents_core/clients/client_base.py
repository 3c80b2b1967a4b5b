"""What model clients and database clients share: connection settings, error typing, serialization.

Clients never do I/O in their constructor; the component's configure phase calls
``check_connection()`` then ``initialize()``. Every client class registers itself by class name,
so :func:`client_from_spec` rebuilds an equal client from :meth:`BaseClient.serialize` (the way
a component is rebuilt in another process). A spec may hold secrets (an API key): it travels
in memory or over a pipe, never on a command line, and ``repr()`` and logs never show it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar

import httpx

from ..errors import (
    ClientConnectionError,
    ConfigError,
    HTTPStatusError,
    InferenceError,
    InferenceTimeoutError,
    ModelClientError,
)

__all__ = ["BaseClient", "client_from_spec", "client_types", "map_client_exception"]

R = TypeVar("R")

_client_types: dict[str, type[BaseClient]] = {}

_LEVELS = {"debug", "info", "warning", "error", "critical"}


def map_client_exception(context: str, exc: BaseException) -> ModelClientError:
    """The typed error for ``exc`` raised while doing ``context`` ("OllamaClient at h:p: inference").

    Timeouts become :class:`InferenceTimeoutError`, unreachable servers
    :class:`ClientConnectionError`, HTTP error statuses :class:`HTTPStatusError` carrying the
    server's own message, anything else :class:`InferenceError`.
    """
    if isinstance(exc, ModelClientError):
        return exc
    if isinstance(exc, httpx.HTTPStatusError):
        return HTTPStatusError(f"{context}: server answered {exc.response.status_code}: "
                               f"{_response_text(exc.response)}", status=exc.response.status_code)
    if isinstance(exc, httpx.TimeoutException | TimeoutError):
        return InferenceTimeoutError(f"{context} timed out: {exc}")
    if isinstance(exc, httpx.TransportError | ConnectionError | OSError):
        return ClientConnectionError(f"{context}: cannot reach the server: {exc}")
    return InferenceError(f"{context} failed: {type(exc).__name__}: {exc}")


def _response_text(response: httpx.Response) -> str:
    try:
        return response.text[:500]
    except httpx.ResponseNotRead:
        # A streamed response that failed: read its (short) error body now.
        try:
            response.read()
            return response.text[:500]
        except Exception:
            return "(no body)"


def client_types() -> dict[str, type[BaseClient]]:
    """Every client class defined so far, by class name."""
    return dict(_client_types)


def client_from_spec(spec: dict[str, Any]) -> BaseClient:
    """Rebuild a client from :meth:`BaseClient.serialize` output."""
    if not isinstance(spec, dict) or "client_type" not in spec:
        raise ConfigError("a client spec must be a dict with a 'client_type' key")
    name = spec["client_type"]
    cls = _client_types.get(name)
    if cls is None:
        raise ConfigError(f"unknown client type {name!r}; import the module that defines it first "
                          f"(known: {sorted(_client_types)})")
    kwargs = {k: v for k, v in spec.items() if k != "client_type"}
    return cls(**kwargs)


class BaseClient:
    """Connection settings and the error discipline shared by model and database clients."""

    #: Attribute names holding secrets: included in serialize(), hidden from repr() and logs.
    secret_fields: ClassVar[tuple[str, ...]] = ("api_key",)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _client_types[cls.__name__] = cls

    def __init__(
        self,
        host: str | None = None,
        port: int | None = None,
        init_on_activation: bool = True,
        logging_level: str = "info",
    ) -> None:
        if host is not None and (not isinstance(host, str) or not host.strip()):
            raise ConfigError(f"{type(self).__name__}: host must be a non-empty str, got {host!r}")
        if port is not None and (isinstance(port, bool) or not isinstance(port, int) or not 0 < port < 65536):
            raise ConfigError(f"{type(self).__name__}: port must be an int in 1..65535, got {port!r}")
        if str(logging_level).lower() not in _LEVELS:
            raise ConfigError(f"{type(self).__name__}: logging_level must be one of {sorted(_LEVELS)}")
        self.host = host
        self.port = port
        self.init_on_activation = bool(init_on_activation)
        self.logging_level = str(logging_level).lower()
        self.logger = logging.getLogger(f"agents_core.clients.{type(self).__name__}")
        self.logger.setLevel(self.logging_level.upper())

    def _guard(self, what: str, func: Callable[[], R]) -> R:
        """Run ``func`` and turn whatever it raises into a typed :class:`ModelClientError`."""
        try:
            return func()
        except (ModelClientError, ConfigError):
            # A bad argument is the caller's error, not the server's: keep it as it is.
            raise
        except Exception as exc:
            raise map_client_exception(f"{self._label()}: {what}", exc) from exc

    def _label(self) -> str:
        where = f" at {self.host}:{self.port}" if self.host else ""
        return f"{type(self).__name__}{where}"

    def serialize(self) -> dict[str, Any]:
        """Everything needed to rebuild an equal client (secrets included: keep it off argv and logs)."""
        return {
            "client_type": type(self).__name__,
            "host": self.host,
            "port": self.port,
            "init_on_activation": self.init_on_activation,
            "logging_level": self.logging_level,
        }

    def __eq__(self, other: object) -> bool:
        return isinstance(other, BaseClient) and type(self) is type(other) and self.serialize() == other.serialize()

    __hash__ = None  # type: ignore[assignment]  # equality is by value and clients are mutable

    def __repr__(self) -> str:
        spec = self.serialize()
        shown = {k: ("***" if k in self.secret_fields and v else v) for k, v in spec.items()
                 if k not in ("client_type", "model", "db")}
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in shown.items())})"
