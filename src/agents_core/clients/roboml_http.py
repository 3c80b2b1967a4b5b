"""``RoboMLHTTPClient``: a model served by RoboML, reached over its HTTP API.

The protocol (routes, bodies, status codes) is described in :mod:`agents_core.clients.roboml`.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, MutableMapping
from typing import Any, ClassVar

import httpx

from ..errors import HTTPStatusError, ProtocolError
from .deadline import BoundedHTTP
from .payloads import ChunkStream
from .roboml import (
    RoboMLNodeClient,
    build_roboml_input,
    error_detail,
    normalize_result,
    retry_connect,
)

__all__ = ["RoboMLHTTPClient"]


class RoboMLHTTPClient(RoboMLNodeClient):
    """A model served by `RoboML <https://github.com/automatika-robotics/roboml>`_ over HTTP.

    Configure creates a node named after the model on the server, with the RoboML model class
    that serves it (``TransformersLLM``, ``Whisper``, ``VisionModel``, ...), and loads the model
    with its init parameters; shutdown removes the node. LLM inferences with ``stream: True``
    return a :class:`~agents_core.clients.payloads.ChunkStream` of text chunks.

    :param model: a RoboML model (:class:`~agents_core.models.TransformersLLM`,
        :class:`~agents_core.models.TransformersMLLM`, :class:`~agents_core.models.RoboBrain2`,
        :class:`~agents_core.models.Whisper`, :class:`~agents_core.models.TransformersTTS`,
        :class:`~agents_core.models.VisionModel` or a subclass), or its serialized dict. Its
        ``name`` names the node, so it may hold letters, digits, ``_`` and ``-`` only.
    :param host: RoboML's host.
    :param port: RoboML's HTTP port (8000 by default, as ``roboml`` starts).
    :param inference_timeout: seconds a whole inference may take, connect to last byte (a
        streamed answer included; ``stream_first_chunk_timeout`` and ``stream_chunk_timeout``
        bound its chunks, see :class:`~agents_core.clients.model_base.ModelClient`). Loading the
        model is bounded by the model's ``init_timeout`` instead.
    :param init_on_activation: create and load the node during configure.
    :param logging_level: ``"debug"``, ``"info"``, ...
    """

    default_port: ClassVar[int] = 8000

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._http: BoundedHTTP | None = None
        self._http_lock = threading.Lock()

    @property
    def url(self) -> str:
        """RoboML's base HTTP URL."""
        return f"http://{self.host}:{self.port}"

    def _client(self) -> BoundedHTTP:
        # Created on first use, never in the constructor (a client is built in processes that may
        # never use it, and must not touch the network there).
        with self._http_lock:
            if self._http is None or self._http.is_closed:
                self._http = BoundedHTTP(self.url)
            return self._http

    def _request(self, method: str, path: str, what: str, *, seconds: float | None = None,
                 setting: str = "inference_timeout", **kwargs: Any) -> httpx.Response:
        """One request, its whole answer read within ``seconds`` (default ``inference_timeout``)."""
        budget = float(self.inference_timeout if seconds is None else seconds)
        return self._client().request(method, path, seconds=budget, label=f"{self._label()}: {what}", what=setting,
                                      **kwargs)

    def _raise_for_status(self, response: httpx.Response, what: str) -> None:
        if not response.is_error:
            return
        try:
            response.read()  # a streamed response has not read its (short) error body yet
        except httpx.HTTPError:
            detail = "(no body)"
        else:
            try:
                detail = error_detail(response.json())
            except ValueError:
                detail = response.text[:500]
        raise HTTPStatusError(f"{self._label()}: {what}: RoboML answered {response.status_code}: {detail}",
                              status=response.status_code)

    def _json(self, response: httpx.Response, what: str) -> Any:
        try:
            return response.json()
        except ValueError as exc:
            raise ProtocolError(f"{self._label()}: {what}: RoboML's answer is not JSON: {response.text[:200]!r}") \
                from exc

    # -- ModelClient ------------------------------------------------------------------------

    def _check_connection(self) -> None:
        def ping() -> None:
            response = self._request("GET", "/", "connection check", seconds=min(float(self.inference_timeout), 10.0))
            self._raise_for_status(response, "connection check")

        retry_connect(ping, attempts=self.connect_attempts, delay=self.connect_retry_delay,
                      retry_on=(httpx.ConnectError, httpx.ConnectTimeout), logger=self.logger,
                      what=f"{self._label()}: connection check")

    def _initialize(self) -> None:
        response = self._request("POST", "/add_node", "add_node",
                                 params={"node_name": self.node_name, "node_model": self.node_model})
        self._raise_for_status(response, f"add_node {self.node_name!r} ({self.node_model})")
        answer = self._json(response, "add_node")
        if isinstance(answer, dict) and "warning" in answer:
            # The node exists (another client, or a previous run): RoboML keeps the loaded model
            # and answers initialize at once if it is ready.
            self.logger.warning("RoboML: %s", answer["warning"])
        response = self._request("POST", f"/{self.node_name}/initialize", "initialize", seconds=self._init_seconds,
                                 setting="init_timeout", json=self.model_init_params)
        self._raise_for_status(response, f"initialize node {self.node_name!r}")
        self.logger.info("RoboML node %r (%s) is ready", self.node_name, self.node_model)

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        payload, stream = build_roboml_input(self.node_model, inference_input, binary=False)
        path = f"/{self.node_name}/inference"
        if stream:
            return {"output": self._stream_http(path, payload)}
        response = self._request("POST", path, "inference", json=payload)
        self._raise_for_status(response, "inference")
        return normalize_result(self.node_model, self._json(response, "inference"), self._label())

    def _stream_http(self, path: str, payload: dict[str, Any]) -> ChunkStream[str]:
        watch = self._watch("inference", stream=True)
        try:
            response = self._client().open("POST", path, watch, json=payload)
        except BaseException:
            watch.close()
            raise
        try:
            self._raise_for_status(response, "inference")
        except Exception as exc:
            watch.close()
            response.close()
            if watch.fired is not None:
                raise watch.error() from exc
            raise

        def chunks() -> Iterator[str]:
            # RoboML streams tokens as plain text with no framing; httpx's decoder keeps
            # characters split across network reads whole.
            for text in response.iter_text():
                watch.check()
                if text:
                    yield text

        return self._chunk_stream(chunks(), watch, f"{self._label()}: inference", on_close=response.close)

    def _deinitialize(self) -> None:
        try:
            response = self._request("POST", "/remove_node", "remove_node", params={"node_name": self.node_name})
            self._raise_for_status(response, f"remove_node {self.node_name!r}")
        finally:
            self.close()

    # -- extras -----------------------------------------------------------------------------

    def node_status(self) -> str:
        """The node's status: ``"LOADED"``, ``"INITIALIZING"``, ``"READY"`` or ``"INITIALIZATION_ERROR"``."""
        def get() -> str:
            response = self._request("GET", f"/{self.node_name}/get_status", "get_status")
            self._raise_for_status(response, "get_status")
            return str(self._json(response, "get_status"))

        return self._guard("node status", get)

    def close(self) -> None:
        """Close the HTTP connections (idempotent; the next call opens new ones)."""
        with self._http_lock:
            http, self._http = self._http, None
        if http is not None:
            http.close()
