"""``RoboMLHTTPClient``: a model served by RoboML, reached over its HTTP API.

The protocol (routes, bodies, status codes) is described in
:mod:`agents_core.clients.roboml_protocol`.
"""

from __future__ import annotations

from collections.abc import Iterator, MutableMapping
from typing import Any, ClassVar

import httpx

from .http_base import HTTPClientBase
from .payloads import ChunkStream
from .roboml_protocol import RoboMLNodeClient, build_roboml_input, normalize_result, retry_connect

__all__ = ["RoboMLHTTPClient"]


class RoboMLHTTPClient(HTTPClientBase, RoboMLNodeClient):
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
    status_template: ClassVar[str] = "RoboML answered {status}"

    @property
    def url(self) -> str:
        """RoboML's base HTTP URL (the same as ``base_url``)."""
        return self.base_url

    # -- ModelClient ------------------------------------------------------------------------

    def _check_connection(self) -> None:
        def ping() -> None:
            self._request("GET", "/", "connection check", seconds=min(float(self.inference_timeout), 10.0))

        retry_connect(ping, attempts=self.connect_attempts, delay=self.connect_retry_delay,
                      retry_on=(httpx.ConnectError, httpx.ConnectTimeout), logger=self.logger,
                      what=f"{self._label()}: connection check")

    def _initialize(self) -> None:
        answer = self._request_json("POST", "/add_node", f"add_node {self.node_name!r} ({self.node_model})",
                                    params={"node_name": self.node_name, "node_model": self.node_model})
        if isinstance(answer, dict) and "warning" in answer:
            # The node exists (another client, or a previous run): RoboML keeps the loaded model
            # and answers initialize at once if it is ready.
            self.logger.warning("RoboML: %s", answer["warning"])
        self._request("POST", f"/{self.node_name}/initialize", f"initialize node {self.node_name!r}",
                      seconds=self._init_seconds, setting="init_timeout", json=self.model_init_params)
        self.logger.info("RoboML node %r (%s) is ready", self.node_name, self.node_model)

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        payload, stream = build_roboml_input(self.node_model, inference_input, binary=False)
        path = f"/{self.node_name}/inference"
        if stream:
            return {"output": self._stream_http(path, payload)}
        return normalize_result(self.node_model, self._request_json("POST", path, "inference", json=payload),
                                self._label())

    def _stream_http(self, path: str, payload: dict[str, Any]) -> ChunkStream[str]:
        watch = self._watch("inference", stream=True)
        response = self._open_stream("POST", path, "inference", watch, json=payload)

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
            self._request("POST", "/remove_node", f"remove_node {self.node_name!r}",
                          params={"node_name": self.node_name})
        finally:
            self.close()

    # -- extras -----------------------------------------------------------------------------

    def node_status(self) -> str:
        """The node's status: ``"LOADED"``, ``"INITIALIZING"``, ``"READY"`` or ``"INITIALIZATION_ERROR"``."""
        return self._guard("node status",
                           lambda: str(self._request_json("GET", f"/{self.node_name}/get_status", "get_status")))
