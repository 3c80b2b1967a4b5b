"""Built-in offline speech recognition on sherpa-onnx: :class:`LocalSTT`, :class:`SpeechSegmenter`
(Silero voice activity detection) and :class:`WakeWordDetector` (microWakeWord).

:class:`LocalSTT` is a callable taking ``{"query": mono float32 samples, "sample_rate": 16000}``
and returning ``{"output": text}``: the result format of the remote transcription clients, so the
:class:`~agents_core.components.SpeechToText` component reads local and remote answers alike.

``model_path`` is a directory of a sherpa-onnx offline model, recognised by its files:

==============  =====================================================================
family          files in the directory
==============  =====================================================================
Whisper         ``*encoder*.onnx``, ``*decoder*.onnx``, ``*tokens.txt``
Moonshine       ``preprocess.onnx``, ``encode*.onnx``, ``uncached_decode*.onnx``,
                ``cached_decode*.onnx``, ``tokens.txt``
transducer      ``encoder*.onnx``, ``decoder*.onnx``, ``joiner*.onnx``, ``tokens.txt`` (Zipformer, ...)
SenseVoice /    ``model*.onnx`` + ``tokens.txt`` (SenseVoice when the name says so, else a
Paraformer      Paraformer)
==============  =====================================================================

When several files match (``int8`` and ``fp32`` exports side by side), the int8 one is used. A hub
id (``owner/repo``) is downloaded whole with ``huggingface-hub``. The default is Whisper tiny.en
(:data:`DEFAULT_STT_REPO`).
"""

from __future__ import annotations

import importlib.util
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError, InferenceError
from ..support.console import say
from ..support.install_hint import install_hint
from .audio import float_to_int16, read_wav, to_mono_float
from .device import resolve_device
from .model_files import import_hub, looks_like_hub_id

__all__ = ["DEFAULT_STT_REPO", "MODEL_RATE", "LocalSTT", "SpeechSegmenter", "WakeWordDetector",
           "default_vad_path", "import_sherpa_onnx"]

_logger = logging.getLogger("agents_core.engines.local_stt")

#: The default recognizer: Whisper tiny.en in the sherpa-onnx layout, from the hub.
DEFAULT_STT_REPO = "csukuangfj/sherpa-onnx-whisper-tiny.en"
#: The rate every model here takes (Hz).
MODEL_RATE = 16_000
#: The longest utterance given to the recognizer (s): Whisper sees 30 s windows, and longer audio
#: would only make one step block the worker for long.
MAX_UTTERANCE_SECONDS = 30.0
#: Shorter utterances are padded with silence to this length: sherpa-onnx's Whisper crashes the
#: process (SIGSEGV, 2.0.1) on a few dozen samples, which a VAD can cut at the end of a stream.
MIN_UTTERANCE_SECONDS = 0.1


def import_sherpa_onnx() -> Any:
    """The ``sherpa_onnx`` module, or a ConfigError saying which extra installs it."""
    try:
        import sherpa_onnx  # noqa: PLC0415  (optional: the local extra)
    except ImportError as exc:
        raise ConfigError(f"the built-in speech models need sherpa-onnx: {install_hint('local')}") from exc
    return sherpa_onnx


def _pick(directory: Path, *patterns: str) -> Path | None:
    """The file of ``directory`` matching the first pattern that matches, preferring int8 exports."""
    for pattern in patterns:
        found = sorted(directory.glob(pattern))
        if found:
            int8 = [p for p in found if "int8" in p.name]
            return (int8 or found)[0]
    return None


def _model_dir(path_or_id: str, what: str) -> Path:
    local = Path(path_or_id).expanduser()
    if local.is_dir():
        return local
    if local.is_file():
        return local.parent
    if not looks_like_hub_id(path_or_id):
        raise ConfigError(f"{what}: no such directory {str(local)!r}")
    huggingface_hub, offline = import_hub(what, path_or_id, "local_model_path to a local directory")
    if offline is None:
        say(f"agents: {what}: fetching the hub repository {path_or_id} (cached after the first time)")
    try:
        # Only the int8 exports and the token table: the fp32 files of these repositories are large.
        return Path(huggingface_hub.snapshot_download(path_or_id, allow_patterns=["*int8*.onnx", "*tokens.txt"],
                                                      local_files_only=offline is not None))
    except Exception as exc:
        if offline is not None:
            raise ConfigError(f"{what}: the model hub cannot be used ({offline}) and {path_or_id!r} is not in the "
                              "local cache: set local_model_path to a local directory, or download it once while "
                              "online") from exc
        raise ConfigError(f"{what}: cannot download hub repository {path_or_id!r} (offline?): set "
                          f"local_model_path to a local directory instead; cause: {type(exc).__name__}: {exc}") from exc


class LocalSTT:
    """An offline sherpa-onnx recognizer (see the module docs for the model families).

    :param model_path: a model directory or hub id (None: :data:`DEFAULT_STT_REPO`).
    :param device: ``"auto"``, ``"cuda"`` (a CUDA build of sherpa-onnx; else the CPU, with a warning) or
        ``"cpu"`` (see :mod:`agents_core.engines.device`).
    :param ncpu: CPU threads.
    :param language: the language hint of multilingual Whisper models (``"en"``).
    """

    def __init__(self, model_path: str | None = None, device: str = "auto", ncpu: int = 2,
                 language: str = "en") -> None:
        so = import_sherpa_onnx()
        what = "speech-to-text local model"
        device = resolve_device(device, "sherpa_onnx", so, "LocalSTT")
        self.device = device
        directory = _model_dir(model_path or DEFAULT_STT_REPO, what)
        common: dict[str, Any] = {"num_threads": ncpu, "provider": device}
        tokens = _pick(directory, "*tokens.txt")
        if tokens is None:
            raise ConfigError(f"{what}: {directory} has no tokens.txt; is it a sherpa-onnx model directory?")
        preprocess = _pick(directory, "preprocess*.onnx")
        joiner = _pick(directory, "joiner*.onnx", "*joiner*.onnx")
        encoder = _pick(directory, "encoder*.onnx", "*encoder*.onnx")
        decoder = _pick(directory, "decoder*.onnx", "*decoder*.onnx")
        single = _pick(directory, "model*.onnx")
        try:
            if preprocess is not None:
                self.family = "moonshine"
                self._recognizer = so.OfflineRecognizer.from_moonshine(
                    preprocessor=str(preprocess), encoder=str(_pick(directory, "encode*.onnx")),
                    uncached_decoder=str(_pick(directory, "uncached_decode*.onnx")),
                    cached_decoder=str(_pick(directory, "cached_decode*.onnx")), tokens=str(tokens), **common)
            elif joiner is not None and encoder is not None and decoder is not None:
                self.family = "transducer"
                self._recognizer = so.OfflineRecognizer.from_transducer(
                    encoder=str(encoder), decoder=str(decoder), joiner=str(joiner), tokens=str(tokens), **common)
            elif encoder is not None and decoder is not None:
                self.family = "whisper"
                self._recognizer = so.OfflineRecognizer.from_whisper(
                    encoder=str(encoder), decoder=str(decoder), tokens=str(tokens), language=language,
                    task="transcribe", **common)
            elif single is not None and "sense" in str(directory).lower():
                self.family = "sense_voice"
                self._recognizer = so.OfflineRecognizer.from_sense_voice(model=str(single), tokens=str(tokens),
                                                                         use_itn=True, **common)
            elif single is not None:
                self.family = "paraformer"
                self._recognizer = so.OfflineRecognizer.from_paraformer(paraformer=str(single), tokens=str(tokens),
                                                                        **common)
            else:
                raise ConfigError(f"{what}: cannot tell the model family of {directory} "
                                  f"(files: {sorted(p.name for p in directory.iterdir())})")
        except (RuntimeError, ValueError, TypeError) as exc:
            raise ConfigError(f"{what}: sherpa-onnx cannot load {directory}: {exc}") from exc
        self.model_dir = directory
        _logger.info("loaded the %s speech model from %s", self.family, directory)

    def transcribe(self, samples: npt.NDArray[np.float32], sample_rate: int = MODEL_RATE) -> str:
        """The text of one utterance (mono float32 samples, at most :data:`MAX_UTTERANCE_SECONDS`)."""
        if samples.size == 0:
            return ""
        if samples.size > MAX_UTTERANCE_SECONDS * sample_rate:
            raise InferenceError(f"a {samples.size / sample_rate:.1f} s utterance is longer than the "
                                 f"{MAX_UTTERANCE_SECONDS:.0f} s the recognizer takes at once")
        shortest = int(MIN_UTTERANCE_SECONDS * sample_rate)
        if samples.size < shortest:
            samples = np.concatenate([samples.astype(np.float32), np.zeros(shortest - samples.size, np.float32)])
        stream = self._recognizer.create_stream()
        stream.accept_waveform(sample_rate, np.ascontiguousarray(samples, np.float32))
        try:
            self._recognizer.decode_stream(stream)
        except RuntimeError as exc:
            raise InferenceError(f"the speech model failed: {exc}") from exc
        return str(stream.result.text).strip()

    def __call__(self, inference_input: Mapping[str, Any]) -> dict[str, Any]:
        """``{"query": audio, "sample_rate": Hz}`` -> ``{"output": text}``.

        ``audio``: WAV file bytes (their own rate), raw 16-bit PCM bytes, or a numpy array (int16,
        or float in [-1, 1]) at ``sample_rate`` (default 16 kHz), as architecture.md says.
        """
        samples, rate = audio_samples(inference_input["query"], int(inference_input.get("sample_rate", MODEL_RATE)))
        return {"output": self.transcribe(samples, rate)}


def audio_samples(audio: Any, sample_rate: int) -> tuple[npt.NDArray[np.float32], int]:
    """Mono float32 samples and their rate from WAV bytes, 16-bit PCM bytes or an array."""
    if isinstance(audio, bytes | bytearray | memoryview):
        data = bytes(audio)
        if data[:4] == b"RIFF":
            pcm, rate, channels = read_wav(data)
            return to_mono_float(pcm, channels), rate
        if len(data) % 2:
            raise InferenceError(f"raw PCM audio must be 16-bit samples: {len(data)} bytes is an odd count")
        return np.frombuffer(data, "<i2").astype(np.float32) / 32768.0, sample_rate
    array = np.asarray(audio)
    if array.dtype == np.int16:
        return array.reshape(-1).astype(np.float32) / 32768.0, sample_rate
    return np.asarray(array, np.float32).reshape(-1), sample_rate


def default_vad_path() -> Path:
    """Silero VAD's ONNX file as shipped by the PyPI package ``silero-vad`` (found without importing
    it: its ``__init__`` imports torch; install it with ``pip install --no-deps silero-vad``)."""
    spec = importlib.util.find_spec("silero_vad")
    for location in list(spec.submodule_search_locations or []) if spec is not None else []:
        candidate = Path(location) / "data" / "silero_vad.onnx"
        if candidate.is_file():
            return candidate
    raise ConfigError("no voice activity model: run `pip install --no-deps silero-vad` (it ships silero_vad.onnx), "
                      "or set vad_model_path to a silero_vad.onnx file")


class SpeechSegmenter:
    """Cuts a 16 kHz stream into utterances with Silero VAD (sherpa-onnx ``VoiceActivityDetector``).

    :meth:`accept` takes samples of any length and returns the utterances completed by them, each
    ``(start sample, samples)`` with the start counted from the beginning of the stream.

    :param threshold: speech probability above which a window counts as speech.
    :param min_silence_ms: silence that ends an utterance.
    :param min_speech_ms: shorter bursts (clicks, a cough) are not utterances.
    :param max_speech_s: an utterance is cut when it gets this long.
    """

    window = 512  # samples: what Silero VAD takes at 16 kHz

    def __init__(self, model_path: str | Path | None = None, threshold: float = 0.5, min_silence_ms: int = 500,
                 min_speech_ms: int = 250, max_speech_s: float = 20.0, ncpu: int = 1) -> None:
        so = import_sherpa_onnx()
        path = Path(model_path).expanduser() if model_path else default_vad_path()
        if not path.is_file():
            raise ConfigError(f"voice activity model: no such file {str(path)!r}")
        config = so.VadModelConfig()
        config.silero_vad.model = str(path)
        config.silero_vad.threshold = threshold
        config.silero_vad.min_silence_duration = min_silence_ms / 1000
        config.silero_vad.min_speech_duration = min_speech_ms / 1000
        config.silero_vad.max_speech_duration = max_speech_s
        config.sample_rate = MODEL_RATE
        config.num_threads = ncpu
        self._config = config
        self._so = so
        # The detector's own buffer must hold the longest utterance plus the silence that ends it.
        self._buffer_s = max_speech_s + 10.0
        self._vad = so.VoiceActivityDetector(config, buffer_size_in_seconds=self._buffer_s)
        self._pending = np.zeros(0, np.float32)

    def reset(self) -> None:
        """Forget the stream so far (a new speaker, a new session)."""
        self._vad = self._so.VoiceActivityDetector(self._config, buffer_size_in_seconds=self._buffer_s)
        self._pending = np.zeros(0, np.float32)

    @property
    def speaking(self) -> bool:
        """Whether an utterance is in progress."""
        return bool(self._vad.is_speech_detected())

    def _drain(self) -> list[tuple[int, npt.NDArray[np.float32]]]:
        out = []
        while not self._vad.empty():
            segment = self._vad.front
            out.append((int(segment.start), np.asarray(segment.samples, np.float32)))
            self._vad.pop()
        return out

    def accept(self, samples: npt.NDArray[np.float32]) -> list[tuple[int, npt.NDArray[np.float32]]]:
        """Feed samples; the utterances they completed."""
        pending = np.concatenate([self._pending, samples]) if self._pending.size else samples
        whole = pending.size - pending.size % self.window
        out = []
        # One window per call: given more at once, sherpa-onnx's detector (2.0) misses the end of speech.
        for start in range(0, whole, self.window):
            self._vad.accept_waveform(np.ascontiguousarray(pending[start:start + self.window]))
            if not self._vad.empty():
                out += self._drain()
        self._pending = pending[whole:].copy()
        return out

    def flush(self) -> list[tuple[int, npt.NDArray[np.float32]]]:
        """End the stream: the utterance in progress, if any, is completed."""
        self._vad.flush()
        out = self._drain()
        self.reset()
        return out


class WakeWordDetector:
    """microWakeWord (PyPI ``pymicro-wakeword``, Apache-2.0) on a 16 kHz stream.

    :param model: a built-in model name (``"hey_jarvis"``, ``"alexa"``, ``"okay_nabu"``,
        ``"hey_mycroft"``) or the path of a microWakeWord ``.json`` config beside its ``.tflite``.
    :param threshold: detection probability (None: the model's own cutoff, which its authors tuned).
    """

    def __init__(self, model: str = "hey_jarvis", threshold: float | None = None) -> None:
        try:
            from pymicro_wakeword import MicroWakeWord, MicroWakeWordFeatures, Model  # noqa: PLC0415
        except ImportError as exc:
            raise ConfigError(f"the wake word needs pymicro-wakeword: {install_hint('local')}") from exc
        builtin = {m.value: m for m in Model}
        try:
            if model in builtin:
                self._model = MicroWakeWord.from_builtin(builtin[model])
            elif Path(model).expanduser().is_file():
                self._model = MicroWakeWord.from_config(Path(model).expanduser())
            else:
                raise ConfigError(f"wake word model {model!r} is neither a built-in ({sorted(builtin)}) nor a "
                                  "microWakeWord .json file")
        except (OSError, ValueError, KeyError) as exc:
            raise ConfigError(f"cannot load wake word model {model!r}: {exc}") from exc
        self._features_class = MicroWakeWordFeatures
        self._features = MicroWakeWordFeatures()
        self.name = model
        self.threshold = float(self._model.probability_cutoff if threshold is None else threshold)
        #: The highest probability seen since the last reset (for tuning the threshold).
        self.peak = 0.0
        self._samples_seen = 0

    def reset(self) -> None:
        """Start over (after a detection, so that one wake word fires once)."""
        self._model.reset()
        self._features = self._features_class()
        self.peak = 0.0

    def accept(self, samples: npt.NDArray[np.float32]) -> int | None:
        """Feed samples; the stream position (sample) of a detection in them, else None."""
        detected: int | None = None
        for features in self._features.process_streaming(float_to_int16(samples).tobytes()):
            prob = self._model.process_streaming_prob(features)
            if prob is None:
                continue
            self.peak = max(self.peak, float(prob))
            if detected is None and prob > self.threshold:
                detected = self._samples_seen + samples.size
        self._samples_seen += samples.size
        if detected is not None:
            self.reset()
        return detected

    def close(self) -> None:
        """Release the TFLite interpreter."""
        self._model.close()
