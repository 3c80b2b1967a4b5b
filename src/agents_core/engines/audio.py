"""Audio helpers for the voice components: checking, down-mixing and resampling PCM chunks.

Microphones and other nodes send audio in many shapes (8 to 48 kHz, int16 or float32, mono or
interleaved stereo, 10 to 100 ms per chunk); the speech models want one thing: mono float32 in
[-1, 1] at 16 kHz. :func:`to_mono_float` does the per-chunk part and :class:`StreamResampler` the
rate change *across* chunks: resampling each chunk on its own would put a filter transient (a
click) at every chunk boundary, so the resampler keeps its filter history and its fractional
position from one chunk to the next.

Only numpy is needed (the anti-aliasing filter is a windowed-sinc FIR computed here).
"""

from __future__ import annotations

import io
import wave
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import AlgorithmFailure

__all__ = ["MAX_SAMPLE_RATE", "MIN_SAMPLE_RATE", "AudioInputError", "StreamResampler", "float_to_int16",
           "read_wav", "to_mono_float", "wav_bytes", "write_wav"]

#: Sample rates accepted (Hz): below 4 kHz nothing intelligible is left of speech, and above
#: 384 kHz (the highest rate sound cards offer) the value is a mistake rather than a format.
MIN_SAMPLE_RATE = 4_000
MAX_SAMPLE_RATE = 384_000
#: Most channels of one interleaved chunk (microphone arrays have up to a few dozen).
MAX_CHANNELS = 64

FloatArray = npt.NDArray[np.float32]


class AudioInputError(AlgorithmFailure):
    """An audio chunk the voice components cannot use (bad rate, non-finite samples, wrong shape).

    A subclass of :class:`~agents_core.errors.AlgorithmFailure`: in a component step it sets the
    health to ALGORITHM_FAILURE, and the next good chunk is processed as usual.
    """


def check_rate(sample_rate: Any) -> int:
    """``sample_rate`` as an int, or :class:`AudioInputError` when it is outside 4 kHz..384 kHz."""
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, int | np.integer):
        raise AudioInputError(f"the sample rate must be an int (Hz), got {sample_rate!r}")
    if not MIN_SAMPLE_RATE <= int(sample_rate) <= MAX_SAMPLE_RATE:
        raise AudioInputError(f"a sample rate of {sample_rate} Hz is outside {MIN_SAMPLE_RATE}..{MAX_SAMPLE_RATE} Hz")
    return int(sample_rate)


def to_mono_float(data: Any, channels: int = 1) -> FloatArray:
    """Interleaved int16 / float PCM as mono float32 in [-1, 1] (channels averaged).

    :raises AudioInputError: non-numeric data, a sample count that does not divide into
        ``channels``, or NaN / infinite samples (a broken driver or a decoding bug upstream:
        passing them on would poison the models' state).
    """
    array = np.asarray(data)
    if array.ndim == 2 and channels == 1:
        # (frames, channels), as sound libraries return them.
        channels = array.shape[1]
        array = array.reshape(-1)
    if array.ndim != 1:
        raise AudioInputError(f"expected 1-D interleaved samples, got shape {array.shape}")
    if not 1 <= channels <= MAX_CHANNELS:
        raise AudioInputError(f"{channels} channels is outside 1..{MAX_CHANNELS}")
    if array.size % channels:
        raise AudioInputError(f"{array.size} samples do not divide into {channels} channels")
    if array.dtype == np.int16:
        samples = array.astype(np.float32) / np.float32(32768.0)
    elif array.dtype.kind == "f":
        samples = array.astype(np.float32, copy=False)
        if not np.isfinite(samples).all():
            raise AudioInputError(f"the chunk has {int((~np.isfinite(samples)).sum())} NaN or infinite sample(s)")
    elif array.dtype.kind in "iu":
        info = np.iinfo(array.dtype)
        samples = (array.astype(np.float64) / max(abs(info.min), info.max)).astype(np.float32)
    else:
        raise AudioInputError(f"expected int16 or float samples, got {array.dtype}")
    if channels > 1:
        samples = samples.reshape(-1, channels).mean(axis=1, dtype=np.float32)
    clipped: FloatArray = np.clip(samples, -1.0, 1.0)
    return clipped


def float_to_int16(samples: FloatArray) -> npt.NDArray[np.int16]:
    """Float samples in [-1, 1] as int16 PCM (clipped)."""
    return (np.clip(samples, -1.0, 1.0) * 32767.0).astype(np.int16)


def _lowpass_taps(cutoff: float, half_width: int = 24) -> FloatArray:
    """A Blackman-windowed sinc low-pass, ``cutoff`` in cycles per input sample (< 0.5)."""
    n = np.arange(-half_width, half_width + 1, dtype=np.float64)
    taps = 2 * cutoff * np.sinc(2 * cutoff * n) * np.blackman(n.size)
    normalized: FloatArray = (taps / taps.sum()).astype(np.float32)
    return normalized


class StreamResampler:
    """Resamples a stream of mono float32 chunks from ``source_rate`` to ``target_rate``.

    Downsampling low-passes first (a 49-tap windowed sinc just below the target's Nyquist
    frequency) so that what lies above it does not fold back into the speech band; then both
    directions interpolate linearly at the output instants. Filter history and the position of the
    next output sample carry over between chunks, so the output is the same however the input is
    cut (up to float rounding). The filter delays the output by 24 input samples (0.5 ms at 48 kHz).
    """

    def __init__(self, source_rate: int, target_rate: int = 16_000) -> None:
        self.source_rate = check_rate(source_rate)
        self.target_rate = check_rate(target_rate)
        self._step = self.source_rate / self.target_rate
        self._taps = _lowpass_taps(0.45 / self._step) if self._step > 1 else None
        self._history = np.zeros(0 if self._taps is None else self._taps.size - 1, np.float32)
        self._last: float | None = None
        self._pos = 0.0  # position of the next output sample, in input samples after self._last

    def __call__(self, samples: FloatArray) -> FloatArray:
        """The resampled continuation of the stream for the next chunk (possibly empty)."""
        if self.source_rate == self.target_rate or samples.size == 0:
            return samples if self.source_rate == self.target_rate else np.zeros(0, np.float32)
        if self._taps is not None:
            padded = np.concatenate([self._history, samples])
            self._history = padded[-(self._taps.size - 1):]
            samples = np.convolve(padded, self._taps, mode="valid").astype(np.float32)
        if self._last is None:
            buffer, self._pos = samples, 0.0  # the first output sample is the first input sample
        else:
            buffer = np.concatenate([np.array([self._last], np.float32), samples])
        end = buffer.size - 1
        count = int(np.floor((end - self._pos) / self._step)) + 1 if end >= self._pos else 0
        positions = self._pos + self._step * np.arange(count)
        out: FloatArray = np.interp(positions, np.arange(buffer.size), buffer).astype(np.float32)
        next_pos = self._pos + self._step * count
        self._pos = next_pos - end  # relative to the new last sample, which becomes index 0
        self._last = float(buffer[-1])
        return out


def wav_bytes(samples: npt.NDArray[Any], sample_rate: int) -> bytes:
    """A mono 16-bit WAV file of ``samples`` (int16, or float in [-1, 1])."""
    pcm = samples if samples.dtype == np.int16 else float_to_int16(samples.astype(np.float32))
    out = io.BytesIO()
    with wave.open(out, "wb") as wav:
        wav.setnchannels(1)
        wav.setsampwidth(2)
        wav.setframerate(int(sample_rate))
        wav.writeframes(pcm.astype("<i2").tobytes())
    return out.getvalue()


def write_wav(path: str | Path, samples: npt.NDArray[Any], sample_rate: int) -> None:
    """Write ``samples`` as a mono 16-bit WAV file."""
    Path(path).write_bytes(wav_bytes(samples, sample_rate))


def read_wav(source: str | Path | bytes) -> tuple[npt.NDArray[np.int16], int, int]:
    """``(interleaved int16 samples, sample rate, channels)`` of a 16-bit PCM WAV file (path or bytes)."""
    handle = io.BytesIO(source) if isinstance(source, bytes) else open(source, "rb")  # noqa: SIM115
    with handle, wave.open(handle, "rb") as wav:
        if wav.getsampwidth() != 2:
            raise AudioInputError(f"only 16-bit PCM WAV files are read, this one has {8 * wav.getsampwidth()}-bit "
                                  "samples")
        data = np.frombuffer(wav.readframes(wav.getnframes()), "<i2").astype(np.int16)
        return data, wav.getframerate(), wav.getnchannels()
