"""The rest of the spec's contract (issue 37), one test per point the spec states and main 367a9ce missed.

- architecture.md: validation runs in ``Component.__init__()`` "via ``_validate_topics()``" (a
  method a subclass can call or override); triggers are wired in ``activate_all_triggers()``;
- custom_client.md: ``_deinitialize`` is "called during the component's deactivate lifecycle phase";
- architecture.md: ``LocalSTT(model_path, device, ncpu)`` accepts audio bytes or numpy arrays,
  ``LocalTTS(model_path, device, ncpu)`` returns WAV bytes; custom_component.md shows
  ``device_local_model`` defaulting to ``"cuda"``: the device is detected, and "cuda" where the
  backend cannot use a GPU runs on the CPU with a warning.
"""

from __future__ import annotations

import io
import logging
import wave
from collections.abc import MutableMapping
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.components.model_component import ModelComponent
from agents_core.errors import WiringError
from agents_core.ros import String

from ..conftest import wait_for
from .test_spec_components import EchoClient


class _Echo(Component):
    def _execution_step(self, **kwargs: Any) -> None:
        value = self.trig_callbacks["text_in"].get_output()
        self.publishers_dict["text_out"].publish(value)


IN, OUT = Topic("text_in", "String"), Topic("text_out", "String")


def test_validate_topics_is_a_method_run_by_init_that_subclasses_override() -> None:
    calls: list[str] = []

    class Strict(_Echo):
        allowed_inputs = {"Required": [String]}  # noqa: RUF012 - as the spec writes it

        def _validate_topics(self) -> None:
            calls.append("validate")
            super()._validate_topics()
            if any(t.name.startswith("debug") for t in self.outputs):
                raise WiringError(f"component {self.component_name!r}: no debug outputs")

    strict = Strict(inputs=[IN], outputs=[OUT], trigger=IN)
    assert calls == ["validate"]
    strict._validate_topics()  # callable again, as a method
    with pytest.raises(WiringError, match="no debug outputs"):
        Strict(inputs=[IN], outputs=[Topic("debug_out", "String")], trigger=IN)
    with pytest.raises(WiringError, match="needs an input topic of type String"):
        Strict(inputs=[Topic("img", "Image")], outputs=[OUT], trigger=1.0)


def test_activate_all_triggers_runs_at_activate_and_wires_the_trigger_callback() -> None:
    order: list[str] = []

    class Traced(_Echo):
        def activate_all_triggers(self) -> None:
            order.append("triggers")
            super().activate_all_triggers()

        def custom_on_activate(self) -> None:
            order.append("custom_on_activate")

    traced = Traced(inputs=[IN], outputs=[OUT], trigger=IN, component_name="traced")
    assert not traced.trig_callbacks["text_in"]._post_callbacks  # wired at activate, not before
    launcher = Launcher("memory")
    launcher.add_pkg(components=[traced])
    got: list[str] = []
    with launcher:
        assert order == ["triggers", "custom_on_activate"]
        assert len(traced.trig_callbacks["text_in"]._post_callbacks) == 1
        launcher.transport.create_subscription(OUT, got.append)
        launcher.transport.create_publisher(IN).publish("ping")
        assert wait_for(lambda: got == ["ping"])
        traced.deactivate()
        traced.activate()  # wired once, not twice
        assert len(traced.trig_callbacks["text_in"]._post_callbacks) == 1


class _Asker(ModelComponent):
    handled_outputs = [String]  # noqa: RUF012 - as the spec writes it

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        text = self.trig_callbacks["text_in"].get_output()
        return {"query": text} if text else None

    def _execution_step(self, **kwargs: Any) -> None:
        inference_input = self._create_input()
        if inference_input is not None:
            self._publish(self._call_inference(inference_input))

    def _warmup(self, *args: Any, **kwargs: Any) -> None: ...


def test_deinitialize_is_called_at_deactivate_and_the_model_set_up_again_after() -> None:
    client = EchoClient()
    asker = _Asker(inputs=[IN], outputs=[OUT], model_client=client, trigger=IN, component_name="asker")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[asker])
    got: list[Any] = []
    with launcher:
        launcher.transport.create_subscription(OUT, got.append)
        assert client.events == ["check", "init"]
        asker.deactivate()
        assert client.events == ["check", "init", "deinit"] and not client.initialized
        asker.activate()
        launcher.transport.create_publisher(IN).publish("again")
        assert wait_for(lambda: got == ["echo: again"])
        assert client.events == ["check", "init", "deinit", "check", "init", "inference"]
    assert client.events[-1] == "deinit"  # and released at shutdown, once


def test_a_model_component_that_never_calls_a_model_needs_only_its_step() -> None:
    class Passive(ModelComponent):  # upstream's SecurityCamera shape: no client, no _create_input
        def _execution_step(self, **kwargs: Any) -> None: ...

    Passive(inputs=[IN], outputs=[], trigger=IN)

    class NoStep(ModelComponent):
        pass

    with pytest.raises(TypeError, match=r"NoStep .*must implement _execution_step"):
        NoStep(inputs=[IN], outputs=[], trigger=IN)


def test_a_model_component_with_a_client_but_no_create_input_is_refused_at_construction() -> None:
    class HalfDone(ModelComponent):
        def _execution_step(self, **kwargs: Any) -> None: ...

        def _warmup(self, *args: Any, **kwargs: Any) -> None: ...

    with pytest.raises(TypeError, match=r"HalfDone \(component 'half'\) must implement _create_input"):
        HalfDone(inputs=[IN], outputs=[], model_client=EchoClient(), trigger=IN, component_name="half")


# -- local models ----------------------------------------------------------------------------------


def _whisper() -> str:
    from ..components.voice_recipe import needs_stt  # noqa: PLC0415

    return needs_stt()[0]


def _wav(samples: np.ndarray, rate: int) -> bytes:
    buffer = io.BytesIO()
    with wave.open(buffer, "wb") as out:
        out.setnchannels(1)
        out.setsampwidth(2)
        out.setframerate(rate)
        out.writeframes(samples.astype("<i2").tobytes())
    return buffer.getvalue()


def test_local_stt_takes_model_path_device_ncpu_and_audio_bytes_or_arrays(caplog: pytest.LogCaptureFixture) -> None:
    whisper = _whisper()
    from agents_core.engines.local_stt import LocalSTT  # noqa: PLC0415

    from ..components.voice_recipe import clip  # noqa: PLC0415

    with caplog.at_level(logging.WARNING, logger="agents_core.engines"):
        stt = LocalSTT(whisper, "cuda", 1)  # architecture.md's order; no GPU here: the CPU, loudly
    if stt.device == "cpu":
        assert any("RUNNING ON THE CPU" in r.getMessage() for r in caplog.records)
    pcm = clip("pick_up_red_cube_16k.wav")
    texts = {
        "wav bytes": stt({"query": _wav(pcm, 16_000)})["output"],
        "pcm bytes": stt({"query": pcm.astype("<i2").tobytes(), "sample_rate": 16_000})["output"],
        "int16 array": stt({"query": pcm, "sample_rate": 16_000})["output"],
        "float array": stt({"query": pcm.astype(np.float32) / 32768.0, "sample_rate": 16_000})["output"],
    }
    assert len(set(texts.values())) == 1, texts
    assert "cube" in next(iter(texts.values())).lower()


def test_local_tts_takes_model_path_device_ncpu_and_returns_wav_bytes() -> None:
    from agents_core.engines.local_tts import LocalTTS  # noqa: PLC0415

    from ..components.voice_recipe import voice_dir  # noqa: PLC0415

    tts = LocalTTS(str(voice_dir()), "cpu", 1)
    result = tts({"query": "Hello there."})
    wav: bytes = result["output"]
    assert isinstance(wav, bytes) and wav[:4] == b"RIFF"
    with wave.open(io.BytesIO(wav)) as read:
        assert read.getframerate() == tts.sample_rate == result["sample_rate"] and read.getnframes() > 1000


def test_device_local_model_is_detected_and_cuda_without_a_gpu_falls_back_loudly(
        caplog: pytest.LogCaptureFixture) -> None:
    from agents_core.config import LLMConfig  # noqa: PLC0415
    from agents_core.engines.device import gpu_available, resolve_device  # noqa: PLC0415

    assert LLMConfig().device_local_model == "auto"
    assert LLMConfig(device_local_model="cuda").device_local_model == "cuda"
    ort = pytest.importorskip("onnxruntime")
    gpu = gpu_available("onnxruntime", ort)
    with caplog.at_level(logging.INFO, logger="agents_core.engines"):
        assert resolve_device("auto", "onnxruntime", ort, "Vision") == ("cuda" if gpu else "cpu")
        assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
        assert resolve_device("cuda", "onnxruntime", ort, "Vision") == ("cuda" if gpu else "cpu")
        assert resolve_device("cpu", "onnxruntime", ort, "Vision") == "cpu"
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warnings == ([] if gpu else [warnings[0]]) and (gpu or "onnxruntime-gpu" in warnings[0])
    llama_cpp = pytest.importorskip("llama_cpp")
    expected = "cuda" if llama_cpp.llama_supports_gpu_offload() else "cpu"
    assert resolve_device("auto", "llama_cpp", llama_cpp, "LLM") == expected


def test_a_model_client_returning_none_is_still_harmless_to_a_none_check() -> None:
    # Typed errors instead of None (docs/porting.md): a spec-style "if result is None: return" after
    # _call_inference never runs on a failure, and the failure is reported as the spec's fallback expects.
    class Silent(EchoClient):
        def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
            return None

    asker = _Asker(inputs=[IN], outputs=[OUT], model_client=Silent(), trigger=IN, component_name="silent")
    fired: list[str] = []
    from agents_core.actions import Action  # noqa: PLC0415

    asker.on_algorithm_fail(Action(lambda: fired.append("algorithm")))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[asker])
    with launcher:
        launcher.transport.create_publisher(IN).publish("anything")
        assert wait_for(lambda: fired == ["algorithm"])
