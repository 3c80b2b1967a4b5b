"""The RoboML model family and LeRobotPolicy: defaults, validators, init parameters, dict round trips."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import attrs
import pytest

from agents_core.errors import ConfigError
from agents_core.models import (
    LLM,
    LeRobotPolicy,
    Model,
    RoboBrain2,
    TransformersLLM,
    TransformersMLLM,
    TransformersTTS,
    VisionModel,
    Whisper,
    model_types,
)
from tests.servers.roboml_server import INIT_PARAMS

ROBOML_MODELS = [TransformersLLM, TransformersMLLM, RoboBrain2, Whisper, TransformersTTS, VisionModel]


@pytest.mark.parametrize("cls", ROBOML_MODELS)
def test_init_params_are_keywords_of_robomls_initialize(cls: type[Model]) -> None:
    plain = cls(name="m")._get_init_params()
    with_source = cls(name="m", source="modelscope")._get_init_params()  # type: ignore[call-arg]
    assert set(plain) <= INIT_PARAMS[cls.__name__] and "source" not in plain  # unset: not sent
    assert with_source["source"] == "modelscope" and set(with_source) <= INIT_PARAMS[cls.__name__]
    assert plain["checkpoint"] == cls(name="m").checkpoint


def test_defaults_follow_roboml() -> None:
    assert TransformersLLM(name="m")._get_init_params() == {"checkpoint": "Qwen/Qwen3-0.6B", "quantization": "4bit",
                                                            "system_prompt": None}
    assert TransformersMLLM(name="m").checkpoint == "Qwen/Qwen2.5-VL-3B-Instruct"
    assert RoboBrain2(name="m")._get_init_params() == {"checkpoint": "BAAI/RoboBrain2.0-3B"}
    assert Whisper(name="m")._get_init_params() == {"checkpoint": "small.en", "compute_type": "int8"}
    assert TransformersTTS(name="m")._get_init_params() == {"checkpoint": "suno/bark-small",
                                                            "voice": "v2/en_speaker_6", "vocoder_checkpoint": None}
    assert VisionModel(name="m")._get_init_params() == {
        "checkpoint": "PekingU/rtdetr_r50vd_coco_o365", "setup_trackers": False, "num_trackers": 1,
        "tracking_distance_threshold": 30}
    assert LeRobotPolicy(name="p")._get_init_params() == {
        "checkpoint": "lerobot/smolvla_base", "policy_type": "smolvla", "features": {}, "actions_per_chunk": 50,
        "device": "cuda"}


def test_hierarchy_and_registry() -> None:
    assert issubclass(TransformersMLLM, TransformersLLM) and issubclass(TransformersLLM, LLM)
    assert issubclass(RoboBrain2, LLM)
    for cls in (*ROBOML_MODELS, LeRobotPolicy):
        assert model_types()[cls.__name__] is cls
    assert [c.model_family for c in (TransformersLLM, TransformersMLLM, Whisper, TransformersTTS, VisionModel)] \
        == ["llm", "mllm", "stt", "tts", "vision"]


@pytest.mark.parametrize(("cls", "field", "value"), [
    (TransformersLLM, "quantization", "2bit"),
    (TransformersLLM, "source", "github"),
    (TransformersLLM, "system_prompt", ""),
    (TransformersLLM, "checkpoint", ""),
    (TransformersMLLM, "quantization", 4),
    (RoboBrain2, "quantization", "4bit"),
    (Whisper, "compute_type", "fp16"),
    (Whisper, "compute_type", None),
    (TransformersTTS, "voice", ""),
    (TransformersTTS, "vocoder_checkpoint", 3),
    (VisionModel, "setup_trackers", "yes"),
    (VisionModel, "num_trackers", 0),
    (VisionModel, "num_trackers", True),
    (VisionModel, "tracking_distance_threshold", 0),
    (VisionModel, "tracking_distance_threshold", 101),
    (VisionModel, "tracking_distance_threshold", 2.5),
    (LeRobotPolicy, "policy_type", "transformer"),
    (LeRobotPolicy, "actions_per_chunk", 0),
    (LeRobotPolicy, "policy_device", "tpu"),
    (LeRobotPolicy, "features", {"observation.state": 6}),
    (LeRobotPolicy, "actions", ["action"]),
    (LeRobotPolicy, "init_timeout", 0),
])
def test_invalid_values_name_the_field(cls: type[Model], field: str, value: Any) -> None:
    with pytest.raises(ConfigError, match=rf"{cls.__name__}\.{field}"):
        cls(name="m", **{field: value})
    model = cls(name="m")
    with pytest.raises(ConfigError, match=rf"{cls.__name__}\.{field}"):
        setattr(model, field, value)  # assignment is validated too


def test_valid_values_are_accepted() -> None:
    VisionModel(name="v", setup_trackers=True, num_trackers=3, tracking_distance_threshold=100)
    Whisper(name="w", compute_type="float16", checkpoint="large-v3")
    TransformersTTS(name="t", checkpoint="microsoft/speecht5_tts", voice=None,
                    vocoder_checkpoint="microsoft/speecht5_hifigan")
    TransformersLLM(name="l", quantization=None, system_prompt="Be brief.", init_timeout=120)
    LeRobotPolicy(name="p", policy_type="act", policy_device="cpu", actions_per_chunk=10,
                  features={"observation.state": {"dtype": "float32", "shape": [6]}}, actions={"action": {}})


def test_no_shared_mutable_defaults() -> None:
    first, second = LeRobotPolicy(name="a"), LeRobotPolicy(name="b")
    assert first.features is not second.features
    first.features["observation.state"] = {"shape": [6]}
    assert second.features == {}
    params = first._get_init_params()
    params["features"]["observation.state"]["shape"].append(7)
    assert first.features["observation.state"] == {"shape": [6]}  # init params are a copy


@pytest.mark.parametrize("cls", [*ROBOML_MODELS, LeRobotPolicy])
def test_dict_round_trip(cls: type[Model]) -> None:
    model = cls(name="m", init_timeout=60)
    again = cls.from_dict(model.asdict())
    assert again == model and again._get_init_params() == model._get_init_params()
    with pytest.raises(ConfigError, match="unknown field"):
        cls.from_dict({"name": "m", "tracking_distance_function": "euclidean"})


def test_from_dict_validates() -> None:
    vision = VisionModel.from_dict({"name": "v", "setup_trackers": True, "tracking_distance_threshold": 40})
    assert vision._get_init_params()["tracking_distance_threshold"] == 40
    with pytest.raises(ConfigError, match=r"VisionModel\.num_trackers"):
        VisionModel.from_dict({"name": "v", "num_trackers": -1})


def test_subclass_keeps_validators_and_registers() -> None:
    @attrs.define(kw_only=True)
    class SmallWhisper(Whisper):
        checkpoint: str = "tiny.en"

    assert SmallWhisper(name="s")._get_init_params() == {"checkpoint": "tiny.en", "compute_type": "int8"}
    assert model_types()["SmallWhisper"] is SmallWhisper
    with pytest.raises(ConfigError, match="compute_type"):
        SmallWhisper(name="s", compute_type="fast")


def _dataset_info() -> dict[str, Any]:
    return {"codebase_version": "v2.1", "fps": 30, "features": {
        "action": {"dtype": "float32", "shape": [6], "names": ["j0", "j1", "j2", "j3", "j4", "gripper"]},
        "observation.state": {"dtype": "float32", "shape": [6], "names": ["j0", "j1", "j2", "j3", "j4", "gripper"]},
        "observation.images.front": {"dtype": "video", "shape": [480, 640, 3], "names": ["height", "width", "c"]},
        "timestamp": {"dtype": "float32", "shape": [1], "names": None},
        "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    }}


def test_lerobot_dataset_info_fills_features_without_io_at_construction(tmp_path: Path) -> None:
    path = tmp_path / "info.json"
    policy = LeRobotPolicy(name="p", dataset_info_file=str(path))  # the file does not exist yet: fine
    path.write_text(json.dumps(_dataset_info()))
    policy.load_dataset_info()
    assert sorted(policy.features) == ["observation.images.front", "observation.state"]
    assert list(policy.actions or {}) == ["action"]
    assert policy._get_init_params()["features"]["observation.state"]["shape"] == [6]
    other = LeRobotPolicy(name="q")
    other.load_dataset_info(_dataset_info())
    assert other.features == policy.features


def test_lerobot_dataset_info_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="needs info or dataset_info_file"):
        LeRobotPolicy(name="p").load_dataset_info()
    with pytest.raises(ConfigError, match="dataset_info_file"):
        LeRobotPolicy(name="p", dataset_info_file=str(tmp_path / "missing.json")).load_dataset_info()
    with pytest.raises(ConfigError, match="'features'"):
        LeRobotPolicy(name="p").load_dataset_info({"fps": 30})
