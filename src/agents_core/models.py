"""Model descriptions: what a model client should load on its serving platform.

A model is attrs data (``@define(kw_only=True)``) holding a name, a checkpoint and the
platform-specific options; :meth:`Model._get_init_params` is the dict sent to the platform when
the client initializes. Model classes register themselves by class name, so a serialized
client can say which kind of model it serves.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any, ClassVar, Final

from attrs import define, field

from . import base_validators
from .config import BaseAttrs
from .errors import ConfigError
from .support.registry import Registry

__all__ = [
    "LLM",
    "GenericLLM",
    "GenericMLLM",
    "GenericSTT",
    "GenericTTS",
    "LeRobotPolicy",
    "Model",
    "OllamaModel",
    "RoboBrain2",
    "SpeechT5",
    "TransformersLLM",
    "TransformersMLLM",
    "TransformersTTS",
    "VisionModel",
    "Whisper",
    "model_types",
]

# Keyed by class name, as serialized clients name their model; a class defined again under a name
# (a notebook re-run, attrs re-creating a slotted class) replaces the previous one.
_model_types: Registry[type[Model]] = Registry("model class", hint="import the module that defines it first")


def model_types() -> dict[str, type[Model]]:
    """Every model class defined so far, by class name."""
    return _model_types.snapshot()


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
    #: What the model does, which decides the requests a client sends for it: ``"chat"`` (the
    #: default), ``"text_to_speech"``, ``"speech_to_text"``, ``"detection"`` or ``"policy"``. Each
    #: client maps the tasks it serves to its handlers; declared once per model class.
    task: ClassVar[str] = "chat"

    name: str = field(validator=_non_empty_str)
    checkpoint: str = field(validator=_non_empty_str)
    init_timeout: int | None = field(default=None, validator=base_validators.gt(0))

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # attrs re-creates slotted classes; the last registration is the final class.
        _model_types.register(cls.__name__, cls, replace=True)

    def _get_init_params(self) -> dict[str, Any]:
        """The parameters the serving platform needs to load this model."""
        return {"checkpoint": self.checkpoint}


_model_types.register("Model", Model, replace=True)


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
    task: ClassVar[str] = "text_to_speech"

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
    task: ClassVar[str] = "speech_to_text"

    language: str | None = field(default=None)
    temperature: float = field(default=0.0, validator=base_validators.in_range(0.0, 1.0))

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "language": self.language, "temperature": self.temperature}


# -- models served by RoboML ------------------------------------------------------------------
#
# The init parameters below are the keyword arguments of each RoboML model's ``_initialize``
# in RoboML 0.6.1 (roboml/models/*.py). RoboML validates them with pydantic's ``validate_call``,
# which rejects unknown keywords, so a model sends exactly those names and nothing else.

#: Hubs RoboML 0.6.1 can download checkpoints from (None: its ROBOML_SOURCE variable, else huggingface).
ROBOML_SOURCES: Final[tuple[str | None, ...]] = ("huggingface", "modelscope", None)

#: The ``compute_type`` values faster-whisper (RoboML's Whisper backend) accepts.
WHISPER_COMPUTE_TYPES: Final[tuple[str, ...]] = (
    "default", "auto", "int8", "int8_float32", "int8_float16", "int8_bfloat16", "int16", "float16", "bfloat16",
    "float32",
)

#: LeRobot policy architectures the LeRobot policy server can load.
LEROBOT_POLICY_TYPES: Final[tuple[str, ...]] = ("smolvla", "diffusion", "act", "pi0", "pi05")


def _optional_str(instance: Any, attribute: Any, value: Any) -> None:
    if value is not None and (not isinstance(value, str) or not value.strip()):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a non-empty str or None, got {value!r}")


def _bool(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, bool):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be True or False, got {value!r}")


def _int(instance: Any, attribute: Any, value: Any) -> None:
    # Checked before the range validators so that 2.5 or True is named as the wrong type.
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be an int, got {value!r}")


def _with_source(params: dict[str, Any], source: str | None) -> dict[str, Any]:
    # ``source`` is only sent when chosen: RoboML versions before it existed reject the keyword.
    if source is not None:
        params["source"] = source
    return params


@define(kw_only=True)
class TransformersLLM(LLM):
    """A HuggingFace causal LM served by RoboML (its ``TransformersLLM`` node).

    :param checkpoint: hub id of the model (default ``"Qwen/Qwen3-0.6B"``, RoboML's own default).
    :param quantization: ``"4bit"``, ``"8bit"`` or None (full precision), applied by RoboML on load.
    :param system_prompt: a system prompt RoboML puts before every conversation. None (the default)
        sends none, because components already send their system message in the query.
    :param source: hub to download from: ``"huggingface"``, ``"modelscope"`` or None (RoboML decides).
    """

    checkpoint: str = field(default="Qwen/Qwen3-0.6B", validator=_non_empty_str)
    system_prompt: str | None = field(default=None, validator=_optional_str)
    source: str | None = field(default=None, validator=base_validators.in_(ROBOML_SOURCES))

    def _get_init_params(self) -> dict[str, Any]:
        return _with_source({"checkpoint": self.checkpoint, "quantization": self.quantization,
                             "system_prompt": self.system_prompt}, self.source)


@define(kw_only=True)
class TransformersMLLM(TransformersLLM):
    """A HuggingFace image-text-to-text model served by RoboML (its ``TransformersMLLM`` node).

    Same parameters as :class:`TransformersLLM`; the default checkpoint is ``"Qwen/Qwen2.5-VL-3B-Instruct"``.
    """

    model_family: ClassVar[str] = "mllm"

    checkpoint: str = field(default="Qwen/Qwen2.5-VL-3B-Instruct", validator=_non_empty_str)


@define(kw_only=True)
class RoboBrain2(LLM):
    """BAAI's RoboBrain 2.0 / 2.5 planning model served by RoboML (its ``RoboBrain2`` node).

    It answers general questions about an image and the tasks ``pointing``, ``affordance``,
    ``trajectory`` and ``grounding`` (chosen per inference with a ``task`` key).

    :param checkpoint: hub id (default ``"BAAI/RoboBrain2.0-3B"``).
    :param quantization: must stay None: RoboML loads RoboBrain in its own dtype and its node takes
        no quantization parameter.
    :param source: hub to download from (see :class:`TransformersLLM`).
    """

    model_family: ClassVar[str] = "mllm"

    checkpoint: str = field(default="BAAI/RoboBrain2.0-3B", validator=_non_empty_str)
    quantization: str | None = field(default=None, validator=base_validators.in_([None]))
    source: str | None = field(default=None, validator=base_validators.in_(ROBOML_SOURCES))

    def _get_init_params(self) -> dict[str, Any]:
        return _with_source({"checkpoint": self.checkpoint}, self.source)


@define(kw_only=True)
class Whisper(Model):
    """OpenAI's Whisper speech recognition served by RoboML through faster-whisper.

    :param checkpoint: a size alias (``"tiny.en"``, ``"small.en"`` (default), ``"large-v3"``,
        ``"turbo"``, ...), a hub id or a path on the server.
    :param compute_type: faster-whisper's compute type (``"int8"`` by default; see
        :data:`WHISPER_COMPUTE_TYPES`).
    :param source: hub to download from (see :class:`TransformersLLM`).
    """

    model_family: ClassVar[str] = "stt"
    task: ClassVar[str] = "speech_to_text"

    checkpoint: str = field(default="small.en", validator=_non_empty_str)
    compute_type: str = field(default="int8", validator=base_validators.in_(WHISPER_COMPUTE_TYPES))
    source: str | None = field(default=None, validator=base_validators.in_(ROBOML_SOURCES))

    def _get_init_params(self) -> dict[str, Any]:
        return _with_source({"checkpoint": self.checkpoint, "compute_type": self.compute_type}, self.source)


@define(kw_only=True)
class TransformersTTS(Model):
    """A HuggingFace text-to-speech model served by RoboML (Bark, VITS, SpeechT5, SeamlessM4T, ...).

    :param checkpoint: hub id (default ``"suno/bark-small"``, RoboML's own default).
    :param voice: voice preset or speaker id; its meaning is model specific (Bark:
        ``"v2/en_speaker_6"``, the default). None: the model's default voice.
    :param vocoder_checkpoint: vocoder for spectrogram models such as SpeechT5 (None: RoboML uses
        ``"microsoft/speecht5_hifigan"`` when one is needed).
    :param source: hub to download from (see :class:`TransformersLLM`).
    """

    model_family: ClassVar[str] = "tts"
    task: ClassVar[str] = "text_to_speech"

    checkpoint: str = field(default="suno/bark-small", validator=_non_empty_str)
    voice: str | None = field(default="v2/en_speaker_6", validator=_optional_str)
    vocoder_checkpoint: str | None = field(default=None, validator=_optional_str)
    source: str | None = field(default=None, validator=base_validators.in_(ROBOML_SOURCES))

    def _get_init_params(self) -> dict[str, Any]:
        return _with_source({"checkpoint": self.checkpoint, "voice": self.voice,
                             "vocoder_checkpoint": self.vocoder_checkpoint}, self.source)


#: SpeechT5's CMU ARCTIC speakers, the voices upstream's ``SpeechT5`` model offers.
SPEECHT5_VOICES: Final[tuple[str, ...]] = ("awb", "bdl", "clb", "jmk", "ksp", "rms", "slt")


@define(kw_only=True)
class SpeechT5(TransformersTTS):
    """Microsoft's SpeechT5 text-to-speech model, under upstream 0.6.0's name (RoboML serves it as a
    :class:`TransformersTTS`, with the HiFi-GAN vocoder it needs).

    :param checkpoint: hub id (default ``"microsoft/speecht5_tts"``).
    :param voice: one of the CMU ARCTIC speakers ``"awb"``, ``"bdl"``, ``"clb"`` (default),
        ``"jmk"``, ``"ksp"``, ``"rms"``, ``"slt"``.
    """

    checkpoint: str = field(default="microsoft/speecht5_tts", validator=_non_empty_str)
    voice: str | None = field(default="clb", validator=base_validators.in_(SPEECHT5_VOICES))


@define(kw_only=True)
class VisionModel(Model):
    """A HuggingFace object detector served by RoboML, with optional ByteTrack tracking.

    :param checkpoint: hub id of an object detection model (default
        ``"PekingU/rtdetr_r50vd_coco_o365"``; DETR, RT-DETR, YOLOS, ... work too).
    :param setup_trackers: create trackers on the server; inferences that name
        ``labels_to_track`` then also get tracked boxes, points and ids.
    :param num_trackers: trackers to create, one per image stream the component sends.
    :param tracking_distance_threshold: minimum IoU, in percent (1 to 100), for the tracker to
        associate a detection with a track (default 30).
    :param source: hub to download from (see :class:`TransformersLLM`).
    """

    model_family: ClassVar[str] = "vision"
    task: ClassVar[str] = "detection"

    checkpoint: str = field(default="PekingU/rtdetr_r50vd_coco_o365", validator=_non_empty_str)
    setup_trackers: bool = field(default=False, validator=_bool)
    num_trackers: int = field(default=1, validator=[_int, base_validators.ge(1)])
    tracking_distance_threshold: int = field(default=30, validator=[_int, base_validators.in_range(1, 100)])
    source: str | None = field(default=None, validator=base_validators.in_(ROBOML_SOURCES))

    def _get_init_params(self) -> dict[str, Any]:
        return _with_source({"checkpoint": self.checkpoint, "setup_trackers": self.setup_trackers,
                             "num_trackers": self.num_trackers,
                             "tracking_distance_threshold": self.tracking_distance_threshold}, self.source)


def _feature_dict(instance: Any, attribute: Any, value: Any) -> None:
    if value is None and attribute.default is None:
        return
    where = f"{type(instance).__name__}.{attribute.name}"
    if not isinstance(value, dict) or not all(isinstance(k, str) and isinstance(v, dict) for k, v in value.items()):
        raise ConfigError(f"{where} must map feature names (str) to their spec dicts, got {value!r:.200}")


@define(kw_only=True)
class LeRobotPolicy(Model):
    """A LeRobot vision-language-action policy (served by LeRobot's policy server, not by RoboML).

    :param checkpoint: hub id or path of the pretrained policy (default ``"lerobot/smolvla_base"``).
    :param policy_type: the policy architecture, one of :data:`LEROBOT_POLICY_TYPES`.
    :param actions_per_chunk: actions predicted per inference chunk (used by chunking policies
        such as SmolVLA and pi0).
    :param policy_device: where the server runs the policy: ``"cuda"`` or ``"cpu"``.
    :param dataset_info_file: path of the training dataset's ``info.json``; read by
        :meth:`load_dataset_info` (never during construction) to fill ``features`` and ``actions``.
    :param features: the observation features the policy expects, by name (``"observation.state"``,
        ``"observation.images.front"``, ...), each a LeRobot feature spec (``dtype``, ``shape``, ``names``).
    :param actions: the action features, by name (normally just ``"action"``), or None when not known yet.
    """

    model_family: ClassVar[str] = "vla"
    task: ClassVar[str] = "policy"

    checkpoint: str = field(default="lerobot/smolvla_base", validator=_non_empty_str)
    policy_type: str = field(default="smolvla", validator=base_validators.in_(LEROBOT_POLICY_TYPES))
    actions_per_chunk: int = field(default=50, validator=[_int, base_validators.ge(1)])
    policy_device: str = field(default="cuda", validator=base_validators.in_(["cuda", "cpu"]))
    dataset_info_file: str | None = field(default=None, validator=_optional_str)
    features: dict[str, Any] = field(factory=dict, validator=_feature_dict)
    actions: dict[str, Any] | None = field(default=None, validator=_feature_dict)

    def load_dataset_info(self, info: dict[str, Any] | None = None) -> None:
        """Fill ``features`` (``observation.*``) and ``actions`` (``action*``) from a dataset's info.

        :param info: the parsed ``info.json``; None reads ``dataset_info_file`` (a local path).
        """
        if info is None:
            if self.dataset_info_file is None:
                raise ConfigError("LeRobotPolicy.load_dataset_info needs info or dataset_info_file")
            try:
                info = json.loads(Path(self.dataset_info_file).read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise ConfigError(f"LeRobotPolicy.dataset_info_file {self.dataset_info_file!r}: {exc}") from exc
        specs = info.get("features") if isinstance(info, dict) else None
        if not isinstance(specs, dict):
            raise ConfigError("LeRobotPolicy: a dataset info must hold a 'features' dict")
        self.features = {k: dict(v) for k, v in specs.items() if k.startswith("observation.")}
        self.actions = {k: dict(v) for k, v in specs.items() if k == "action" or k.startswith("action.")}

    def _get_init_params(self) -> dict[str, Any]:
        # The action spec stays with the component (it maps actions onto joints); the policy
        # server needs the observation features only.
        return {"checkpoint": self.checkpoint, "policy_type": self.policy_type,
                "features": copy.deepcopy(self.features), "actions_per_chunk": self.actions_per_chunk,
                "device": self.policy_device}
