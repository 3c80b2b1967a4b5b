"""The UI's HTTP and WebSocket API (Starlette), front-end agnostic, with the page on top.

==========================================================  =========================================
``GET  /api/health``                                          liveness, transport, client counters
``GET  /api/interfaces``                                      components (type, lifecycle, health,
                                                              inputs, outputs, actions) and the
                                                              inputs / outputs the UI shows
``POST /api/inputs/<topic>``                                  publish (see :mod:`.inputs`)
``WS   /api/outputs[?topics=a,b][&frames=binary][&full=1]`` frames (see :mod:`.frames`, :mod:`.binary_frames`)
``POST /api/components/<name>/transition``                    ``{"transition": "deactivate"}``
``POST /api/components/<name>/actions/<action>``              ``{"args": [...], "kwargs": {...}}``,
                                                              ``@component_action`` methods only
``POST /api/login``                                           ``{"token": ...}`` opens a session (cookie)
``POST /api/logout``                                          closes it
``GET  /``                                                    the page (``static/``)
==========================================================  =========================================

Errors are JSON ``{"error": "..."}`` with a 4xx/5xx status. Requests from another origin (a web
page elsewhere that a browser would happily send to 127.0.0.1) are refused, and so are Host
names other than loopback ones while bound to loopback (DNS rebinding). Request bodies are read
by :class:`~.body_guard.BodyGuard` (bounded in size, time and number), uploads are decoded on
worker threads a bounded number at a time, and wrong tokens are throttled (:mod:`.sessions`).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import anyio
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.requests import HTTPConnection, Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..errors import AgentsError, RemoteError, RequestTimeoutError, ServiceUnavailableError
from ..status import TRANSITIONS
from ..topics import Topic
from .approvals import approval_routes
from .body_guard import BodyGuard
from .hub import OutputHub
from .inputs import InputRejected, input_widget, read_bounded_body, value_for_topic
from .json_body import BadJSON, parse_json_body
from .recipe_view import RecipeView, unavailable_entry
from .sessions import Gatekeeper
from .settings import UISettings, is_loopback

__all__ = ["COOKIE_NAME", "UIState", "create_app"]

logger = logging.getLogger(__name__)

STATIC = Path(__file__).resolve().parent / "static"
#: The session cookie: an opaque random id, never the token (see :mod:`.sessions`).
COOKIE_NAME = "agents_ui_session"
#: The largest JSON body of a transition / action / login request.
_SMALL_BODY = 64 * 1024


class UIState:
    """What the endpoints share: the recipe view, the transport, the shown topics and the hub."""

    def __init__(self, view: RecipeView, transport: Any, inputs: list[Topic], outputs: list[Topic],
                 settings: UISettings) -> None:
        self.view = view
        self.transport = transport
        self.settings = settings
        self.inputs = {t.name: t for t in inputs}
        self.outputs = {t.name: t for t in outputs}
        self.hub = OutputHub(transport, outputs, view.component_names(), image_format=settings.image_format,
                             client_queue=settings.client_queue, image_preview=settings.image_preview)
        self.gate = Gatekeeper(settings.token, settings.session_seconds)
        #: Uploads decoded at once: each may take a few hundred MB and a core for a second.
        self.decoders = anyio.CapacityLimiter(settings.decode_workers)
        #: Set by the server: cuts the TCP connection of a client address unless it closes within a
        #: second (a WebSocket client dropped as too slow may have a send buffer that a polite close
        #: would wait on forever). Called on the event loop.
        self.abort_connection: Callable[[tuple[str, int]], bool] | None = None
        #: Request bodies refused by :class:`~.body_guard.BodyGuard`, by rule (size, time, busy).
        self.refused_bodies: dict[str, int] = {}
        self._publishers: dict[str, Any] = {}

    def publisher(self, topic: Topic) -> Any:
        """The (cached) publisher of an input topic."""
        pub = self._publishers.get(topic.name)
        if pub is None:
            pub = self._publishers[topic.name] = self.transport.create_publisher(topic)
        return pub

    def close(self) -> None:
        self.hub.stop()
        publishers, self._publishers = self._publishers, {}
        for pub in publishers.values():
            try:
                pub.close()
            except AgentsError as exc:
                logger.debug("closing the UI publisher on %s: %s", pub.topic.name, exc)


def _error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


# -- the guard: token, origin, host ------------------------------------------------------------


def _address(conn: HTTPConnection) -> str:
    return conn.client.host if conn.client is not None else "?"


def _token_refusal(conn: HTTPConnection, gate: Gatekeeper) -> tuple[int, str] | None:
    """Why ``conn``'s credentials are refused (a bearer token, or a session cookie), or None."""
    auth = conn.headers.get("authorization", "")
    if auth.lower().startswith("bearer "):
        address = _address(conn)
        wait = gate.throttled(address)
        if wait > 0:
            return 429, f"too many wrong tokens from this address; try again in {wait:.0f} s"
        if gate.check_token(address, auth[7:].strip()):
            return None
        return 401, "wrong token"
    session = conn.cookies.get(COOKIE_NAME)
    if session is not None and gate.session_valid(session):
        return None
    if session is not None:
        return 401, "the session has expired; log in again (POST /api/login)"
    return 401, "a token is needed (Authorization: Bearer <token>, or POST /api/login)"


def _refusal(conn: HTTPConnection, state: UIState, needs_token: bool = True) -> tuple[int, str] | None:
    """Why ``conn`` may not use the API (status, message), or None."""
    settings = state.settings
    host = conn.headers.get("host", "")
    hostname = urlsplit(f"//{host}").hostname or ""
    if is_loopback(settings.host) and not is_loopback(hostname):
        return 403, "this UI is bound to loopback: use http://127.0.0.1 (the Host header names another machine)"
    origin = conn.headers.get("origin")
    if origin is not None and urlsplit(origin).netloc != host:
        return 403, "requests from another origin are refused"
    if needs_token and state.gate.token_needed:
        return _token_refusal(conn, state.gate)
    return None


Endpoint = Callable[[Request], Awaitable[Response]]


def _guarded(state: UIState, endpoint: Endpoint, needs_token: bool = True) -> Endpoint:
    async def guarded(request: Request) -> Response:
        refused = _refusal(request, state, needs_token)
        if refused is not None:
            return _error(*refused)
        try:
            return await endpoint(request)
        except InputRejected as exc:
            return _error(exc.status, exc.message)
        except Exception:  # a bug, not the client's fault: logged with its traceback, answered in JSON
            logger.exception("the UI failed on %s %s", request.method, request.url.path)
            return _error(500, "the UI failed on this request (the server log has the details)")

    return guarded


async def _json_body(request: Request) -> dict[str, Any]:
    body = await read_bounded_body(request, _SMALL_BODY)
    if not body.strip():
        return {}
    try:
        document = parse_json_body(body, max_bytes=_SMALL_BODY)
    except BadJSON as exc:
        raise InputRejected(400, str(exc)) from None
    if not isinstance(document, dict):
        raise InputRejected(422, "the body must be a JSON object")
    return document


# -- endpoints --------------------------------------------------------------------------------


def _topic_entry(topic: Topic, topic_id: int | None = None) -> dict[str, Any]:
    entry: dict[str, Any] = {"name": topic.name, "msg_type": topic.msg_type.type_name(),
                             "widget": input_widget(topic.msg_type)}
    if topic_id is not None:  # outputs: the topic_id of their binary frames
        entry["id"] = topic_id
    return entry


def _routes(state: UIState) -> list[Any]:  # noqa: PLR0915  (one closure per endpoint, over one state)
    settings = state.settings

    async def health(request: Request) -> Response:
        hub = state.hub
        return JSONResponse({"ok": True, "transport": state.transport.name, "components": len(hub.components),
                             "clients": hub.client_count, "frames_sent": hub.frames_sent,
                             "dropped_frames": hub.dropped_frames,
                             "dropped_clients": hub.dropped_clients, "encode_errors": hub.encode_errors,
                             "refused_clients": hub.refused_clients, "refused_bodies": dict(state.refused_bodies)})

    def _describe_all() -> list[dict[str, Any]]:
        described = []
        for name in state.view.component_names():
            try:
                entry = dict(state.view.describe(name))
            except (AgentsError, KeyError) as exc:
                described.append(unavailable_entry(name, str(exc)))
                continue
            latest = state.hub.latest_status(name)
            if latest is not None:  # newer than a describe reply that crossed the network
                entry.update(state=latest["state"], health=latest["health"], message=latest["message"])
            described.append(entry)
        return described

    async def interfaces(request: Request) -> Response:
        components = await run_in_threadpool(_describe_all)
        return JSONResponse({"transport": state.transport.name, "components": components,
                             "inputs": [_topic_entry(t) for t in state.inputs.values()],
                             "outputs": [_topic_entry(t, state.hub.topic_ids[t.name])
                                         for t in state.outputs.values()],
                             "max_upload_bytes": settings.max_upload_bytes})

    async def publish_input(request: Request) -> Response:
        name = request.path_params["topic"]
        topic = state.inputs.get(name)
        if topic is None:
            return _error(404, f"topic {name!r} is not an input of this UI; inputs: {sorted(state.inputs)}")
        content_type = request.headers.get("content-type", "")
        body = await read_bounded_body(request, settings.max_upload_bytes)
        upload: bytes | None = None
        if content_type.startswith("multipart/form-data"):
            upload = await _uploaded_file(request, body, topic.name)
            body = b""  # the upload is a copy: let the raw multipart body go before decoding

        def decode_and_publish() -> None:
            value = value_for_topic(topic, content_type, body, upload, max_pixels=settings.max_upload_pixels,
                                    max_json_bytes=settings.max_json_bytes)
            state.publisher(topic).publish(value)

        try:
            # Off the event loop (health, WebSocket frames and the other requests keep going), and a
            # bounded number at a time (each decode may take a few hundred MB).
            await anyio.to_thread.run_sync(decode_and_publish, limiter=state.decoders)
        except AgentsError as exc:
            return _error(422 if isinstance(exc, TypeError | ValueError) else 503, f"topic {name!r}: {exc}")
        return JSONResponse({"ok": True, "topic": name, "msg_type": topic.msg_type.type_name()})

    def _known_component(name: str) -> dict[str, Any] | None:
        if name not in state.view.component_names():
            return None
        try:
            return state.view.describe(name)
        except (AgentsError, KeyError, TypeError, ValueError) as exc:
            raise InputRejected(503, f"component {name!r} is unavailable: {exc}") from None

    async def transition(request: Request) -> Response:
        name = request.path_params["name"]
        document = await _json_body(request)
        wanted = document.get("transition")
        if wanted not in TRANSITIONS:
            return _error(422, f"'transition' must be one of {sorted(TRANSITIONS)}, got {wanted!r}")
        if await run_in_threadpool(_known_component, name) is None:
            return _error(404, f"no component {name!r}; components: {state.view.component_names()}")
        try:
            ok = await run_in_threadpool(state.transport.request_transition, name, wanted,
                                         timeout=settings.request_timeout)
        except AgentsError as exc:
            return _error(*_transport_error(exc, f"component {name!r}"))
        described = await run_in_threadpool(_known_component, name)
        now = described["state"] if described else None
        if not ok:
            return _error(409, f"component {name!r} did not {wanted} (it is {now})")
        return JSONResponse({"ok": True, "component": name, "transition": wanted, "state": now})

    async def action(request: Request) -> Response:
        name, method = request.path_params["name"], request.path_params["action"]
        document = await _json_body(request)
        described = await run_in_threadpool(_known_component, name)
        if described is None:
            return _error(404, f"no component {name!r}; components: {state.view.component_names()}")
        if method not in described.get("actions", {}):
            return _error(404, f"{method!r} is not a component action of {name!r}; actions: "
                               f"{sorted(described.get('actions', {}))}")
        args, kwargs = document.get("args", []), document.get("kwargs", {})
        if not isinstance(args, list) or not isinstance(kwargs, dict):
            return _error(422, "'args' must be a list and 'kwargs' an object")
        payload = {"method": method, "args": args, "kwargs": kwargs, "timeout": settings.request_timeout,
                   "caller": "ui"}
        try:
            reply = await run_in_threadpool(state.transport.request, f"{name}/execute_method", payload,
                                            timeout=settings.request_timeout + 1.0)
        except AgentsError as exc:
            return _error(*_transport_error(exc, f"{name}.{method}"))
        return JSONResponse({"ok": True, "component": name, "action": method, "result": reply.get("result")})

    async def login(request: Request) -> Response:
        gate = state.gate
        if not gate.token_needed:
            return JSONResponse({"ok": True, "token_needed": False})
        address = _address(request)
        wait = gate.throttled(address)
        if wait > 0:  # before reading the body: a throttled address costs nothing
            return _error(429, f"too many wrong tokens from this address; try again in {wait:.0f} s")
        token = (await _json_body(request)).get("token")
        if not isinstance(token, str) or not gate.check_token(address, token):
            return _error(401, "wrong token")
        response = JSONResponse({"ok": True, "token_needed": True})
        response.set_cookie(COOKIE_NAME, gate.open_session(), max_age=int(gate.session_seconds), httponly=True,
                            samesite="strict", secure=request.url.scheme == "https", path="/")
        return response

    async def logout(request: Request) -> Response:
        session = request.cookies.get(COOKIE_NAME)
        if session is not None:
            state.gate.close_session(session)
        response = JSONResponse({"ok": True})
        response.delete_cookie(COOKIE_NAME, httponly=True, samesite="strict", path="/")
        return response

    async def page(request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    return [
        Route("/", page),
        Route("/api/health", _guarded(state, health)),
        Route("/api/interfaces", _guarded(state, interfaces)),
        Route("/api/inputs/{topic:path}", _guarded(state, publish_input), methods=["POST"]),
        Route("/api/components/{name:path}/transition", _guarded(state, transition), methods=["POST"]),
        Route("/api/components/{name:path}/actions/{action}", _guarded(state, action), methods=["POST"]),
        Route("/api/login", _guarded(state, login, needs_token=False), methods=["POST"]),
        Route("/api/logout", _guarded(state, logout, needs_token=False), methods=["POST"]),
        WebSocketRoute("/api/outputs", _outputs_socket(state)),
        *approval_routes(state, lambda endpoint: _guarded(state, endpoint), _json_body, _address),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]


async def _uploaded_file(request: Request, body: bytes, topic: str) -> bytes:
    """The bytes of the multipart field ``file`` of an already read (bounded) ``body``."""
    sent = False

    async def replay() -> dict[str, Any]:
        nonlocal sent
        if sent:
            return {"type": "http.disconnect"}
        sent = True
        return {"type": "http.request", "body": body, "more_body": False}

    try:
        async with Request(request.scope, replay).form(max_files=1, max_fields=8) as form:
            upload = form.get("file")
            if upload is None or isinstance(upload, str):
                raise InputRejected(422, f"topic {topic!r}: the multipart body has no 'file' field")
            return await upload.read()
    except InputRejected:
        raise
    except Exception as exc:  # python-multipart's parse errors, a malformed boundary
        raise InputRejected(400, f"topic {topic!r}: the multipart body does not parse ({exc})") from None


def _transport_error(exc: AgentsError, what: str) -> tuple[int, str]:
    if isinstance(exc, RequestTimeoutError):
        return 504, f"{what}: no answer in time ({exc})"
    if isinstance(exc, ServiceUnavailableError):
        return 503, f"{what}: not reachable ({exc})"
    if isinstance(exc, RemoteError):
        return 422, f"{what}: {exc}"
    return 500, f"{what}: {exc}"


def _outputs_socket(state: UIState) -> Callable[[WebSocket], Awaitable[None]]:
    async def outputs(websocket: WebSocket) -> None:
        refused = _refusal(websocket, state)
        if refused is not None:
            await websocket.close(code=1008, reason=refused[1][:120])
            return
        wanted = websocket.query_params.get("topics")
        topics = [t for t in wanted.split(",") if t] if wanted else None
        unknown = sorted(set(topics or []) - set(state.outputs))
        form = websocket.query_params.get("frames", "json")
        await websocket.accept()
        if unknown:
            await websocket.close(code=1008, reason=f"not outputs of this UI: {unknown}"[:120])
            return
        if form not in ("json", "binary"):
            await websocket.close(code=1008, reason="frames must be 'json' or 'binary'")
            return
        if state.hub.client_count >= state.settings.max_clients:
            state.hub.refused_clients += 1
            await websocket.close(code=1013, reason=f"too many clients ({state.settings.max_clients}); try later")
            return
        client = state.hub.connect(topics, binary=form == "binary", full=websocket.query_params.get("full") == "1")
        try:
            # Two tasks, the first to end stops both: pump sends frames until the client is dropped,
            # listen notices a client that goes away (what it sends is ignored; the server's
            # ws_max_size bounds it).
            async with anyio.create_task_group() as group:

                async def pump() -> None:
                    try:
                        while (frame := await client.next_frame()) is not None:
                            if isinstance(frame, bytes):
                                await websocket.send_bytes(frame)
                            else:
                                await websocket.send_text(frame)
                    except (WebSocketDisconnect, RuntimeError):
                        pass  # the client went away during a send: the end, not an error to log
                    group.cancel_scope.cancel()

                async def listen() -> None:
                    try:
                        while (await websocket.receive())["type"] != "websocket.disconnect":
                            pass
                    except (WebSocketDisconnect, RuntimeError):
                        pass
                    group.cancel_scope.cancel()

                # A dropped client's send may be stuck on a full socket: stop waiting for it.
                client.on_drop = group.cancel_scope.cancel
                group.start_soon(pump)
                group.start_soon(listen)
        finally:
            state.hub.disconnect(client)
        if client.dropped:
            with anyio.move_on_after(1.0):  # the socket may be stuck; the handler ends either way
                try:
                    await websocket.close(code=1013, reason="too slow: frames were not read")
                except Exception as exc:
                    logger.debug("closing a dropped UI client: %s", exc)
            # The close frame waits behind a full send buffer, and uvicorn keeps the connection (and the
            # buffer) until the peer reads, which a stalled client never does: cut it after a grace.
            if state.abort_connection is not None and websocket.client is not None:
                state.abort_connection((websocket.client.host, websocket.client.port))

    return outputs


def create_app(state: UIState) -> Starlette:
    """The Starlette application of ``state``: the hub subscribes at startup and closes at shutdown."""

    @asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        state.hub.start(asyncio.get_running_loop())
        try:
            yield
        finally:
            state.close()

    settings = state.settings
    guard = Middleware(BodyGuard, max_bytes=settings.max_upload_bytes, timeout=settings.body_timeout,
                       max_bodies=settings.max_bodies, refused=state.refused_bodies)
    return Starlette(routes=_routes(state), lifespan=lifespan, middleware=[guard])
