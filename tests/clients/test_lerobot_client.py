"""LeRobotClient against a real gRPC server on 127.0.0.1 speaking LeRobot's AsyncInference service,
and the restricted unpickling of the protocol's payloads."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

grpc = pytest.importorskip("grpc", reason="the vla extra (grpcio) is not installed")

from agents_core.clients.client_base import client_from_spec  # noqa: E402
from agents_core.clients.lerobot import LeRobotClient  # noqa: E402
from agents_core.clients.lerobot import protocol as wire  # noqa: E402
from agents_core.clients.lerobot.restricted_pickle import NUMPY_GLOBALS, UnsafePayloadError, restricted_loads  # noqa: E402
from agents_core.errors import (  # noqa: E402
    ClientConnectionError,
    ConfigError,
    InferenceTimeoutError,
    ProtocolError,
)
from agents_core.models import LeRobotPolicy  # noqa: E402
from agents_core.testing.helpers import free_tcp_port  # noqa: E402
from tests.servers.policy_server import PolicyTestServer, ReachPolicy  # noqa: E402

JOINTS = ["shoulder", "elbow"]


def policy_model(chunk: int = 4) -> LeRobotPolicy:
    return LeRobotPolicy(
        name="arm_policy", checkpoint="me/arm-policy", policy_type="act", actions_per_chunk=chunk, policy_device="cpu",
        features={"observation.state": {"dtype": "float32", "shape": [2], "names": JOINTS},
                  "observation.images.front": {"dtype": "image", "shape": [8, 8, 3],
                                               "names": ["height", "width", "channels"]}},
        actions={"action": {"dtype": "float32", "shape": [2], "names": JOINTS}})


def observation(step: int = 0, **state: float) -> dict[str, Any]:
    values = {"shoulder": 0.0, "elbow": 0.0, **state}
    return {"state": values, "images": {"front": np.full((8, 8, 3), 7, np.uint8)}, "task": "reach", "timestep": step}


def started(client: LeRobotClient) -> LeRobotClient:
    client.check_connection()
    client.initialize()
    return client


class TestLeRobotClientOnServer:
    def test_round_trip_sends_setup_and_observation_and_reads_the_chunk(self) -> None:
        with PolicyTestServer(ReachPolicy({"shoulder": 1.0, "elbow": -1.0}, step=0.1)) as server:
            client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=5))
            try:
                result = client.inference(observation(step=7, shoulder=0.2))
            finally:
                client.deinitialize()
        chunk = result["output"]
        assert result["timestep"] == 7
        assert chunk.dtype == np.float64 and chunk.shape == (4, 2)
        np.testing.assert_allclose(chunk[:, 0], [0.3, 0.4, 0.5, 0.6], atol=1e-6)
        np.testing.assert_allclose(chunk[:, 1], [-0.1, -0.2, -0.3, -0.4], atol=1e-6)
        # What the server received is what LeRobot's robot client sends.
        setup = server.setups[-1]
        assert (setup.policy_type, setup.pretrained_name_or_path, setup.actions_per_chunk, setup.device) == (
            "act", "me/arm-policy", 4, "cpu")
        assert setup.lerobot_features["observation.state"]["shape"] == (2,)
        obs = server.observations[-1]
        assert obs.timestep == 7 and obs.must_go
        assert obs.observation["task"] == "reach" and obs.observation["shoulder"] == pytest.approx(0.2)
        assert obs.observation["front"].shape == (8, 8, 3) and int(obs.observation["front"][0, 0, 0]) == 7
        assert server.ready_calls >= 1
        assert client.action_names == JOINTS

    def test_a_large_observation_travels_in_several_chunks(self) -> None:
        with PolicyTestServer() as server:
            client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=10,
                                           max_message_bytes=1024 * 1024))
            big = observation()
            big["images"]["front"] = np.random.default_rng(0).integers(0, 255, (600, 800, 3), dtype=np.uint8)
            try:
                client.inference(big)
            finally:
                client.deinitialize()
        assert np.array_equal(server.observations[-1].observation["front"], big["images"]["front"])

    def test_no_chunk_within_the_inference_timeout_is_a_timeout(self) -> None:
        with PolicyTestServer(fault="empty") as server:
            client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=0.5))
            try:
                with pytest.raises(InferenceTimeoutError, match="LeRobotClient"):
                    client.inference(observation())
            finally:
                client.deinitialize()

    def test_an_unreachable_server_is_a_connection_error(self) -> None:
        client = LeRobotClient(policy_model(), port=free_tcp_port(), allow_pickle=True, inference_timeout=1)
        with pytest.raises((ClientConnectionError, InferenceTimeoutError)):
            client.check_connection()
        client.deinitialize()

    def test_a_server_killed_by_pid_fails_the_next_inference(self) -> None:
        port = free_tcp_port()
        script = Path(__file__).resolve().parents[1] / "servers" / "policy_server.py"
        with subprocess.Popen([sys.executable, str(script), "--port", str(port), "--target", '{"shoulder": 1}'],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True) as proc:
            try:
                assert proc.stdout is not None
                assert "listening" in proc.stdout.readline()
                client = started(LeRobotClient(policy_model(), port=port, allow_pickle=True, inference_timeout=2))
                assert client.inference(observation())["output"].shape == (4, 2)
                proc.kill()
                proc.wait(timeout=10)
                with pytest.raises((ClientConnectionError, InferenceTimeoutError)):
                    client.inference(observation(step=4))
                client.deinitialize()
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait(timeout=10)


class TestPickleSafety:
    def test_the_client_refuses_to_start_without_the_opt_in(self) -> None:
        with pytest.raises(ConfigError, match="allow_pickle=True"):
            LeRobotClient(policy_model())

    def test_a_hostile_server_cannot_run_code_in_the_client(self, tmp_path: Path) -> None:
        marker = tmp_path / "pwned"

        class Exploit:
            def __reduce__(self) -> tuple[Any, ...]:
                return (open, (str(marker), "w"))

        with PolicyTestServer(actions_payload=pickle.dumps([Exploit()])) as server:
            client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=5))
            try:
                with pytest.raises(UnsafePayloadError, match=r"io\.open"):
                    client.inference(observation())
            finally:
                client.deinitialize()
        assert not marker.exists()

    @pytest.mark.parametrize("payload, match", [
        (pickle.dumps({"not": "a list"}), "list of TimedAction"),
        (wire.dumps_payload([]), "empty"),
        (wire.dumps_payload([wire.TimedAction(0.0, 3, np.zeros(2)), wire.TimedAction(0.0, 9, np.zeros(2))]),
         "not consecutive"),
        (wire.dumps_payload([wire.TimedAction(0.0, 0, np.zeros(2)), wire.TimedAction(0.0, 1, np.zeros(3))]),
         "different sizes"),
        (b"\x80\x04not a pickle", "not a readable pickle"),
    ])
    def test_malformed_actions_are_protocol_errors(self, payload: bytes, match: str) -> None:
        with PolicyTestServer(actions_payload=payload) as server:
            client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=5))
            try:
                with pytest.raises(ProtocolError, match=match):
                    client.inference(observation())
            finally:
                client.deinitialize()

    def test_an_oversized_payload_is_refused_before_reading(self) -> None:
        with pytest.raises(UnsafePayloadError, match="more than the 10 allowed"):
            restricted_loads(pickle.dumps(list(range(100))), NUMPY_GLOBALS, max_bytes=10)

    def test_numpy_arrays_and_payload_classes_round_trip(self) -> None:
        value = [wire.TimedAction(1.5, 2, np.arange(3, dtype=np.float32)), np.float64(2.5), np.zeros((2, 2), bool)]
        back = wire.loads_payload(wire.dumps_payload(value), max_bytes=1 << 20, what="t")
        assert isinstance(back[0], wire.TimedAction) and back[0].timestep == 2
        assert np.array_equal(back[0].action, np.arange(3, dtype=np.float32)) and back[1] == 2.5
        assert back[2].dtype == bool and back[2].shape == (2, 2)

    def test_payloads_name_lerobots_class_paths(self) -> None:
        data = wire.dumps_payload(wire.TimedObservation(0.0, 1, {"task": "x"}))
        assert b"lerobot.async_inference.helpers" in data and b"TimedObservation" in data
        assert b"agents_core" not in data


class TestWireFormat:
    def test_chunking_marks_begin_middle_end_and_joins_back(self) -> None:
        data = bytes(range(256)) * 10
        chunks = list(wire.chunk_payload(data, chunk_size=1000))
        assert [c.transfer_state for c in chunks] == [1, 2, 3]
        assert wire.join_chunks(iter(chunks), max_bytes=10_000) == data
        assert [c.transfer_state for c in wire.chunk_payload(b"x")] == [3]

    def test_joining_is_bounded_and_needs_an_end(self) -> None:
        chunks = list(wire.chunk_payload(b"y" * 5000, chunk_size=1000))
        with pytest.raises(ProtocolError, match="more than 3000 bytes"):
            wire.join_chunks(iter(chunks), max_bytes=3000)
        with pytest.raises(ProtocolError, match="without a TRANSFER_END"):
            wire.join_chunks(iter(chunks[:-1]), max_bytes=10_000)
        with pytest.raises(ProtocolError, match="unknown transfer state"):
            wire.join_chunks(iter([wire.Observation(transfer_state=0, data=b"")]), max_bytes=10)

    def test_message_encoding_matches_the_proto_field_numbers(self) -> None:
        # Observation{transfer_state=3 (field 1, varint), data=b"x" (field 2, bytes)}
        assert wire.Observation(transfer_state=3, data=b"x").SerializeToString() == b"\x08\x03\x12\x01x"
        assert wire.Actions(data=b"ab").SerializeToString() == b"\x0a\x02ab"
        assert wire.PolicySetup(data=b"c").SerializeToString() == b"\x0a\x01c"
        assert wire.Empty().SerializeToString() == b""


class TestClientSpec:
    def test_serialize_rebuilds_an_equal_client_with_the_opt_in(self) -> None:
        client = LeRobotClient(policy_model(), port=50051, allow_pickle=True, rename_map={"a": "b"})
        spec = client.serialize()
        assert spec["allow_pickle"] is True and spec["action_names"] == JOINTS
        assert client_from_spec(spec) == client

    def test_bad_arguments_are_config_errors(self) -> None:
        with pytest.raises(ConfigError, match="rename_map"):
            LeRobotClient(policy_model(), allow_pickle=True, rename_map={"a": 1})  # type: ignore[dict-item]
        with pytest.raises(ConfigError, match="max_message_bytes"):
            LeRobotClient(policy_model(), allow_pickle=True, max_message_bytes=10)

    def test_a_policy_input_must_follow_the_contract(self) -> None:
        with PolicyTestServer() as server:
            client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=5))
            try:
                with pytest.raises(ConfigError, match="missing"):
                    client.inference({"state": {}})
                with pytest.raises(ConfigError, match="timestep"):
                    client.inference({**observation(), "timestep": -1})
            finally:
                client.deinitialize()

