"""``SpeechToText``: transcribes a stream of audio chunks, one String per utterance.

Audio comes as a stream of short Audio messages (10 to 100 ms is usual) from a microphone node or
any other component, or from a local microphone (``enable_microphone``, the ``voice`` extra):
8 to 48 kHz (4 to 384 kHz accepted), int16 or float32, mono or interleaved multi-channel. Each
chunk is down-mixed and resampled to the 16 kHz mono the models take
(:mod:`agents_core.engines.audio`); the resampler keeps its state across chunks.

With ``enable_vad`` (on when a ``vad_model_path`` is given), Silero VAD cuts the stream into
utterances (speech start -> ``min_silence_duration_ms`` of silence) and each utterance becomes one
transcript. With
``enable_wakeword`` as well, only the utterance after the wake word (microWakeWord, e.g.
``"hey_jarvis"``) is transcribed; a wake word said in one breath with the command counts too.
Without VAD every Audio message is one utterance.

Threading: the transport's thread only appends the chunk to a bounded buffer (``max_buffer_s`` of
audio; beyond it the oldest chunks are dropped and counted in :attr:`SpeechToText.dropped_chunks`)
and, when none is pending, queues one step on the component's serial worker. That step drains
the buffer, runs the VAD and the recognizer, and publishes; audio arriving meanwhile waits in the
buffer for the next step, so a slow transcription never blocks the transport and never loses
the middle of an utterance.

A chunk that cannot be used (NaN or infinite samples, a sample rate outside 4..384 kHz, a single
chunk longer than ``max_chunk_s``) fails the step with :class:`~agents_core.engines.audio.AudioInputError`
(health ALGORITHM_FAILURE) after the good audio around it is processed; the next good chunk brings
the health back. Empty chunks are skipped.

The recognizer is the built-in :class:`~agents_core.engines.local_stt.LocalSTT` (sherpa-onnx, Whisper
tiny.en by default; ``enable_local_model``), or a remote ``GenericSTT`` / ``Whisper`` model through a
model client (the utterance is sent as 16 kHz audio).
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..clients.model_base import ModelClient
from ..engines.audio import AudioInputError, StreamResampler, check_rate, to_mono_float
from ..errors import AlgorithmFailure, ConfigError
from ..messages import AudioMsg, StreamingStringMsg
from ..support.install_hint import install_hint
from ..supported_types import Audio, StreamingString, String, SupportedType
from ..topics import Topic
from .component_base import TriggerType
from .model_component import ModelComponent
from .speech_to_text_config import SpeechToTextConfig

__all__ = ["SpeechToText"]

_RATE = 16_000
# A wake word said in one breath with the command: the rest of the utterance is the command
# when at least this much audio follows the detection (s).
_MIN_COMMAND_AFTER_WAKE_S = 1.0


class SpeechToText(ModelComponent):
    """Hears speech and publishes what was said (see the module docs).

    :param inputs: one or more Audio topics (chunks of a stream).
    :param outputs: String topics (one message per utterance), and/or StreamingString topics.
    :param model_client: a client serving ``GenericSTT`` / ``Whisper``; None with ``config.enable_local_model``.
    :param config: a :class:`~agents_core.config.SpeechToTextConfig`.
    :param trigger: default: the Audio inputs (every chunk is taken in as it arrives).
    """

    config_class = SpeechToTextConfig
    handled_outputs: Sequence[type[SupportedType]] = (String,)

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: SpeechToTextConfig | None = None,
        trigger: TriggerType | None = None,
        component_name: str = "speech_to_text",
        **kwargs: Any,
    ) -> None:
        microphone = bool(config is not None and config.enable_microphone)
        self.allowed_inputs = {"Optional": [Audio]} if microphone else {"Required": [Audio]}
        self.allowed_outputs = {"Required": [String]}
        if trigger is None:
            # With only a microphone there is no input to fire steps: a slow timer keeps the
            # component's usual shape (its steps find the buffer empty; the microphone wakes the worker).
            trigger = list(inputs) if inputs else 1.0
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config, trigger=trigger,
                         component_name=component_name, **kwargs)
        self.config: SpeechToTextConfig
        self._lock = threading.Lock()
        # Chunks waiting for the worker: (topic name, AudioMsg) or (None, error text), in arrival order.
        self._pending: collections.deque[tuple[str | None, Any]] = collections.deque()
        self._pending_s = 0.0
        self._step_queued = False
        self._resamplers: dict[str, StreamResampler] = {}
        self._segmenter: Any = None
        self._wakeword: Any = None
        self._position = 0  # 16 kHz samples of the stream fed to the VAD so far
        self._wake_at: int | None = None
        self._microphone: Any = None
        #: Chunks (and their seconds of audio) dropped because the buffer was full.
        self.dropped_chunks = 0
        self.dropped_seconds = 0.0
        #: Chunks refused as unusable, and utterances heard / transcribed / ignored (no wake word).
        self.refused_chunks = 0
        self.utterances = 0
        self.transcripts = 0
        self.ignored_utterances = 0

    @property
    def busy(self) -> bool:
        """Whether audio is waiting for the worker or being processed now."""
        with self._lock:
            waiting = bool(self._pending) or self._step_queued
        return waiting or self.worker_statistics().pending > 0

    # -- model --------------------------------------------------------------------------------

    def _deploy_local_model(self) -> None:
        from ..engines.local_stt import LocalSTT  # noqa: PLC0415  (sherpa-onnx is optional)

        cfg = self.config
        self.local_model = LocalSTT(model_path=cfg.local_model_path, ncpu=cfg.ncpu_local_model,
                                    device=cfg.device_local_model, language=cfg.language)

    def custom_on_configure(self) -> None:
        cfg = self.config
        if cfg.enable_vad:
            from ..engines.local_stt import SpeechSegmenter, WakeWordDetector  # noqa: PLC0415

            self._segmenter = SpeechSegmenter(cfg.vad_model_path, threshold=cfg.vad_threshold,
                                              min_silence_ms=cfg.min_silence_duration_ms,
                                              min_speech_ms=cfg.min_speech_duration_ms,
                                              max_speech_s=cfg.max_speech_duration_s)
            if cfg.enable_wakeword:
                self._wakeword = WakeWordDetector(cfg.wakeword_model, cfg.wakeword_threshold)
        if cfg.enable_microphone:
            self._check_microphone()
        super().custom_on_configure()

    def _check_microphone(self) -> None:
        try:
            # Optional (the voice extra), and without type information.
            import sounddevice  # type: ignore[import-not-found,import-untyped,unused-ignore]  # noqa: PLC0415
        except (ImportError, OSError) as exc:  # OSError: the PortAudio library is missing
            raise ConfigError(f"enable_microphone needs sounddevice and PortAudio: {install_hint('voice')} "
                              f"(or publish Audio chunks from a microphone node): {exc}") from exc
        try:
            info = sounddevice.query_devices(self.config.device_audio, kind="input")
        except Exception as exc:  # sounddevice raises ValueError or PortAudioError
            raise ConfigError(f"enable_microphone: no audio input device {self.config.device_audio!r} here "
                              f"({exc})") from exc
        self._sd, self._mic_rate = sounddevice, int(info["default_samplerate"])

    def custom_on_activate(self) -> None:
        self._reset_stream()
        if self.config.enable_microphone:
            mic = Topic("microphone", "Audio")

            def on_block(block: Any, frames: int, when: Any, status: Any) -> None:
                # On PortAudio's thread: copy the block (its buffer is reused) and hand it over.
                self._take_chunk(mic, AudioMsg(data=block[:, 0].copy(), sample_rate=self._mic_rate))

            self._microphone = self._sd.InputStream(device=self.config.device_audio, channels=1, dtype="int16",
                                                    samplerate=self._mic_rate, blocksize=self._mic_rate // 50,
                                                    callback=on_block)
            self._microphone.start()
        super().custom_on_activate()

    def custom_on_deactivate(self) -> None:
        if self._microphone is not None:
            self._microphone.close()
            self._microphone = None
        super().custom_on_deactivate()

    def custom_on_shutdown(self) -> None:
        if self._wakeword is not None:
            self._wakeword.close()
            self._wakeword = None
        super().custom_on_shutdown()

    def _reset_stream(self) -> None:
        with self._lock:
            self._pending.clear()
            self._pending_s = 0.0
        self._resamplers.clear()
        self._position = 0
        self._wake_at = None
        if self._segmenter is not None:
            self._segmenter.reset()
        if self._wakeword is not None:
            self._wakeword.reset()

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        self._call_inference({"query": np.zeros(_RATE // 2, np.float32), "sample_rate": _RATE,
                              **self.inference_params})

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        samples = kwargs.get("samples")
        if samples is None or samples.size == 0:
            return None
        return {"query": samples, "sample_rate": _RATE, **self.inference_params}

    # -- the transport's side: buffer and wake the worker -------------------------------------

    def _make_topic_trigger(self, topic: Topic) -> Callable[[Any], None]:
        def take(value: Any) -> None:
            self._take_chunk(topic, value)

        return take

    def _take_chunk(self, topic: Topic, value: Any) -> None:
        """On the transport's thread: keep the chunk (bounded) and queue a step unless one is pending."""
        cfg = self.config
        with self._lock:
            if not isinstance(value, AudioMsg):
                self._pending.append((None, f"expected an AudioMsg, got {type(value).__name__}"))
            elif value.duration > cfg.max_chunk_s:
                self.refused_chunks += 1
                self._pending.append((None, f"a {value.duration:.1f} s chunk is longer than max_chunk_s "
                                            f"({cfg.max_chunk_s} s); send the stream in short chunks"))
            else:
                self._pending.append((topic.name, value))
                self._pending_s += value.duration
                while self._pending_s > cfg.max_buffer_s:
                    # Drop oldest: the newest audio is what the speaker is saying now.
                    name, old = self._pending.popleft()
                    if name is not None:
                        self._pending_s -= old.duration
                        self.dropped_chunks += 1
                        self.dropped_seconds += old.duration
            queue_step = not self._step_queued
            self._step_queued = True
        if queue_step:
            self._submit_step({"topic": topic})

    def _drain(self) -> list[tuple[str | None, Any]]:
        with self._lock:
            items = list(self._pending)
            self._pending.clear()
            self._pending_s = 0.0
            self._step_queued = False
        return items

    # -- the worker's side --------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        first_error: AlgorithmFailure | None = None
        for name, value in self._drain():
            try:
                if name is None:
                    raise AudioInputError(value)
                self._process_chunk(name, value)
            except AlgorithmFailure as exc:
                # Keep going: the good audio after a bad chunk is processed in this very step.
                if name is not None:
                    self.refused_chunks += 1
                first_error = first_error or exc
        if first_error is not None:
            raise AudioInputError(f"component {self.component_name!r}: {first_error}") from first_error

    def _process_chunk(self, topic_name: str, msg: AudioMsg) -> None:
        if msg.data.size == 0:
            return
        rate = check_rate(msg.sample_rate)
        samples = to_mono_float(msg.data, msg.channels)
        if self._segmenter is None:
            self._transcribe_and_publish(StreamResampler(rate)(samples))
            return
        resampler = self._resamplers.get(topic_name)
        if resampler is None or resampler.source_rate != rate:
            resampler = self._resamplers[topic_name] = StreamResampler(rate)
        samples = resampler(samples)
        if samples.size == 0:
            return
        if self._wakeword is not None:
            detected = self._wakeword.accept(samples)
            if detected is not None:
                self._logger.info("wake word %r heard", self._wakeword.name)
                self._wake_at = detected
        self._position += samples.size
        for start, utterance in self._segmenter.accept(samples):
            self._on_utterance(start, utterance)

    def _on_utterance(self, start: int, utterance: npt.NDArray[np.float32]) -> None:
        self.utterances += 1
        if self._wakeword is not None:
            wake = self._wake_at
            if wake is None or (start >= wake and start - wake > self.config.wakeword_timeout_s * _RATE):
                self.ignored_utterances += 1
                return
            if start < wake:
                # The wake word is in this utterance: what follows the detection may be the command.
                tail = utterance[wake - start:]
                if tail.size < _MIN_COMMAND_AFTER_WAKE_S * _RATE:
                    # The wake word alone: the next utterance is the command (counted from its end).
                    self._wake_at = max(wake, start + utterance.size)
                    self.ignored_utterances += 1
                    return
                utterance = tail
            self._wake_at = None
        self._transcribe_and_publish(utterance)

    def _transcribe_and_publish(self, samples: npt.NDArray[np.float32]) -> None:
        inference_input = self._create_input(samples=samples)
        if inference_input is None:
            return
        result = self._call_inference(inference_input)
        text = result.get("output")
        if not isinstance(text, str):
            raise AlgorithmFailure(f"component {self.component_name!r}: the speech model answered "
                                   f"{type(text).__name__}, not text")
        text = text.strip()
        if not text:
            return
        self.transcripts += 1
        self._logger.debug("heard %r", text)
        for name, pub in self.publishers_dict.items():
            if issubclass(self._topic(name).msg_type, StreamingString):
                pub.publish(StreamingStringMsg(data=text, stream=False, done=True))
            else:
                pub.publish(text)
