"""Upstream (EmbodiedAgents / ros_sugar) names and defaults that recipes use as written (issue 26)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import agents_core.ros
from agents_core import Topic
from agents_core.clients import ChromaClient, OllamaClient
from agents_core.clients.client_base import client_from_spec
from agents_core.components import ComponentRunType, MapLayer
from agents_core.config import LLMConfig, MLLMConfig, SpeechToTextConfig, VisionConfig
from agents_core.errors import ConfigError, TypeValidationError
from agents_core.messages import DetectionsMsg, PoseMsg
from agents_core.supported_types import Pose, PoseStamped
from agents_core.vectordbs import ChromaDB


def test_chromadb_without_arguments_embeds_with_ollama_as_upstream() -> None:
    db = ChromaDB()
    assert (db.name, db.embeddings, db.checkpoint, db.ollama_host, db.ollama_port) == (
        "chroma", "ollama", "bge-large:latest", "127.0.0.1", 11434)
    client = ChromaClient(db=db, port=8080)
    embedder = client.embedding_client
    assert isinstance(embedder, OllamaClient) and embedder.port == 11434
    assert embedder.serialize()["model"]["model_init_params"]["checkpoint"] == "bge-large:latest"
    # The derived embedder is rebuilt from the database's fields, not serialized beside them.
    spec = client.serialize()
    assert spec["embedding_client"] is None
    assert client_from_spec(spec) == client
    assert isinstance(client_from_spec(spec).embedding_client, OllamaClient)
    assert ChromaClient(db=ChromaDB(embeddings=None)).embedding_client is None
    with pytest.raises(ConfigError, match="embedding_client"):
        ChromaDB(embeddings="sentence-transformers")


@pytest.mark.parametrize("config_class", [LLMConfig, MLLMConfig])
def test_distance_func_is_accepted_in_the_llm_config(config_class: Any) -> None:
    assert config_class(enable_rag=True, collection_name="c", distance_func="cosine").distance_func == "cosine"
    assert config_class().distance_func == "l2"
    with pytest.raises(ConfigError):
        config_class(distance_func="dot")


def test_agents_ros_exports_the_upstream_names_we_implement() -> None:
    assert agents_core.ros.MapLayer is MapLayer
    assert agents_core.ros.ComponentRunType is ComponentRunType
    assert {"MapLayer", "ComponentRunType"} <= set(agents_core.ros.__all__)


DETECTIONS = Topic("det", "Detections")
SEEN = {"det": DetectionsMsg(boxes=np.zeros((2, 4), np.float32), labels=["person", "cup"],
                             scores=np.ones(2, np.float32))}


@pytest.mark.parametrize(("make", "expected"), [
    (lambda labels: labels.contains_any(["person", "dog"]), True),
    (lambda labels: labels.contains_any(["dog"]), False),
    (lambda labels: labels.contains_all(["person", "cup"]), True),
    (lambda labels: labels.contains_all(["person", "dog"]), False),
    (lambda labels: labels.not_contains_any(["dog", "cat"]), True),
    (lambda labels: labels.not_contains_any(["cup"]), False),
    (lambda labels: labels.not_contains_all(["person", "dog"]), True),
    (lambda labels: labels.contains("cup"), True),
    (lambda labels: labels.contains(["cup", "person"]), True),
    (lambda labels: labels.not_contains("dog"), True),
    (lambda labels: labels.not_contains(["cup", "person"]), False),
    (lambda labels: labels[0] == "person", True),
    (lambda labels: labels[1].is_in(["cup", "plate"]), True),
    (lambda labels: labels[1].not_in(["cup", "plate"]), False),
])
def test_container_operators_of_upstream_field_refs(make: Any, expected: bool) -> None:
    condition = make(DETECTIONS.msg.labels)
    assert condition.evaluate(SEEN) is expected


def test_bool_field_operators_and_str_items_refused() -> None:
    flag = Topic("flag", "Bool")
    assert flag.msg.data.is_true().evaluate({"flag": True})
    assert flag.msg.data.is_false().evaluate({"flag": False})
    assert (~flag.msg.data).evaluate({"flag": False}) and not (~flag.msg.data).evaluate({"flag": True})
    with pytest.raises(ConfigError, match="write \\['person'\\]"):
        DETECTIONS.msg.labels.contains_any("person")


def test_vision_config_takes_upstreams_enable_local_classifier() -> None:
    config = VisionConfig(enable_local_classifier=True)
    assert config.enable_local_model and config.enable_local_classifier
    assert VisionConfig(enable_local_model=True).enable_local_classifier
    assert not VisionConfig().enable_local_model


@pytest.mark.parametrize("msg_type", [Pose, PoseStamped])
def test_pose_from_upstreams_arrays(msg_type: Any) -> None:
    plain = msg_type.validate([1.0, 2.0, 3.0])
    assert isinstance(plain, PoseMsg) and plain.position.tolist() == [1.0, 2.0, 3.0]
    assert plain.orientation.tolist() == [0.0, 0.0, 0.0, 1.0]
    # Upstream's order: [x, y, z, qw, qx, qy, qz]; PoseMsg keeps [qx, qy, qz, qw].
    turned = msg_type.validate(np.array([1, 2, 3, 0.7071, 0.0, 0.0, 0.7071]))
    assert turned.orientation.tolist() == pytest.approx([0.0, 0.0, 0.7071, 0.7071])
    assert msg_type.convert((0, 0, 0, 1, 0, 0, 0), frame_id="map").header.frame_id == "map"
    for bad in ([1.0, 2.0], [1, 2, 3, 4], ["a", "b", "c"], "1 2 3", {"x": 1}):
        with pytest.raises(TypeValidationError):
            msg_type.validate(bad)


def test_speech_to_text_vad_is_off_unless_asked_for() -> None:
    assert SpeechToTextConfig().enable_vad is False
    assert SpeechToTextConfig(vad_model_path="/models/silero_vad.onnx").enable_vad is True
    assert SpeechToTextConfig(enable_vad=True).enable_vad is True
    assert SpeechToTextConfig(enable_vad=False, vad_model_path="/x.onnx").enable_vad is False
