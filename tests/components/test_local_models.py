"""The LLM and MLLM components on real local models (llama.cpp): SmolLM2 and a tiny random VLM."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents_core import Action, Topic
from agents_core.components import LLM, MLLM
from agents_core.config import LLMConfig, MLLMConfig
from agents_core.errors import ConfigError
from agents_core.messages import ImageMsg
from agents_core.status import HealthStatus
from agents_core.utils import LocalLLM, LocalVLM

from ..conftest import wait_for
from .models_dir import needs_smollm2, needs_tiny_vlm
from .scripted_client import ScriptedChatClient
from .test_llm import _collect, running

pytestmark = pytest.mark.local_models

QUESTION, STREAM, ANSWER = Topic("question", "String"), Topic("answer_stream", "StreamingString"), Topic("answer",
                                                                                                       "String")


def test_smollm2_streams_an_answer_through_the_llm_component() -> None:
    needs_smollm2()
    llm = LLM(inputs=[QUESTION], outputs=[STREAM, ANSWER], trigger=QUESTION,
              config=LLMConfig(enable_local_model=True, stream=True, temperature=0.0, max_new_tokens=24,
                               system_prompt="You are a helpful robot."))
    with running(llm) as launcher:
        assert isinstance(llm.local_model, LocalLLM)
        assert llm.local_model.model_path.name == "SmolLM2-135M-Instruct.Q4_1.gguf"
        chunks, sentences = _collect(launcher, STREAM), _collect(launcher, ANSWER)
        launcher.transport.create_publisher(QUESTION).publish("What is the capital of France?")
        assert wait_for(lambda: bool(chunks) and chunks[-1].done, timeout=60)
        assert wait_for(lambda: bool(sentences), timeout=5)
    text = "".join(c.data for c in chunks)
    assert len(chunks) >= 4, f"streamed in several chunks, got {len(chunks)}"
    assert text.strip() and "Paris" in text, text
    assert " ".join(sentences) == text.strip()


def test_smollm2_answers_whole_when_not_streaming() -> None:
    needs_smollm2()
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], trigger=QUESTION,
              config=LLMConfig(enable_local_model=True, temperature=0.0, max_new_tokens=16, warmup=True))
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        launcher.transport.create_publisher(QUESTION).publish("Say hello.")
        assert wait_for(lambda: bool(answers), timeout=60)
    assert isinstance(answers[0], str) and answers[0].strip()


def test_local_llm_tool_call_is_a_parsed_tool_call() -> None:
    needs_smollm2()
    model = LocalLLM()
    tools = [{"type": "function", "function": {
        "name": "move", "description": "Move the robot forward by a distance in meters",
        "parameters": {"type": "object", "properties": {"distance": {"type": "number"}}, "required": ["distance"]}}}]
    result = model({"query": [{"role": "user", "content": "Move forward 3 meters."}], "tools": tools,
                    "temperature": 0.0, "max_new_tokens": 40})
    model.close()
    # The grammar allows a call or an answer; either way the result follows the payload contract.
    if result.get("tool_calls"):
        call = result["tool_calls"][0]
        assert call["function"]["name"] == "move" and isinstance(call["function"]["arguments"], dict)
        assert call["id"] == "call_0"
    else:
        assert isinstance(result["output"], str)


def test_fallback_to_local_answers_after_the_client_fails() -> None:
    needs_smollm2()
    broken = ScriptedChatClient(fail=True)
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=broken, trigger=QUESTION,
              config=LLMConfig(temperature=0.0, max_new_tokens=12))
    llm.on_algorithm_fail(Action(llm.fallback_to_local), max_retries=1)  # run time: an algorithm failure
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        pub = launcher.transport.create_publisher(QUESTION)
        pub.publish("Hello?")
        assert wait_for(lambda: llm.model_client is None and llm.local_model is not None, timeout=60)
        assert answers == []
        pub.publish("Say hello.")
        assert wait_for(lambda: bool(answers), timeout=60)
        assert wait_for(lambda: llm.health_status == HealthStatus.HEALTHY)
    assert answers[0].strip()


def test_tiny_vlm_drives_the_image_path_end_to_end() -> None:
    tiny = needs_tiny_vlm()
    camera, answer = Topic("camera", "Image"), Topic("caption", "String")
    vlm = MLLM(inputs=[QUESTION, camera], outputs=[answer], trigger=QUESTION,
               config=MLLMConfig(enable_local_model=True, local_model_path=str(tiny), max_new_tokens=6,
                                 temperature=0.0))
    with running(vlm) as launcher:
        model = vlm.local_model
        assert isinstance(model, LocalVLM)
        assert (model.model_path.name, model.mmproj_path.name) == ("tiny-qwen3.gguf", "tiny-mmproj.gguf")
        captions = _collect(launcher, answer)
        launcher.transport.create_publisher(camera).publish(
            ImageMsg(data=np.random.default_rng(0).integers(0, 255, (40, 56, 3), dtype=np.uint8), encoding="rgb8"))
        assert wait_for(lambda: vlm.callbacks["camera"].got_msg)
        launcher.transport.create_publisher(QUESTION).publish("What is in the image?")
        # Random weights: the words are gibberish by design; the path (image in, text out) is the test.
        assert wait_for(lambda: bool(captions), timeout=60)
    assert isinstance(captions[0], str)


def test_local_vlm_counts_image_tokens_in_the_prompt() -> None:
    tiny = needs_tiny_vlm()
    model = LocalVLM(str(tiny / "tiny-qwen3.gguf"))
    text_only = model({"query": [{"role": "user", "content": "Describe."}], "max_new_tokens": 1})
    with_image = model({"query": [{"role": "user", "content": "Describe.",
                                   "images": [np.zeros((32, 32, 3), np.uint8)]}], "max_new_tokens": 1})
    model.close()
    assert with_image["usage"]["prompt_tokens"] > text_only["usage"]["prompt_tokens"], "the image reached the model"


def test_local_model_path_errors_name_the_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    needs_smollm2()
    missing = tmp_path / "nope.gguf"
    with pytest.raises(ConfigError, match="no such file"):
        LocalLLM(str(missing))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")  # never reach a hub from tests
    with pytest.raises(ConfigError, match="some-org/some-model"):
        LocalLLM("some-org/some-model")
    (tmp_path / "only.txt").write_text("x")
    with pytest.raises(ConfigError, match="exactly one file"):
        LocalLLM(str(tmp_path))
