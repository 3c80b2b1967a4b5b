"""What the HTTP clients share: one connection pool per client, bounded requests, typed error statuses.

:class:`HTTPClientBase` is the base of :class:`~agents_core.clients.generic.GenericHTTPClient`,
:class:`~agents_core.clients.ollama.OllamaClient`, :class:`~agents_core.clients.chroma.ChromaClient`
and :class:`~agents_core.clients.roboml_http.RoboMLHTTPClient`. It holds the client's pool (a
:class:`~agents_core.clients.deadline.BoundedHTTP`, opened on first use since constructors do no
I/O, dropped by :meth:`HTTPClientBase.close`), sends every request under a whole-call deadline,
and turns an error status into :class:`~agents_core.errors.HTTPStatusError` carrying the server's
own message (:func:`server_error_message`). The clients' ``_guard`` masks their secrets in all of it.

The two stream formats model servers use are read here too: server-sent events through
`httpx-sse <https://github.com/florimondmanca/httpx-sse>`_ (:func:`sse_data`, OpenAI-compatible
servers) and newline-delimited JSON (:func:`iter_ndjson`, Ollama).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterable, Iterator
from typing import Any, ClassVar

import httpx
from httpx_sse import EventSource, SSEError

from ..errors import ConfigError, HTTPStatusError, ProtocolError
from .client_base import BaseClient
from .deadline import BoundedHTTP, CallWatch
from .reply_limit import DEFAULT_MAX_REPLY_BYTES

__all__ = [
    "HTTPClientBase",
    "bearer",
    "check_api_key",
    "check_response",
    "iter_ndjson",
    "iter_sse_data",
    "json_object",
    "response_json",
    "server_error_message",
    "sse_data",
]

# Opening and dropping a pool are rare and quick: one lock for every client is enough.
_POOL_LOCK = threading.Lock()


# -- helpers ------------------------------------------------------------------------------------------


def bearer(token: str | None) -> dict[str, str]:
    """The ``Authorization: Bearer <token>`` header, or no header when there is no token."""
    return {"Authorization": f"Bearer {token}"} if token else {}


def check_api_key(owner: str, api_key: Any) -> str | None:
    """``api_key`` when it is a non-empty str or None, else :class:`~agents_core.errors.ConfigError`."""
    if api_key is not None and (not isinstance(api_key, str) or not api_key):
        raise ConfigError(f"{owner}: api_key must be a non-empty str or None")
    return api_key


def server_error_message(response: httpx.Response) -> str:
    """The server's own error text from an error response (its body is read here if it was streamed).

    Understands OpenAI's ``{"error": {"message": ...}}``, Chroma's ``{"error": kind, "message": ...}``
    (given as ``"kind: message"``), Ollama's ``{"error": "..."}`` and FastAPI's (RoboML's)
    ``{"detail": ...}`` (pydantic's error list as JSON); anything else is returned as (shortened) text.
    """
    try:
        text = response.text
    except httpx.ResponseNotRead:
        try:
            response.read()
            text = response.text
        except Exception:  # the connection failed while reading the error body
            return "(no body)"
    try:
        body = json.loads(text)
    except ValueError:
        return text[:500] or response.reason_phrase
    if isinstance(body, dict):
        error = body.get("error")
        if isinstance(error, dict) and isinstance(error.get("message"), str):
            return str(error["message"])
        if "message" in body:
            return f"{error if error is not None else 'error'}: {body['message']}"
        if isinstance(error, str):
            return error
        detail = body.get("detail")
        if isinstance(detail, str):
            return detail
        if detail is not None:
            return json.dumps(detail)[:500]
    return text[:500]


def check_response(response: httpx.Response, context: str,
                   template: str = "server answered {status} {reason}") -> None:
    """Raise :class:`~agents_core.errors.HTTPStatusError` (with the server's message) unless 2xx.

    :param context: names the client and operation ("GenericHTTPClient at h:p: chat").
    :param template: how the status reads after it; ``{status}`` is the code, ``{reason}`` its phrase.
    """
    if response.is_success:
        return
    status = template.format(status=response.status_code, reason=response.reason_phrase)
    raise HTTPStatusError(f"{context}: {status}: {server_error_message(response)}", status=response.status_code)


def response_json(response: httpx.Response, context: str) -> Any:
    """The decoded JSON body, or :class:`~agents_core.errors.ProtocolError` when it is not JSON."""
    try:
        return response.json()
    except ValueError as exc:
        raise ProtocolError(f"{context}: the answer is not JSON: {response.text[:200]!r}") from exc


# -- streams ------------------------------------------------------------------------------------------


def sse_data(response: httpx.Response, context: str, watch: CallWatch | None = None) -> Iterator[str]:
    """The ``data`` of each server-sent event of a streamed ``text/event-stream`` response.

    httpx-sse parses the stream. Comments (keep-alive pings) and events without data yield
    nothing, so they never count as chunks; ``watch``, when given, is checked at every event (a
    blocked read is cut by its watchdog). A response of another content type raises
    :class:`~agents_core.errors.ProtocolError`.
    """
    try:
        for event in EventSource(response).iter_sse():
            if watch is not None:
                watch.check()
            if event.data:
                yield event.data
    except SSEError as exc:  # httpx-sse's own errors are transport errors: this one is the protocol's
        raise ProtocolError(f"{context}: not an event stream: {exc}") from exc


def iter_sse_data(lines: Iterable[str]) -> Iterator[str]:
    """The ``data`` of each server-sent event in ``lines`` (lines of a ``text/event-stream`` body).

    Lines of one event's ``data`` are joined with newlines; comments and the ``event`` / ``id`` /
    ``retry`` fields are skipped (the OpenAI protocol carries everything in ``data``).
    """
    body = (f"{line}\n".encode() for line in lines)
    response = httpx.Response(200, headers={"Content-Type": "text/event-stream"}, content=body)
    return sse_data(response, "server-sent events")


def json_object(text: str, context: str, piece: str) -> dict[str, Any]:
    """``text`` decoded as a JSON object, else :class:`~agents_core.errors.ProtocolError` naming the
    ``piece`` of the stream it was ("an event", "a streamed line")."""
    try:
        obj = json.loads(text)
    except ValueError as exc:
        raise ProtocolError(f"{context}: {piece} is not JSON: {text[:200]!r}") from exc
    if not isinstance(obj, dict):
        raise ProtocolError(f"{context}: {piece} is not a JSON object: {text[:200]!r}")
    return obj


def iter_ndjson(lines: Iterable[str], context: str, watch: CallWatch | None = None) -> Iterator[dict[str, Any]]:
    """The JSON objects of newline-delimited JSON ``lines`` (blank lines skipped).

    A line that is not a JSON object raises :class:`~agents_core.errors.ProtocolError`; ``watch``,
    when given, is checked at every line, blank ones included.
    """
    for line in lines:
        if watch is not None:
            watch.check()
        if line.strip():
            yield json_object(line, context, "a streamed line")


# -- the base class -----------------------------------------------------------------------------------


class HTTPClientBase(BaseClient):
    """A client speaking HTTP to one server through a pooled, deadline-bounded connection.

    Subclasses combine it with :class:`~agents_core.clients.model_base.ModelClient` or
    :class:`~agents_core.clients.db_base.DBClient` (``class C(HTTPClientBase, ModelClient)``) and
    say where the server is (``use_https``, ``base_path``), how to authenticate (:meth:`_headers`),
    which attribute bounds a request (``timeout_setting``) and how an error status reads.
    """

    #: The attribute holding the seconds a request may take, connect to last byte; named in timeout errors.
    timeout_setting: ClassVar[str] = "inference_timeout"
    #: How an error status reads in an HTTPStatusError, after the operation: ``{status}`` is the
    #: code, ``{reason}`` its phrase.
    status_template: ClassVar[str] = "server answered {status} {reason}"
    #: Talk HTTPS instead of HTTP (set per instance by clients that take a ``use_https`` argument).
    use_https: bool = False
    #: The path every route of the server's API lives under.
    base_path: str = ""
    #: Constructor arguments :meth:`serialize` adds to the base spec, each from the attribute of that name.
    spec_fields: ClassVar[tuple[str, ...]] = ()
    # The connection pool: None until the first request, and again after close().
    _http: BoundedHTTP | None = None

    @property
    def base_url(self) -> str:
        """``http(s)://host:port`` and the base path (an IPv6 host in brackets)."""
        host = self.host or ""
        if ":" in host and not host.startswith("["):
            host = f"[{host}]"
        return f"{'https' if self.use_https else 'http'}://{host}:{self.port}{self.base_path}"

    @property
    def _client(self) -> BoundedHTTP | None:
        # The name GenericHTTPClient and OllamaClient gave their pool, kept for code that looks at it.
        return self._http

    def _headers(self) -> dict[str, str]:
        """Headers sent with every request (authentication); none by default."""
        return {}

    def _context(self, what: str) -> str:
        """``what`` prefixed by the client's label, as errors name an operation."""
        return f"{self._label()}: {what}"

    def _reply_limit(self) -> int:
        """The most bytes a reply may hold after decompression (a model client's ``max_reply_bytes``)."""
        return int(getattr(self, "max_reply_bytes", DEFAULT_MAX_REPLY_BYTES))

    def _pool(self) -> BoundedHTTP:
        """The connection pool, opened on first use (and again after :meth:`close`)."""
        with _POOL_LOCK:
            if self._http is None or self._http.is_closed:
                self._http = BoundedHTTP(self.base_url, headers=self._headers(), max_reply_bytes=self._reply_limit())
            return self._http

    def _request(self, method: str, path: str, what: str, *, seconds: float | None = None,
                 setting: str | None = None, fresh: bool = False, check: bool = True,
                 **kwargs: Any) -> httpx.Response:
        """One request, its whole answer read within ``seconds`` (default: the ``timeout_setting``).

        :param what: the operation, named in errors.
        :param setting: the setting that gave ``seconds``, named in a timeout error.
        :param fresh: use a connection of its own, closed afterwards (a connection check must leave
            nothing open behind it).
        :param check: raise :class:`~agents_core.errors.HTTPStatusError` unless the status is 2xx.
        :param kwargs: what ``httpx.Client.build_request`` takes (``json``, ``params``, ``files``...).
        """
        budget = float(getattr(self, self.timeout_setting) if seconds is None else seconds)
        http = (BoundedHTTP(self.base_url, headers=self._headers(), max_reply_bytes=self._reply_limit()) if fresh
                else self._pool())
        try:
            response = http.request(method, path, seconds=budget, label=self._context(what),
                                    what=setting or self.timeout_setting, **kwargs)
        finally:
            if fresh:
                http.close()
        if check:
            self._check_response(response, what)
        return response

    def _request_json(self, method: str, path: str, what: str, **kwargs: Any) -> Any:
        """:meth:`_request` (same arguments), its answer decoded as JSON."""
        return self._json(self._request(method, path, what, **kwargs), what)

    def _check_response(self, response: httpx.Response, what: str) -> None:
        """Raise the typed :class:`~agents_core.errors.HTTPStatusError` unless the status is 2xx."""
        check_response(response, self._context(what), self.status_template)

    def _json(self, response: httpx.Response, what: str) -> Any:
        """The decoded JSON body, or :class:`~agents_core.errors.ProtocolError`."""
        return response_json(response, self._context(what))

    def _open_stream(self, method: str, path: str, what: str, watch: CallWatch, **kwargs: Any) -> httpx.Response:
        """Send a request whose answer is read as a stream under ``watch``; its status is checked.

        The caller reads the body, then closes the response and the watch. On failure here both
        are closed, and a limit of ``watch`` that passed is what is raised.
        """
        try:
            response = self._pool().open(method, path, watch, **kwargs)
        except BaseException:
            watch.close()
            raise
        try:
            self._check_response(response, what)
        except Exception as exc:
            watch.close()
            response.close()
            if watch.fired is not None:
                raise watch.error() from exc
            raise
        return response

    def serialize(self) -> dict[str, Any]:
        """The base spec plus the ``spec_fields`` (secrets included: keep it off argv and logs)."""
        spec: dict[str, Any] = super().serialize()
        spec.update((name, getattr(self, name)) for name in self.spec_fields)
        return spec

    def close(self) -> None:
        """Close the connection pool now (without telling the server anything); reopened on next use."""
        with _POOL_LOCK:
            http, self._http = self._http, None
        if http is not None:
            http.close()
