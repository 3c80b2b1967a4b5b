"""Model server stand-ins for upstream's Memory recipes: an Ollama that embeds by words and plans "go to X",
and a RoboML whose detector is the real COCO SSD from ``../shared/models``.

Both are real servers on 127.0.0.1 speaking the real protocols (they subclass the doubles in
``tests/servers``); only the answers are chosen so that a test can check what a recipe did:

- :class:`GoToOllamaServer` embeds a text as its bag of words (hashed into a fixed number of
  dimensions, unit length), so "cup" is near "cup, dining table" and far from "cat", as a real
  embedding model would have it; and when a chat request offers tools and its last user message
  says "go to (the) X", it answers with one call of the first offered tool with ``X`` as the
  argument the test named (``concept`` for Memory's ``locate``). A chat with an image is answered with
  the room the test said that photo shows ("This looks like a kitchen."), told apart by the photo's
  width; any other chat is the base answer.
- :class:`CocoRoboMLServer` answers a ``VisionModel`` node's inference with the COCO SSD's
  detections (labels such as ``cat``, ``cup``), so what the memory stores depends on the photo the
  camera showed.
"""

from __future__ import annotations

import base64
import hashlib
import io
import math
import re
import threading
from functools import cached_property
from typing import Any

from ..servers.ollama_server import Fault, OllamaTestServer, ProtocolHandler
from ..servers.roboml_server import RoboMLTestServer, decode_png

__all__ = ["CocoRoboMLServer", "GoToOllamaServer", "word_embedding"]

#: Length of the word-hash embeddings (large enough that the few words of a test rarely collide).
EMBEDDING_DIM = 256

_GO_TO = re.compile(r"go to (?:the )?([a-z][a-z ]*?)[.!?]*$", re.IGNORECASE)


def word_embedding(text: str, dim: int = EMBEDDING_DIM) -> list[float]:
    """``text``'s lower-case words, each hashed to one dimension, counted, scaled to unit length."""
    vector = [0.0] * dim
    for word in re.findall(r"[a-z0-9]+", text.lower()):
        vector[int.from_bytes(hashlib.sha256(word.encode()).digest()[:4], "big") % dim] += 1.0
    norm = math.sqrt(sum(v * v for v in vector))
    if norm == 0.0:  # no words: a fixed vector, so that an empty text still embeds
        vector[0], norm = 1.0, 1.0
    return [round(v / norm, 6) for v in vector]


class GoToOllamaServer(OllamaTestServer):
    """An Ollama stand-in whose embeddings follow the words and whose model turns "go to X" into a tool call.

    :param place_argument: the tool argument that gets the place's name (``"concept"`` for Memory's
        ``locate``, ``"place"`` for a recipe's own tool).
    :param rooms: photo width (pixels) -> the room a vision-language model sees in that photo.
    """

    def __init__(self, models: list[str], place_argument: str = "concept", rooms: dict[int, str] | None = None) -> None:
        super().__init__(models=models)
        self.place_argument = place_argument
        self.rooms = dict(rooms or {})
        self._chat_lock = threading.Lock()

    def _embed(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        if self._model_of(handler, body) is None:
            return
        inputs = body.get("input")
        texts = [inputs] if isinstance(inputs, str) else inputs
        if not isinstance(texts, list) or not all(isinstance(t, str) for t in texts):
            handler.send_json(400, {"error": "invalid input type"})
            return
        handler.send_json(200, {"model": body.get("model"), "embeddings": [word_embedding(t) for t in texts]})

    def _chat(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        # The answer is chosen per request, then the base server sends it; one chat at a time, as the
        # base server reads the answer from these attributes.
        with self._chat_lock:
            self.tool_calls = self._plan(body)
            self.reply = self._room(body)
            super()._chat(handler, body, fault)

    def _room(self, body: dict[str, Any]) -> str | None:
        images = [image for m in body.get("messages") or [] if isinstance(m, dict) for image in m.get("images") or []]
        if not images or not self.rooms:
            return None
        from PIL import Image  # noqa: PLC0415  (only the VLM recipes send images)

        with Image.open(io.BytesIO(base64.b64decode(images[-1]))) as img:
            width = img.size[0]
        room = self.rooms.get(width)
        return f"This looks like a {room}." if room else "I cannot tell which room this is."

    def _plan(self, body: dict[str, Any]) -> list[dict[str, Any]] | None:
        tools = body.get("tools") or []
        messages = body.get("messages") or []
        users = [m.get("content") or "" for m in messages if isinstance(m, dict) and m.get("role") == "user"]
        if not tools or not users:
            return None
        found = _GO_TO.search(users[-1].strip())
        name = ((tools[0] or {}).get("function") or {}).get("name")
        if found is None or not name:
            return None
        return [{"name": name, "arguments": {self.place_argument: found.group(1).strip()}}]


class _CocoNode:
    """Wraps a RoboML double's vision node: inference runs the COCO SSD on each image."""

    def __init__(self, node: Any, detector: Any) -> None:
        self._node, self._detector = node, detector

    def __getattr__(self, name: str) -> Any:
        return getattr(self._node, name)

    def infer(self, data: dict[str, Any]) -> tuple[dict[str, Any] | None, list[str] | None]:
        data = self._node.validate(data)
        if self._node.status != "READY":
            raise RuntimeError("Inference called before initialization")
        threshold = float(data.get("threshold", 0.5))
        results = []
        for image in data["images"]:
            # RESP carries arrays; the HTTP and WebSocket protocols base64 PNGs.
            pixels = image if hasattr(image, "shape") else decode_png(base64.b64decode(image))
            found = self._detector.detect(pixels[..., :3], threshold)
            results.append({"bboxes": [list(map(float, b)) for b in found["bboxes"]],
                            "labels": list(found["labels"]), "scores": [float(s) for s in found["scores"]]})
        return {"output": results}, None


class CocoRoboMLServer(RoboMLTestServer):
    """The RoboML double with the real COCO SSD behind its ``VisionModel`` nodes.

    :param model_path: the SSD's ``.onnx`` file (see ``tests/components/vision_recipe.py``).
    """

    def __init__(self, model_path: str) -> None:
        super().__init__()
        self.model_path = model_path

    @cached_property
    def detector(self) -> Any:
        """The COCO SSD, loaded on first use."""
        from agents_core.engines.local_vision import LocalVisionModel  # noqa: PLC0415

        return LocalVisionModel(model_path=self.model_path, threshold=0.4)

    def _add_node(self, name: str, model: str) -> dict[str, Any]:
        answer = super()._add_node(name, model)
        if model == "VisionModel" and not isinstance(self.nodes[name], _CocoNode):
            self.nodes[name] = _CocoNode(self.nodes[name], self.detector)  # type: ignore[assignment]
        return answer
