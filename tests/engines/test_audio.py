"""agents_core.engines.audio: down-mixing, checks, and a resampler whose output does not depend on chunking."""

from __future__ import annotations

import numpy as np
import pytest

from agents_core.engines.audio import AudioInputError, StreamResampler, check_rate, read_wav, to_mono_float, wav_bytes
from agents_core.errors import AlgorithmFailure


def _tone(freq: float, rate: int, seconds: float = 1.0) -> np.ndarray:
    t = np.arange(round(rate * seconds)) / rate
    return (0.5 * np.sin(2 * np.pi * freq * t)).astype(np.float32)


def test_int16_and_float_stereo_are_downmixed_to_mono_float() -> None:
    stereo = np.array([32767, -32768, 16384, 16384], np.int16)
    assert np.allclose(to_mono_float(stereo, 2), [0.0, 0.5], atol=1e-4)
    frames = np.array([[0.2, 0.4], [1.5, 1.5]], np.float32)  # (frames, channels); clipped to [-1, 1]
    assert np.allclose(to_mono_float(frames), [0.3, 1.0])


@pytest.mark.parametrize("bad", [np.array([0.0, np.nan], np.float32), np.array([np.inf], np.float32),
                                 np.array(["a"]), np.zeros((2, 2, 2), np.float32)])
def test_unusable_chunks_raise_a_typed_error(bad: np.ndarray) -> None:
    with pytest.raises(AudioInputError):
        to_mono_float(bad)
    assert issubclass(AudioInputError, AlgorithmFailure)


def test_rates_outside_the_usual_range_are_refused() -> None:
    assert check_rate(np.int64(44_100)) == 44_100
    for bad in (0, 1, 3_999, 10_000_000, 16_000.0, True):
        with pytest.raises(AudioInputError):
            check_rate(bad)
    with pytest.raises(AudioInputError):
        to_mono_float(np.zeros(3, np.int16), channels=2)


@pytest.mark.parametrize(("source", "target"), [(48_000, 16_000), (44_100, 16_000), (8_000, 16_000),
                                                (16_000, 22_050)])
def test_the_stream_resampler_keeps_the_tone_and_the_length_whatever_the_chunking(source: int, target: int) -> None:
    tone = _tone(440.0, source)
    whole = StreamResampler(source, target)(tone)
    resampler = StreamResampler(source, target)
    edges = np.cumsum(np.random.default_rng(1).integers(1, 500, tone.size))
    cut = np.concatenate([resampler(part) for part in np.split(tone, edges[edges < tone.size])])
    assert np.allclose(whole, cut, atol=1e-5)
    assert abs(whole.size - target) <= 2
    spectrum = np.abs(np.fft.rfft(whole[-target // 2:]))
    assert abs(np.argmax(spectrum) * 2 - 440) <= 4  # 0.5 s window: 2 Hz bins


def test_downsampling_filters_what_would_fold_back() -> None:
    high = _tone(12_000.0, 48_000)  # above the 8 kHz Nyquist frequency of 16 kHz
    out = StreamResampler(48_000, 16_000)(high)
    assert float(np.abs(out[100:]).max()) < 0.05


def test_wav_round_trip() -> None:
    samples = (_tone(300.0, 16_000, 0.1) * 32767).astype(np.int16)
    data, rate, channels = read_wav(wav_bytes(samples, 16_000))
    assert rate == 16_000 and channels == 1 and np.array_equal(data, samples)
