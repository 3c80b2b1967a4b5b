"""The guard in front of the ``foxglove-sdk`` WebSocket server: what the SDK cannot bound, bounded here.

The SDK's server (0.30) buffers ``message_backlog_size`` *messages* per client whatever their
size, takes any number of clients, keeps a connection that never finishes its HTTP upgrade, and
answers any ``Origin``: a web page in a browser on the machine could watch every topic. It has no
hook for any of that, so the bridge runs it on a hidden loopback port and puts this guard, a small
asyncio TCP proxy on a thread of its own, on the port clients are given:

* **clients**: at most ``max_clients`` connections at once (handshakes included); one more is
  answered ``503`` and closed.
* **handshake**: the HTTP upgrade request must arrive whole within ``handshake_timeout`` seconds
  and within 16 KiB, else the connection is closed (``408`` / ``431``).
* **origin**: a request with an ``Origin`` header is refused (``403``) unless that origin is the
  bridge's own (the ``Host`` it was asked for, as the web UI's rule) or listed in
  ``allowed_origins`` (``https://app.foxglove.dev`` to use Foxglove's web app). Clients that are
  not web pages (the Foxglove desktop app, scripts) send none.
* **per-client buffer, in bytes**: what the server sends a client waits in a queue of at most
  ``client_buffer_bytes``; an image channel (``foxglove.RawImage``, ``foxglove.CompressedImage``)
  keeps only its newest frame waiting (latest wins), other data drops its oldest message past the
  bound; control messages are never dropped (a client too slow even for those is disconnected).
  While a client does not take what was sent (its socket is full) and something already waits for
  it, the guard stops reading that client's stream from the SDK, whose own queue then holds at most
  ``client_backlog`` messages and drops the oldest: a stalled client costs neither memory past
  those bounds nor CPU. Compression is not negotiated, so frames can be read.

The hidden hop is TLS with a key made for this bridge when ``cryptography`` is installed, so a web
page that finds the hidden port by scanning cannot talk to it (a browser refuses the unknown
certificate, and the SDK refuses plain ``ws://``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import ssl
import struct
import threading
from collections import deque
from typing import Any
from urllib.parse import urlsplit

from attrs import define

__all__ = ["FoxgloveGuard", "GuardStatistics", "hidden_hop_tls"]

logger = logging.getLogger(__name__)

_MAX_HEAD = 16 * 1024
#: The largest frame a client may send (the protocol's control messages are small).
_MAX_CLIENT_FRAME = 16 * 1024 * 1024
#: Client text frames up to this size are read for their subscriptions (to know image channels).
_MAX_PARSED = 1024 * 1024
_IMAGE_SCHEMAS = frozenset({"foxglove.RawImage", "foxglove.CompressedImage"})
_MESSAGE_DATA = 0x01


@define
class GuardStatistics:
    """What the guard refused and dropped since it started."""

    clients: int = 0
    refused_clients: int = 0
    refused_origins: int = 0
    handshake_timeouts: int = 0
    dropped_messages: int = 0
    dropped_bytes: int = 0
    slow_clients_closed: int = 0


def hidden_hop_tls() -> tuple[bytes, bytes, ssl.SSLContext] | None:
    """A fresh self-signed certificate and key (PEM) and a client context trusting only it; None
    without ``cryptography``."""
    try:
        import datetime  # noqa: PLC0415

        from cryptography import x509  # noqa: PLC0415
        from cryptography.hazmat.primitives import hashes, serialization  # noqa: PLC0415
        from cryptography.hazmat.primitives.asymmetric import ec  # noqa: PLC0415
        from cryptography.x509.oid import NameOID  # noqa: PLC0415
    except ImportError:
        return None
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name).public_key(key.public_key())
            .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=3650))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName("localhost")]), critical=False)
            .sign(key, hashes.SHA256()))
    cert_pem = cert.public_bytes(serialization.Encoding.PEM)
    key_pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                serialization.NoEncryption())
    context = ssl.create_default_context(cadata=cert_pem.decode())
    context.check_hostname = True
    return cert_pem, key_pem, context


def _response(status: str, text: str) -> bytes:
    body = text.encode()
    return (f"HTTP/1.1 {status}\r\nContent-Type: text/plain\r\nContent-Length: {len(body)}\r\n"
            "Connection: close\r\n\r\n").encode() + body


async def _read_frame(reader: asyncio.StreamReader, limit: int) -> tuple[int, bytes, bytes | None, int]:
    """One WebSocket frame: (first byte, header bytes, payload or None when over ``limit``, length)."""
    head = await reader.readexactly(2)
    n = head[1] & 0x7F
    ext = b""
    if n == 126:
        ext = await reader.readexactly(2)
        n = struct.unpack("!H", ext)[0]
    elif n == 127:
        ext = await reader.readexactly(8)
        n = struct.unpack("!Q", ext)[0]
    mask = await reader.readexactly(4) if head[1] & 0x80 else b""
    if n > limit:
        return head[0], head + ext + mask, None, n
    return head[0], head + ext + mask, await reader.readexactly(n), n


async def _skip(reader: asyncio.StreamReader, n: int) -> None:
    while n > 0:
        chunk = await reader.read(min(n, 1 << 20))
        if not chunk:
            raise asyncio.IncompleteReadError(b"", n)
        n -= len(chunk)


class _Outbox:
    """One client's queue of frames from the server, bounded in bytes (see the module docstring)."""

    def __init__(self, limit: int, stats: GuardStatistics) -> None:
        self.limit = limit
        self.items: deque[tuple[int | None, bytes]] = deque()  # (image subscription or -1 for data, frame)
        self.size = 0
        self.ready = asyncio.Event()
        #: Clear while the client's socket does not take what was written (the writer waits on it).
        self.flowing = asyncio.Event()
        self.flowing.set()
        self.closed = False
        self._stats = stats

    def put(self, key: int | None, frame: bytes, image: bool) -> bool:
        """Queue ``frame`` (``key``: its subscription for data, None for control); False: close the client."""
        if image and key is not None:
            for i, (k, old) in enumerate(self.items):
                if k == key:  # latest wins: the waiting frame of this image channel is replaced
                    del self.items[i]
                    self.size -= len(old)
                    self._drop(old)
                    break
        self.items.append((key, frame))
        self.size += len(frame)
        while self.size > self.limit:
            for i, (k, old) in enumerate(self.items):
                if k is not None:
                    del self.items[i]
                    self.size -= len(old)
                    self._drop(old)
                    break
            else:
                return False  # only control messages left, and too many: the client is too slow
        self.ready.set()
        return True

    def _drop(self, frame: bytes) -> None:
        self._stats.dropped_messages += 1
        self._stats.dropped_bytes += len(frame)

    def pop(self) -> bytes | None:
        if not self.items:
            self.ready.clear()
            return None
        _, frame = self.items.popleft()
        self.size -= len(frame)
        return frame


class FoxgloveGuard:
    """Listens on ``host:port`` and relays each client to the SDK server at ``127.0.0.1:upstream_port``.

    :param settings: a :class:`~.settings.FoxgloveSettings` (the bounds: ``max_clients``,
        ``handshake_timeout``, ``client_buffer_bytes``, ``allowed_origins``).
    :param upstream_tls: the client context of the hidden TLS hop (None: plain).
    """

    def __init__(self, host: str, port: int, upstream_port: int, settings: Any,
                 upstream_tls: ssl.SSLContext | None = None) -> None:
        self._host, self._port, self._upstream_port = host, port, upstream_port
        self._settings = settings
        self._tls = upstream_tls
        self.stats = GuardStatistics()
        self._active = 0
        self._loop = asyncio.new_event_loop()
        self._server: asyncio.Server | None = None
        self._thread: threading.Thread | None = None
        self._tasks: set[asyncio.Task[Any]] = set()

    @property
    def port(self) -> int:
        """The port clients connect to."""
        assert self._server is not None
        return int(self._server.sockets[0].getsockname()[1])

    def start(self) -> FoxgloveGuard:
        """Bind now (an address in use is an OSError here), then serve on the guard's thread."""
        self._server = self._loop.run_until_complete(asyncio.start_server(
            self._accept, self._host, self._port, limit=_MAX_HEAD, backlog=256))
        self._thread = threading.Thread(target=self._loop.run_forever, name="foxglove-guard", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Close the listening socket and every relayed connection; idempotent."""
        if self._thread is None:
            return

        async def close() -> None:
            if self._server is not None:
                self._server.close()
            for task in list(self._tasks):
                task.cancel()
            await asyncio.gather(*self._tasks, return_exceptions=True)

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(close(), self._loop).result(5)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(5)
        self._thread = None
        with contextlib.suppress(Exception):
            self._loop.close()

    # -- one client ---------------------------------------------------------------------------------

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        try:
            if self._active >= self._settings.max_clients:
                self.stats.refused_clients += 1
                writer.write(_response("503 Service Unavailable", f"at most {self._settings.max_clients} "
                                       "Foxglove clients at once (max_clients)"))
                return
            self._active += 1
            try:
                await self._client(reader, writer)
            finally:
                self._active -= 1
        except (OSError, asyncio.IncompleteReadError, asyncio.CancelledError):
            pass
        finally:
            self._tasks.discard(task)
            with contextlib.suppress(Exception):
                writer.close()

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), self._settings.handshake_timeout)
        except asyncio.TimeoutError:
            self.stats.handshake_timeouts += 1
            writer.write(_response("408 Request Timeout", "the WebSocket upgrade did not arrive in time"))
            return
        except (asyncio.LimitOverrunError, ValueError):
            writer.write(_response("431 Request Header Fields Too Large", "request head over 16 KiB"))
            return
        lines = head.decode("latin-1").split("\r\n")
        headers: dict[str, str] = {}
        for line in lines[1:]:
            name, sep, value = line.partition(":")
            if sep:
                headers[name.strip().lower()] = value.strip()
        refusal = self._origin_refusal(headers)
        if refusal is not None:
            self.stats.refused_origins += 1
            writer.write(_response("403 Forbidden", refusal))
            return
        # No permessage-deflate: the guard must read the server's frames to bound them.
        kept = [lines[0]] + [line for line in lines[1:] if line and
                             not line.lower().startswith("sec-websocket-extensions")]
        up_reader, up_writer = await asyncio.wait_for(asyncio.open_connection(
            "127.0.0.1", self._upstream_port, ssl=self._tls, server_hostname="localhost" if self._tls else None,
            limit=1 << 20), self._settings.handshake_timeout)
        try:
            up_writer.write(("\r\n".join(kept) + "\r\n\r\n").encode("latin-1"))
            answer = await asyncio.wait_for(up_reader.readuntil(b"\r\n\r\n"), self._settings.handshake_timeout)
            writer.write(answer)
            if not answer.startswith(b"HTTP/1.1 101"):
                return
            self.stats.clients += 1
            await self._relay(reader, writer, up_reader, up_writer)
        finally:
            with contextlib.suppress(Exception):
                up_writer.close()

    def _origin_refusal(self, headers: dict[str, str]) -> str | None:
        origin = headers.get("origin")
        if origin is None:
            return None
        allowed = {o.rstrip("/") for o in self._settings.allowed_origins}
        if origin.rstrip("/") in allowed or urlsplit(origin).netloc == headers.get("host", ""):
            return None
        return (f"WebSocket requests from the web page origin {origin[:200]!r} are refused (a page could "
                "watch every topic); allow it with FoxgloveSettings.allowed_origins")

    async def _relay(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter,
                     up_reader: asyncio.StreamReader, up_writer: asyncio.StreamWriter) -> None:
        outbox = _Outbox(self._settings.client_buffer_bytes, self.stats)
        channels: dict[int, str] = {}  # channel id -> schema name (from the server's advertise)
        subscriptions: dict[int, int] = {}  # subscription id -> channel id (from the client's subscribe)
        tasks = [asyncio.ensure_future(self._from_client(reader, up_writer, subscriptions)),
                 asyncio.ensure_future(self._from_server(up_reader, outbox, channels, subscriptions)),
                 asyncio.ensure_future(self._to_client(writer, outbox))]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def _from_client(self, reader: asyncio.StreamReader, up_writer: asyncio.StreamWriter,
                           subscriptions: dict[int, int]) -> None:
        with contextlib.suppress(asyncio.IncompleteReadError, OSError):
            while True:
                first, header, payload, n = await _read_frame(reader, _MAX_CLIENT_FRAME)
                if payload is None:
                    return  # a frame larger than any the protocol needs: the connection ends
                if first & 0x0F == 0x1 and n <= _MAX_PARSED and len(header) >= 6:
                    _note_subscriptions(_unmask(payload, header[-4:]), subscriptions)
                up_writer.write(header + payload)
                await up_writer.drain()

    async def _from_server(self, up_reader: asyncio.StreamReader, outbox: _Outbox, channels: dict[int, str],
                           subscriptions: dict[int, int]) -> None:
        with contextlib.suppress(asyncio.IncompleteReadError, OSError):
            while True:
                if outbox.items and not outbox.flowing.is_set():
                    await outbox.flowing.wait()  # backpressure: the SDK's bounded queue takes over
                first, header, payload, n = await _read_frame(up_reader, outbox.limit)
                opcode, fin = first & 0x0F, bool(first & 0x80)
                data = fin and opcode == 0x2 and (payload is None or payload[:1] == bytes([_MESSAGE_DATA]))
                if payload is None:
                    if not data:
                        return  # a control message larger than the whole buffer: give up on the client
                    await _skip(up_reader, n)
                    self.stats.dropped_messages += 1
                    self.stats.dropped_bytes += n
                    continue
                key: int | None = None
                image = False
                if data and len(payload) >= 5:
                    key = struct.unpack_from("<I", payload, 1)[0]
                    image = channels.get(subscriptions.get(key, -1), "") in _IMAGE_SCHEMAS
                elif opcode == 0x1 and fin:
                    _note_channels(payload, channels)
                if not outbox.put(key, header + payload, image):
                    self.stats.slow_clients_closed += 1
                    return

    @staticmethod
    async def _to_client(writer: asyncio.StreamWriter, outbox: _Outbox) -> None:
        while True:
            frame = outbox.pop()
            if frame is None:
                await outbox.ready.wait()
                continue
            writer.write(frame)
            if writer.transport.get_write_buffer_size() > 0:
                outbox.flowing.clear()
                try:
                    await writer.drain()
                finally:
                    outbox.flowing.set()


def _unmask(payload: bytes, mask: bytes) -> bytes:
    whole = (mask * (len(payload) // 4 + 1))[: len(payload)]
    return (int.from_bytes(payload, "little") ^ int.from_bytes(whole, "little")).to_bytes(len(payload), "little")


def _json(payload: bytes) -> Any:
    try:
        return json.loads(payload)
    except ValueError:
        return None


def _note_subscriptions(payload: bytes, subscriptions: dict[int, int]) -> None:
    doc = _json(payload)
    if not isinstance(doc, dict):
        return
    if doc.get("op") == "subscribe" and isinstance(doc.get("subscriptions"), list):
        for item in doc["subscriptions"][:10_000]:
            if isinstance(item, dict) and isinstance(item.get("id"), int) and isinstance(item.get("channelId"), int) \
                    and len(subscriptions) < 100_000:
                subscriptions[item["id"]] = item["channelId"]
    elif doc.get("op") == "unsubscribe" and isinstance(doc.get("subscriptionIds"), list):
        for sub in doc["subscriptionIds"][:10_000]:
            if isinstance(sub, int):
                subscriptions.pop(sub, None)


def _note_channels(payload: bytes, channels: dict[int, str]) -> None:
    doc = _json(payload)
    if isinstance(doc, dict) and doc.get("op") == "advertise" and isinstance(doc.get("channels"), list):
        for channel in doc["channels"]:
            if isinstance(channel, dict) and isinstance(channel.get("id"), int):
                channels[channel["id"]] = str(channel.get("schemaName", ""))
    elif isinstance(doc, dict) and doc.get("op") == "unadvertise" and isinstance(doc.get("channelIds"), list):
        for cid in doc["channelIds"]:
            if isinstance(cid, int):
                channels.pop(cid, None)
