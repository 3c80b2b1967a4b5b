"""``TextToSpeech``: speaks text, sentence by sentence, as Audio on a topic and/or on a sound device.

Input is String (each message one utterance) or StreamingString (an LLM's answer as it is
generated). With ``stream`` on (the default), a stream is spoken sentence by sentence as the
sentences complete, so the robot starts talking before the LLM has finished; off, the whole text
is spoken once the stream's last chunk (``done``) arrives. The first clause of an utterance is
spoken on its own as soon as it is complete, when it has ``first_clause_words`` words or more
(:func:`~agents_core.engines.local_tts.split_speakable`): first audio then waits only for the
synthesis of that clause, not of the whole first sentence.

Each sentence is synthesized on the component's serial worker and published on the Audio outputs
as int16 chunks of ``chunk_ms``; with ``play_on_device`` it is also played on a sound device (the
``voice`` extra's ``sounddevice``; without it, or without a device, configure fails with a clear
error). One step speaks one sentence and queues the next, so the ``say(text)`` and
``stop_playback()`` actions, which run on the same worker, never wait behind a long answer.

A new utterance (a String, or the first chunk of a new stream) interrupts the one being spoken
when ``interrupt`` is on (the default), and queues after it otherwise; at most ``max_queue``
sentences wait (the oldest are dropped and counted in :attr:`TextToSpeech.dropped_sentences`).
Text longer than ``max_text_chars`` is refused with :class:`~agents_core.errors.AlgorithmFailure`
(health ALGORITHM_FAILURE); the next good text is spoken as usual.

The voice is the built-in :class:`~agents_core.engines.local_tts.LocalTTS` (sherpa-onnx, Piper "joe" by
default; ``enable_local_model``), or a remote ``GenericTTS`` / ``TransformersTTS`` through a model
client (its WAV answer is decoded; other containers are refused).
"""

from __future__ import annotations

import collections
import queue
import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..actions import component_action
from ..clients.model_base import ModelClient
from ..engines.audio import AudioInputError, float_to_int16, read_wav, to_mono_float
from ..engines.local_tts import split_speakable
from ..errors import AlgorithmFailure, ConfigError, WiringError
from ..messages import AudioMsg, StreamingStringMsg
from ..support.install_hint import install_hint
from ..supported_types import Audio, String, SupportedType
from ..topics import Topic
from .component_base import TriggerType
from .model_component import ModelComponent
from .text_to_speech_config import TextToSpeechConfig

__all__ = ["TextToSpeech"]


class _Player:
    """Plays float32 audio on a sound device from its own thread, so playing never blocks the worker."""

    def __init__(self, device: int | str | None) -> None:
        try:
            # Optional (the voice extra), and without type information.
            import sounddevice  # type: ignore[import-not-found,import-untyped,unused-ignore]  # noqa: PLC0415
        except (ImportError, OSError) as exc:  # OSError: the PortAudio library is missing
            raise ConfigError(f"play_on_device needs sounddevice and PortAudio: {install_hint('voice')} "
                              f"(or publish the Audio output only): {exc}") from exc
        try:
            sounddevice.query_devices(device, kind="output")
        except Exception as exc:  # sounddevice raises ValueError or PortAudioError
            raise ConfigError(f"play_on_device: no audio output device {device!r} here ({exc}); "
                              "set play_on_device=False to publish the Audio output only") from exc
        self._sd = sounddevice
        self._device = device
        self._queue: queue.Queue[tuple[npt.NDArray[np.float32], int] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="tts-playback", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            samples, rate = item
            self._sd.play(samples, rate, device=self._device)
            self._sd.wait()

    def play(self, samples: npt.NDArray[np.float32], rate: int) -> None:
        self._queue.put((samples, rate))

    def stop(self) -> None:
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        self._sd.stop()

    def close(self) -> None:
        self.stop()
        self._queue.put(None)
        self._thread.join(timeout=2.0)


class TextToSpeech(ModelComponent):
    """Speaks the text it receives (see the module docs).

    :param inputs: String and/or StreamingString topics.
    :param outputs: Audio topics (may be empty with ``config.play_on_device``).
    :param model_client: a client serving ``GenericTTS`` / ``TransformersTTS``; None with ``enable_local_model``.
    :param config: a :class:`~agents_core.config.TextToSpeechConfig`.
    :param trigger: default: the text inputs.
    """

    config_class = TextToSpeechConfig
    handled_outputs: Sequence[type[SupportedType]] = (Audio,)

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: TextToSpeechConfig | None = None,
        trigger: TriggerType | None = None,
        component_name: str = "text_to_speech",
        **kwargs: Any,
    ) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Optional": [Audio]}
        if trigger is None and inputs:
            trigger = list(inputs)
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config, trigger=trigger,
                         component_name=component_name, **kwargs)
        self.config: TextToSpeechConfig
        if not self.outputs and not self.config.play_on_device:
            raise WiringError(f"component {self.component_name!r}: give an Audio output or set "
                              "config.play_on_device=True, or the speech goes nowhere")
        self._lock = threading.Lock()
        self._texts: collections.deque[tuple[str, Any]] = collections.deque()  # (input name, value) arrivals
        self._partial: dict[str, str] = {}  # per input: the unfinished text of the stream in progress
        self._begun: set[str] = set()  # inputs whose utterance in progress has had a piece queued
        self._sentences: collections.deque[str] = collections.deque()
        self._step_queued = False
        self._player: _Player | None = None
        #: Sentences spoken, sentences dropped (queue full or interrupted), texts refused.
        self.sentences_spoken = 0
        self.dropped_sentences = 0
        self.refused_texts = 0

    @property
    def busy(self) -> bool:
        """Whether text is waiting, or a sentence is being synthesized."""
        with self._lock:
            waiting = bool(self._texts) or bool(self._sentences) or self._step_queued
        return waiting or self.worker_statistics().pending > 0

    # -- model and device ---------------------------------------------------------------------

    def _deploy_local_model(self) -> None:
        from ..engines.local_tts import LocalTTS  # noqa: PLC0415  (sherpa-onnx is optional)

        cfg = self.config
        self.local_model = LocalTTS(model_path=cfg.local_model_path, ncpu=cfg.ncpu_local_model,
                                    device=cfg.device_local_model, data_dir=cfg.data_dir,
                                    speaker_id=cfg.speaker_id, speed=cfg.speed)

    def custom_on_configure(self) -> None:
        if self.config.play_on_device and self._player is None:
            self._player = _Player(self.config.device)
        super().custom_on_configure()

    def custom_on_deactivate(self) -> None:
        self._clear()
        super().custom_on_deactivate()

    def custom_on_shutdown(self) -> None:
        if self._player is not None:
            self._player.close()
            self._player = None
        super().custom_on_shutdown()

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        self._call_inference({"query": "Ready.", **self.inference_params})

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        text = kwargs.get("text")
        return {"query": text, **self.inference_params} if text else None

    # -- arrivals (the transport's thread) ----------------------------------------------------

    def _make_topic_trigger(self, topic: Topic) -> Callable[[Any], None]:
        def take(value: Any) -> None:
            with self._lock:
                self._texts.append((topic.name, value))
            self._wake_worker()

        return take

    def _wake_worker(self) -> None:
        with self._lock:
            queue_step = not self._step_queued
            self._step_queued = True
        if queue_step:
            self._submit_step({})

    def _clear(self) -> None:
        with self._lock:
            self.dropped_sentences += len(self._sentences)
            self._sentences.clear()
            self._partial.clear()
            self._begun.clear()
        if self._player is not None:
            self._player.stop()

    # -- the worker's side --------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        with self._lock:
            arrivals = list(self._texts)
            self._texts.clear()
            self._step_queued = False
        error: AlgorithmFailure | None = None
        for name, value in arrivals:
            try:
                self._take_text(name, value)
            except AlgorithmFailure as exc:
                self.refused_texts += 1
                error = error or exc
        with self._lock:
            sentence = self._sentences.popleft() if self._sentences else None
            more = bool(self._sentences)
        if more:
            self._wake_worker()  # the next sentence gets its own step: actions can run in between
        if sentence is not None:
            self._speak(sentence)
        if error is not None:
            raise error

    def _take_text(self, name: str, value: Any) -> None:
        cfg = self.config
        if isinstance(value, StreamingStringMsg):
            text, done, new = value.data, value.done, name not in self._partial
        elif isinstance(value, str):
            text, done, new = value, True, True
        else:
            raise AlgorithmFailure(f"component {self.component_name!r}: cannot speak a {type(value).__name__}")
        if new and cfg.interrupt:
            self._clear()
        if new:
            self._begun.discard(name)
        pending = self._partial.pop(name, "") + text
        if len(pending) > cfg.max_text_chars:
            raise AlgorithmFailure(f"component {self.component_name!r}: {len(pending)} characters of text is more "
                                   f"than max_text_chars ({cfg.max_text_chars}); split it or raise the limit")
        if cfg.stream or done:
            sentences, rest = split_speakable(pending, first=name not in self._begun,
                                              min_clause_words=cfg.first_clause_words)
        else:
            sentences, rest = [], pending
        if done:
            sentences += [rest.strip()] if rest.strip() else []
            self._begun.discard(name)
        else:
            self._partial[name] = rest
            if sentences:
                self._begun.add(name)
        self._queue_sentences(sentences)

    def _queue_sentences(self, sentences: list[str]) -> None:
        with self._lock:
            for sentence in sentences:
                if len(self._sentences) >= self.config.max_queue:
                    self._sentences.popleft()
                    self.dropped_sentences += 1
                self._sentences.append(sentence)

    def _speak(self, sentence: str) -> None:
        self._logger.debug("speaking %r", sentence)
        result = self._call_inference(self._create_input(text=sentence) or {})
        samples, rate = self._to_samples(result)
        self.sentences_spoken += 1
        if self._player is not None:
            self._player.play(samples, rate)
        pcm = float_to_int16(samples)
        step = max(1, rate * self.config.chunk_ms // 1000)
        for pub in self.publishers_dict.values():
            for start in range(0, pcm.size, step):
                pub.publish(AudioMsg(data=pcm[start:start + step], sample_rate=rate))

    def _to_samples(self, result: Any) -> tuple[npt.NDArray[np.float32], int]:
        output = result.get("output")
        try:
            if isinstance(output, bytes | bytearray):
                data, rate, channels = read_wav(bytes(output))  # a remote server's WAV file
                return to_mono_float(data, channels), rate
            return to_mono_float(np.asarray(output)), int(result.get("sample_rate", 22_050))
        except (AudioInputError, EOFError, ValueError) as exc:
            raise AlgorithmFailure(f"component {self.component_name!r}: unusable audio from the voice "
                                   f"({type(output).__name__}): {exc}") from exc

    # -- actions ------------------------------------------------------------------------------

    @component_action(description={
        "description": "Say a sentence out loud.",
        "parameters": {"type": "object", "properties": {"text": {"type": "string", "description": "what to say"}},
                       "required": ["text"]},
    })
    def say(self, text: str) -> bool:
        """Speak ``text`` (interrupting or after what is being said, as ``config.interrupt`` says)."""
        if not isinstance(text, str) or not text.strip():
            raise AlgorithmFailure(f"component {self.component_name!r}: say() needs text, got {text!r}")
        with self._lock:
            self._texts.append(("__say__", text))
        self._wake_worker()
        return True

    @component_action(description={
        "description": "Stop speaking now and forget what was still to be said.",
        "parameters": {"type": "object", "properties": {}, "required": []},
    })
    def stop_playback(self) -> bool:
        """Drop the sentences waiting to be spoken and stop the sound device."""
        with self._lock:
            self._texts.clear()
        self._clear()
        return True
