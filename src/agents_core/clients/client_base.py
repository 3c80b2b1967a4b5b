"""What model clients and database clients share: connection settings, error typing, serialization.

Clients never do I/O in their constructor; the component's configure phase calls
``check_connection()`` then ``initialize()``. Every client class registers itself by class name,
so :func:`client_from_spec` rebuilds an equal client from :meth:`BaseClient.serialize` (the way
a component is rebuilt in another process). A spec may hold secrets (an API key): it travels
in memory or over a pipe, never on a command line, and ``repr()`` and logs never show it.

Servers echo what they were sent: an error body may hold the API key, or the whole
``Authorization: Bearer <key>`` header. Every error a client raises goes through
:meth:`BaseClient._guard` (or a :class:`~agents_core.clients.payloads.ChunkStream`), which
replaces each configured secret (every attribute named in ``secret_fields``, plus any bearer
token, and every HTTP Basic credential) with ``***`` in the message and in the exceptions chained
to it (:func:`scrub_exception`); a secret echoed base64-encoded (``Basic base64(user:key)``, or the
key inside any base64 text, standard or URL-safe alphabet) is masked too;
the clients' loggers scrub their records the same way. What reaches ``<name>/status``, the state
queries and the logs is therefore free of them.
"""

from __future__ import annotations

import base64
import binascii
import functools
import json
import logging
import re
import weakref
from collections.abc import Callable, Iterable
from typing import Any, ClassVar, TypeVar
from urllib.parse import quote, quote_plus

import httpx

from ..errors import (
    ClientConnectionError,
    ConfigError,
    HTTPStatusError,
    InferenceError,
    InferenceTimeoutError,
    ModelClientError,
)
from ..support.registry import Registry

__all__ = [
    "SECRET_MASK",
    "BaseClient",
    "client_from_spec",
    "client_types",
    "map_client_exception",
    "scrub_exception",
    "scrub_text",
]

R = TypeVar("R")
E = TypeVar("E", bound=BaseException)

_client_types: Registry[type[BaseClient]] = Registry("client type", hint="import the module that defines it first")

_LEVELS = {"debug", "info", "warning", "error", "critical"}

#: What a secret is replaced with.
SECRET_MASK = "***"

# Any bearer token, known or not (a proxy may add its own): "Bearer abc" -> "Bearer ***".
_BEARER = re.compile(r"(?i)\b(bearer\s+)(?!\*\*\*)[^\s\"',;}\]]+")


# Any HTTP Basic credential: "Basic <base64 of user:password>" -> "Basic ***" (checked by decoding).
_BASIC = re.compile(r"(?i)\b(basic\s+)([A-Za-z0-9+/]{4,}={0,2})")
# A run of base64 text (either alphabet), in which an encoded secret may hide.
_BASE64_RUN = re.compile(r"[A-Za-z0-9+/_-]{8,}={0,2}")
#: Encoded secrets shorter than this are not looked for in base64 text (too likely by chance).
_MIN_BASE64_CORE = 8


def _forms(secret: str) -> set[str]:
    # The secret as a server may echo it: raw, JSON-escaped, URL-encoded.
    return {secret, json.dumps(secret)[1:-1], quote(secret, safe=""), quote_plus(secret)}


@functools.lru_cache(maxsize=64)
def _base64_cores(secret: str) -> tuple[str, ...]:
    """What any base64 text holding ``secret`` contains, whatever comes before and after it.

    Base64 encodes 3 bytes as 4 characters, so the secret's characters depend on its offset modulo
    3 in the encoded bytes (``user:`` before it in HTTP Basic): one core per offset, without the
    groups it shares with its neighbours; in the standard and the URL-safe alphabet.
    """
    raw = secret.encode()
    cores: set[str] = set()
    for offset in range(3):
        encoded = base64.b64encode(b"\0" * offset + raw).decode()
        start = 4 if offset else 0  # the first group mixes the bytes before the secret with its own
        end = len(encoded) if (offset + len(raw)) % 3 == 0 else len(encoded) - 4  # so does the last one
        core = encoded[start:end]
        if len(core) >= _MIN_BASE64_CORE:
            cores.update((core, core.replace("+", "-").replace("/", "_")))
    return tuple(cores)


def _basic_credential(token: str) -> bool:
    try:
        return b":" in base64.b64decode(token, validate=True)
    except (binascii.Error, ValueError):
        return False


def scrub_text(text: str, secrets: Iterable[str]) -> str:
    """``text`` with every secret (also base64-encoded), bearer token and Basic credential replaced by ``***``."""
    secrets = [secret for secret in secrets if secret]
    forms = {form for secret in secrets for form in _forms(secret) if form}
    # Longest first, so a secret that contains another is masked whole.
    for form in sorted(forms, key=len, reverse=True):
        if form in text:
            text = text.replace(form, SECRET_MASK)
    cores = [core for secret in secrets for core in _base64_cores(secret)]
    if any(core in text for core in cores):  # a plain search first: most texts hold none
        # The whole base64 run goes, not just the core: its edges would show bytes of the secret.
        text = _BASE64_RUN.sub(lambda m: SECRET_MASK if any(c in m.group(0) for c in cores) else m.group(0), text)
    lowered = text.lower()  # the case-insensitive scans are skipped for texts without their word
    if "basic" in lowered:
        text = _BASIC.sub(lambda m: m.group(1) + SECRET_MASK if _basic_credential(m.group(2)) else m.group(0), text)
    return _BEARER.sub(lambda m: m.group(1) + SECRET_MASK, text) if "bearer" in lowered else text


def _shows(exc: BaseException, secrets: Iterable[str]) -> bool:
    try:
        text = str(exc)
    except Exception:
        return False
    return scrub_text(text, secrets) != text


def scrub_exception(exc: E, secrets: Iterable[str]) -> E:
    """Scrub the secrets from ``exc`` and the exceptions chained to it, in place; returns ``exc``.

    The str arguments of each exception in the ``__cause__`` / ``__context__`` chain are
    rewritten. An exception whose text still shows a secret afterwards (one that builds its
    message from other attributes) is cut from the chain, so no traceback prints it.
    """
    secrets = tuple(s for s in secrets if s)
    seen: set[int] = set()
    current: BaseException | None = exc
    parent: BaseException | None = None
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if any(isinstance(a, str) for a in current.args):
            current.args = tuple(scrub_text(a, secrets) if isinstance(a, str) else a for a in current.args)
        if parent is not None and _shows(current, secrets):
            parent.__cause__ = None
            parent.__context__ = None
            parent.__suppress_context__ = True
            break
        parent, current = current, current.__cause__ or current.__context__
    return exc


class _ScrubFilter(logging.Filter):
    """Masks the secrets of every live client in the records of the clients' loggers."""

    def __init__(self) -> None:
        super().__init__()
        self._clients: weakref.WeakValueDictionary[int, BaseClient] = weakref.WeakValueDictionary()

    def add(self, client: BaseClient) -> None:
        self._clients[id(client)] = client

    def filter(self, record: logging.LogRecord) -> bool:
        secrets: set[str] = set()
        for client in list(self._clients.values()):
            secrets.update(client._secrets())
        try:
            message = record.getMessage()
        except Exception:  # a malformed record is the logging module's to report
            return True
        clean = scrub_text(message, secrets)
        if clean != message:
            record.msg, record.args = clean, None
        if record.exc_info and record.exc_info[1] is not None:
            scrub_exception(record.exc_info[1], secrets)
            record.exc_text = None
        return True


_SCRUB_FILTER = _ScrubFilter()


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
    return _client_types.snapshot()


def client_from_spec(spec: dict[str, Any]) -> BaseClient:
    """Rebuild a client from :meth:`BaseClient.serialize` output."""
    if not isinstance(spec, dict) or "client_type" not in spec:
        raise ConfigError("a client spec must be a dict with a 'client_type' key")
    name = spec["client_type"]
    cls = _client_types.find(name)
    if cls is None:
        # Clients register when their module is imported, and the package imports them lazily:
        # load every built-in client before deciding the name is unknown.
        from . import client_types as builtin_client_types  # noqa: PLC0415

        cls = builtin_client_types().get(name)
    if cls is None:
        raise _client_types.missing(name)
    kwargs = {k: v for k, v in spec.items() if k != "client_type"}
    return cls(**kwargs)


class BaseClient:
    """Connection settings and the error discipline shared by model and database clients."""

    #: Attribute names holding secrets: included in serialize(), hidden from repr() and logs.
    secret_fields: ClassVar[tuple[str, ...]] = ("api_key",)

    #: The hooks a subclass has not implemented yet (methods still marked ``@abstractmethod``).
    _missing_hooks: ClassVar[tuple[str, ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._missing_hooks = tuple(sorted(name for name in dir(cls)
                                          if getattr(getattr(cls, name, None), "__isabstractmethod__", False)))
        _client_types.register(cls.__name__, cls, replace=True)  # the last definition wins

    def __init__(
        self,
        host: str | None = None,
        port: int | None = None,
        init_on_activation: bool = True,
        logging_level: str = "info",
    ) -> None:
        missing = type(self)._missing_hooks
        if missing:
            # At construction, as upstream's abstract methods promise: not at configure, or never.
            base = next((b.__name__ for b in type(self).__mro__[1:] if b.__name__ in ("ModelClient", "DBClient")),
                        "BaseClient")
            raise TypeError(f"{type(self).__name__} must implement {', '.join(missing)} (the hooks every "
                            f"{base} subclass implements); it cannot be constructed without them")
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
        _SCRUB_FILTER.add(self)
        if _SCRUB_FILTER not in self.logger.filters:
            self.logger.addFilter(_SCRUB_FILTER)

    def _secrets(self) -> tuple[str, ...]:
        """The secret values this client sends (each set attribute named in ``secret_fields``)."""
        values = (getattr(self, name, None) for name in self.secret_fields)
        return tuple(v for v in values if isinstance(v, str) and v)

    def _scrub(self, exc: E) -> E:
        """``exc`` (and its chain) with this client's secrets masked."""
        return scrub_exception(exc, self._secrets())

    def _guard(self, what: str, func: Callable[[], R]) -> R:
        """Run ``func`` and turn whatever it raises into a typed :class:`ModelClientError`, secrets masked."""
        try:
            return func()
        except Exception as exc:
            error = self._typed_error(what, exc)
        # Raised outside the handler, so the original exception is not attached again as context.
        raise error

    def _typed_error(self, what: str, exc: Exception) -> Exception:
        if isinstance(exc, ModelClientError | ConfigError):
            # Already typed; a bad argument is the caller's error, not the server's: kept as it is.
            return self._scrub(exc)
        error = map_client_exception(f"{self._label()}: {what}", exc)
        error.__cause__ = exc
        error.__suppress_context__ = True
        return self._scrub(error)

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
