"""Model descriptions: what a model client should load on its serving platform.

A model is attrs data (``@define(kw_only=True)``) holding a name, a checkpoint and the
platform-specific options; :meth:`Model._get_init_params` is the dict sent to the platform when
the client initializes. Model classes register themselves by class name, so a serialized
client can say which kind of model it serves.
"""

from __future__ import annotations

from typing import Any, ClassVar, Final

from attrs import define, field

from . import base_validators
from .config import BaseAttrs
from .errors import ConfigError

__all__ = [
    "LLM",
    "GenericLLM",
    "GenericMLLM",
    "GenericSTT",
    "GenericTTS",
    "Model",
    "OllamaModel",
    "model_types",
]

_model_types: dict[str, type[Model]] = {}


def model_types() -> dict[str, type[Model]]:
    """Every model class defined so far, by class name."""
    return dict(_model_types)


def _non_empty_str(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a non-empty str, got {value!r}")


@define(kw_only=True)
class Model(BaseAttrs):
    """Base of model descriptions.

    :param name: an identifier chosen by the user (logs, client keys).
    :param checkpoint: the model's identifier on the serving platform (Ollama tag, hub repo, ...).
    :param init_timeout: seconds the platform may take to load the model (None: its default).
    """

    #: Set by subclasses that only some components can use (informational).
    model_family: ClassVar[str] = "generic"

    name: str = field(validator=_non_empty_str)
    checkpoint: str = field(validator=_non_empty_str)
    init_timeout: int | None = field(default=None, validator=base_validators.gt(0))

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # attrs re-creates slotted classes; the last registration is the final class.
        _model_types[cls.__name__] = cls

    def _get_init_params(self) -> dict[str, Any]:
        """The parameters the serving platform needs to load this model."""
        return {"checkpoint": self.checkpoint}


_model_types["Model"] = Model


def _check_options(allowed: dict[str, type | tuple[type, ...]]) -> Any:
    """A validator for an ``options`` dict: known keys only, each of the right type."""

    def validate(instance: Any, attribute: Any, value: Any) -> None:
        if value is None:
            return
        where = f"{type(instance).__name__}.{attribute.name}"
        if not isinstance(value, dict):
            raise ConfigError(f"{where} must be a dict or None, got {type(value).__name__}")
        for key, val in value.items():
            if key not in allowed:
                raise ConfigError(f"{where}: unknown option {key!r}; allowed: {sorted(allowed)}")
            kind = allowed[key]
            # bool is an int in Python; an int option given True is almost surely a mistake.
            if (isinstance(val, bool) and kind is not bool) or not isinstance(val, kind):
                names = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
                raise ConfigError(f"{where}: option {key!r} must be {names}, got {val!r}")

    return validate


_NUMBER = (int, float)


@define(kw_only=True)
class LLM(Model):
    """A large language model served by a platform that can quantize it on load.

    :param quantization: ``"4bit"``, ``"8bit"`` or None (full precision).
    """

    model_family: ClassVar[str] = "llm"

    quantization: str | None = field(default="4bit", validator=base_validators.in_(["4bit", "8bit", None]))

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "quantization": self.quantization}


#: Ollama's model options (its Modelfile parameters) and their types.
OLLAMA_OPTIONS: Final[dict[str, type | tuple[type, ...]]] = {
    "num_keep": int, "seed": int, "num_predict": int, "top_k": int, "top_p": _NUMBER, "min_p": _NUMBER,
    "typical_p": _NUMBER, "repeat_last_n": int, "temperature": _NUMBER, "repeat_penalty": _NUMBER,
    "presence_penalty": _NUMBER, "frequency_penalty": _NUMBER, "penalize_newline": bool, "stop": list,
    "numa": bool, "num_ctx": int, "num_batch": int, "num_gpu": int, "main_gpu": int, "use_mmap": bool,
    "num_thread": int,
}


@define(kw_only=True)
class OllamaModel(LLM):
    """A model served by Ollama.

    :param checkpoint: the Ollama tag, e.g. ``"llama3.2:3b"`` or ``"qwen3:0.6b"``.
    :param port: Ollama's port (used by clients that are not given one).
    :param options: Ollama model options (``temperature``, ``num_ctx``, ...), checked by name and type.
    :param keep_alive: how long Ollama keeps the model loaded after a request (``"5m"``, seconds,
        or -1 for ever).
    """

    port: int | None = field(default=11434)
    options: dict[str, Any] | None = field(default=None, validator=_check_options(OLLAMA_OPTIONS))
    keep_alive: str | int | None = field(default="5m")

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "options": dict(self.options or {}), "keep_alive": self.keep_alive}


#: Sampling options an OpenAI-compatible chat endpoint accepts.
OPENAI_CHAT_OPTIONS: Final[dict[str, type | tuple[type, ...]]] = {
    "temperature": _NUMBER, "top_p": _NUMBER, "max_tokens": int, "max_completion_tokens": int,
    "presence_penalty": _NUMBER, "frequency_penalty": _NUMBER, "seed": int, "stop": (str, list),
    "n": int, "logit_bias": dict, "response_format": dict, "reasoning_effort": str,
}


@define(kw_only=True)
class GenericLLM(Model):
    """A chat model behind an OpenAI-compatible API (OpenAI, vLLM, llama.cpp's server, LM Studio, ...).

    :param checkpoint: the model id the server knows (``"gpt-4o-mini"``, the GGUF alias, ...).
    :param options: default sampling options sent with every request, checked by name and type.
    """

    model_family: ClassVar[str] = "llm"

    options: dict[str, Any] | None = field(default=None, validator=_check_options(OPENAI_CHAT_OPTIONS))

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "options": dict(self.options or {})}


@define(kw_only=True)
class GenericMLLM(GenericLLM):
    """A multimodal (text + image) chat model behind an OpenAI-compatible API."""

    model_family: ClassVar[str] = "mllm"


@define(kw_only=True)
class GenericTTS(Model):
    """A speech synthesis model behind an OpenAI-compatible ``/v1/audio/speech`` endpoint.

    :param voice: the voice name the server offers.
    :param speed: speaking rate, 0.25 to 4.0.
    :param response_format: audio container the server returns (``"wav"`` is what robots play
        without a decoder).
    """

    model_family: ClassVar[str] = "tts"

    voice: str = field(default="alloy", validator=_non_empty_str)
    speed: float = field(default=1.0, validator=base_validators.in_range(0.25, 4.0))
    response_format: str = field(default="wav",
                                 validator=base_validators.in_(["wav", "mp3", "opus", "aac", "flac", "pcm"]))

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "voice": self.voice, "speed": self.speed,
                "response_format": self.response_format}


@define(kw_only=True)
class GenericSTT(Model):
    """A transcription model behind an OpenAI-compatible ``/v1/audio/transcriptions`` endpoint.

    :param language: ISO-639-1 language hint (None: the server detects it).
    :param temperature: sampling temperature, 0 to 1.
    """

    model_family: ClassVar[str] = "stt"

    language: str | None = field(default=None)
    temperature: float = field(default=0.0, validator=base_validators.in_range(0.0, 1.0))

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "language": self.language, "temperature": self.temperature}
