"""``SpeechToTextConfig``: the settings of ``SpeechToText`` (:mod:`agents_core.components.speech_to_text`), beside it.

Public as ``agents_core.config.SpeechToTextConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from typing import Any

import attrs
from attrs import define, field

from .. import base_validators
from ..config import AT_CONFIGURE, ModelComponentConfig
from ..errors import ConfigError

__all__ = ["SpeechToTextConfig"]


@define(kw_only=True)
class SpeechToTextConfig(ModelComponentConfig):
    """Settings of :class:`~agents_core.components.SpeechToText`.

    :param enable_vad: cut the incoming audio stream into utterances with Silero VAD (each becomes
        one transcript); off: every Audio message is one utterance. None (default): on when a
        ``vad_model_path`` is given, else off (upstream's default).
    :param vad_threshold: speech probability above which audio counts as speech.
    :param min_silence_duration_ms: the silence that ends an utterance.
    :param min_speech_duration_ms: shorter bursts (a click, a cough) are not utterances.
    :param max_speech_duration_s: an utterance is cut (and transcribed) when it gets this long.
    :param vad_model_path: the ``silero_vad.onnx`` file (None: the one shipped by the PyPI package
        ``silero-vad``, installed with ``--no-deps``).
    :param enable_wakeword: transcribe only the utterance that follows a wake word (needs enable_vad).
    :param wakeword_model: a built-in microWakeWord model (``"hey_jarvis"``, ``"alexa"``,
        ``"okay_nabu"``, ``"hey_mycroft"``) or a microWakeWord ``.json`` file.
    :param wakeword_threshold: detection probability (None: the model's own tuned cutoff).
    :param wakeword_timeout_s: how long after the wake word the command may start.
    :param max_buffer_s: audio waiting for the worker (while a transcription runs) is kept up to
        this many seconds; beyond it the oldest chunks are dropped and counted.
    :param max_chunk_s: a longer single Audio message is refused with an error.
    :param language: the language hint of multilingual Whisper models.
    :param stream: the upstream name for partial results; none are produced yet: StreamingString
        outputs get each transcript as one final chunk (``done=True``) either way.
    :param enable_microphone: also listen to a local microphone (the ``voice`` extra's sounddevice;
        without it, or without an input device, configure fails with a clear error).
    :param device_audio: the microphone (device index or name; None: the default input device).
    :param ncpu_local_model: CPU threads of the local recognizer (default 2).
    """

    enable_vad: bool | None = field(default=None, metadata=AT_CONFIGURE)
    vad_threshold: float = field(default=0.5, validator=base_validators.in_range(0.01, 0.99), metadata=AT_CONFIGURE)
    min_silence_duration_ms: int = field(default=500, validator=base_validators.in_range(50, 10_000),
                                         metadata=AT_CONFIGURE)
    min_speech_duration_ms: int = field(default=250, validator=base_validators.in_range(10, 10_000),
                                        metadata=AT_CONFIGURE)
    max_speech_duration_s: float = field(default=20.0, validator=base_validators.in_range(1.0, 30.0),
                                         metadata=AT_CONFIGURE)
    vad_model_path: str | None = field(default=None, validator=base_validators.optional_str, metadata=AT_CONFIGURE)
    enable_wakeword: bool = field(default=False, metadata=AT_CONFIGURE)
    wakeword_model: str = field(default="hey_jarvis", validator=base_validators.non_empty_str, metadata=AT_CONFIGURE)
    wakeword_threshold: float | None = field(default=None, metadata=AT_CONFIGURE)
    wakeword_timeout_s: float = field(default=8.0, validator=base_validators.in_range(0.5, 600.0))
    max_buffer_s: float = field(default=30.0, validator=base_validators.in_range(1.0, 3600.0))
    max_chunk_s: float = field(default=10.0, validator=base_validators.in_range(0.01, 600.0))
    language: str = field(default="en", validator=base_validators.non_empty_str, metadata=AT_CONFIGURE)
    stream: bool = field(default=False)
    enable_microphone: bool = field(default=False, metadata=AT_CONFIGURE)
    device_audio: int | str | None = field(default=None, metadata=AT_CONFIGURE)
    ncpu_local_model: int = field(default=2, validator=base_validators.gt(0), metadata=AT_CONFIGURE)

    @wakeword_threshold.validator
    def _check_wakeword_threshold(self, attribute: attrs.Attribute[Any], value: Any) -> None:
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)
                                  or not 0.0 < value < 1.0):
            raise ConfigError(f"SpeechToTextConfig.wakeword_threshold must be None or in (0, 1), got {value!r}")

    def __attrs_post_init__(self) -> None:
        if self.enable_vad is None:
            self.enable_vad = self.vad_model_path is not None
        if self.enable_wakeword and not self.enable_vad:
            raise ConfigError("SpeechToTextConfig: enable_wakeword needs enable_vad (the command after the wake "
                              "word is the next utterance)")

    def _get_inference_params(self) -> dict[str, Any]:
        return {"language": self.language}

