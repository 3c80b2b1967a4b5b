"""The policy setup is sent again when the policy server may have lost it: a server restarted between
goals (a new process state, no policy) is used again at once instead of being polled to the timeout."""

from __future__ import annotations

import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio) is not installed")

from agents_core.clients.lerobot import LeRobotClient
from agents_core.transport.goals import GoalStatus
from tests.clients.test_lerobot_client import observation, policy_model, started
from tests.components.test_vla import TARGET, rig
from tests.servers.policy_server import PolicyTestServer, ReachPolicy


def test_a_server_restarted_between_inferences_gets_the_setup_again() -> None:
    first = PolicyTestServer().start()
    port = first.port
    client = started(LeRobotClient(policy_model(), port=port, allow_pickle=True, inference_timeout=10))
    try:
        assert client.inference(observation(step=0))["output"].shape == (4, 2)
        first.stop()
        with PolicyTestServer(port=port) as second:  # the same address, no policy loaded
            # Before the fix this polled the policy-less server to the 10 s inference timeout and raised.
            result = client.inference(observation(step=1))
            assert result["output"].shape == (4, 2) and result["timestep"] == 1
            assert len(second.setups) == 1 and second.setups[0].pretrained_name_or_path == "me/arm-policy"
            assert client.setups_sent == 2
    finally:
        client.deinitialize()
        first.stop()


def test_a_healthy_server_gets_the_setup_once() -> None:
    with PolicyTestServer() as server:
        client = started(LeRobotClient(policy_model(), port=server.port, allow_pickle=True, inference_timeout=10))
        try:
            for step in range(5):
                client.inference(observation(step=step))
        finally:
            client.deinitialize()
    assert len(server.setups) == 1 and client.setups_sent == 1


def test_a_vla_goal_after_a_server_restart_succeeds() -> None:
    first = PolicyTestServer(ReachPolicy(TARGET, step=0.05)).start()
    port = first.port
    try:
        with rig(port, inference_timeout=10) as r:
            status, result = r.send(max_steps=10).result(timeout=30)
            assert status == GoalStatus.SUCCEEDED, result
            first.stop()
            with PolicyTestServer(ReachPolicy(TARGET, step=0.05), port=port) as second:
                status, result = r.send(max_steps=10).result(timeout=30)
                assert status == GoalStatus.SUCCEEDED, result
                assert len(second.setups) == 1
    finally:
        first.stop()
