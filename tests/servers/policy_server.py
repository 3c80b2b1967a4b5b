"""A LeRobot async-inference policy server double: gRPC ``transport.AsyncInference`` on 127.0.0.1.

It speaks the service of :mod:`agents_core.clients.lerobot.protocol` the way LeRobot's
``policy_server.py`` does (``Ready`` resets it, ``SendPolicyInstructions`` loads a "policy",
``SendObservations`` queues the newest observation, ``GetActions`` answers the chunk predicted from
it or no actions when none arrived within ``obs_queue_timeout``), with numpy arrays standing in
for torch tensors. The "policy" is a Python function, so tests script what the robot should do;
:class:`ReachPolicy` moves every joint toward a target pose at a bounded step per action.

Faults for bad-input tests: ``nan`` (a chunk of NaN), ``wrong_dim`` (one entry too many),
``hang`` (GetActions never answers in time), ``empty`` (always no actions).

Run it in its own process (to kill it by PID mid-goal)::

    python tests/servers/policy_server.py --port 50123 --target '{"j1": 0.5}' --step 0.05
"""

from __future__ import annotations

import argparse
import contextlib
import json
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent import futures
from pathlib import Path
from typing import Any

import grpc
import numpy as np

if __package__ in (None, ""):  # run as a script: make the project importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))

from agents_core.clients.lerobot import protocol as wire

__all__ = ["PolicyFunction", "PolicyTestServer", "ReachPolicy"]

#: (observation, policy setup) -> action chunk (n_actions, action_dim).
PolicyFunction = Callable[[wire.TimedObservation, wire.RemotePolicyConfig], np.ndarray]

_MAX_BYTES = 64 * 1024 * 1024


def state_names(setup: wire.RemotePolicyConfig) -> list[str]:
    """The joint names of the policy's ``observation.state`` feature, in order."""
    return list(setup.lerobot_features["observation.state"]["names"])


class ReachPolicy:
    """Moves each joint of ``observation.state`` toward ``target`` by at most ``step`` per action."""

    def __init__(self, target: dict[str, float], step: float = 0.05) -> None:
        self.target = dict(target)
        self.step = step

    def __call__(self, obs: wire.TimedObservation, setup: wire.RemotePolicyConfig) -> np.ndarray:
        names = state_names(setup)
        current = np.array([float(obs.observation[n]) for n in names])
        goal = np.array([self.target.get(n, c) for n, c in zip(names, current, strict=True)])
        rows = []
        for i in range(1, setup.actions_per_chunk + 1):
            rows.append(current + np.clip(goal - current, -self.step * i, self.step * i))
        return np.array(rows, dtype=np.float32)


class PolicyTestServer:
    """The server; a context manager that starts it on a free port of 127.0.0.1 and stops it.

    :param policy: what a chunk is, from an observation (default: hold the observed state).
    :param fault: None, ``"nan"``, ``"wrong_dim"``, ``"hang"`` or ``"empty"``.
    :param obs_queue_timeout: how long GetActions waits for an observation before answering none.
    :param port: 0 picks a free port.
    :param actions_payload: when set, GetActions answers exactly these bytes (a hostile server).
    """

    def __init__(self, policy: PolicyFunction | None = None, fault: str | None = None,
                 obs_queue_timeout: float = 2.0, port: int = 0, actions_payload: bytes | None = None) -> None:
        self.policy: PolicyFunction = policy or (lambda obs, setup: np.array(
            [[float(obs.observation[n]) for n in state_names(setup)]] * setup.actions_per_chunk, np.float32))
        self.fault = fault
        self.actions_payload = actions_payload
        self.obs_queue_timeout = obs_queue_timeout
        self.setups: list[wire.RemotePolicyConfig] = []
        self.observations: list[wire.TimedObservation] = []
        self.ready_calls = 0
        self.chunks_sent = 0
        self._queue: queue.Queue[wire.TimedObservation] = queue.Queue(maxsize=1)
        self._stopped = threading.Event()
        self._server = grpc.server(futures.ThreadPoolExecutor(max_workers=4),
                                   options=[("grpc.max_receive_message_length", _MAX_BYTES),
                                            ("grpc.max_send_message_length", _MAX_BYTES)])
        handlers = {
            "Ready": grpc.unary_unary_rpc_method_handler(self._ready, wire.Empty.FromString,
                                                         wire.Empty.SerializeToString),
            "SendPolicyInstructions": grpc.unary_unary_rpc_method_handler(
                self._setup, wire.PolicySetup.FromString, wire.Empty.SerializeToString),
            "SendObservations": grpc.stream_unary_rpc_method_handler(
                self._observations, wire.Observation.FromString, wire.Empty.SerializeToString),
            "GetActions": grpc.unary_unary_rpc_method_handler(self._get_actions, wire.Empty.FromString,
                                                              wire.Actions.SerializeToString),
        }
        self._server.add_generic_rpc_handlers((grpc.method_handlers_generic_handler(wire.SERVICE, handlers),))
        self.port = self._server.add_insecure_port(f"127.0.0.1:{port}")
        if self.port == 0:
            raise OSError(f"policy test server: cannot listen on 127.0.0.1:{port}")

    # -- the service ------------------------------------------------------------------------------

    def _ready(self, request: Any, context: grpc.ServicerContext) -> Any:
        self.ready_calls += 1
        self._queue = queue.Queue(maxsize=1)
        return wire.Empty()

    def _setup(self, request: Any, context: grpc.ServicerContext) -> Any:
        setup = wire.loads_payload(request.data, max_bytes=_MAX_BYTES, what="policy setup")
        if not isinstance(setup, wire.RemotePolicyConfig):
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, f"expected a RemotePolicyConfig, got {type(setup)}")
        self.setups.append(setup)
        return wire.Empty()

    def _observations(self, chunks: Iterator[Any], context: grpc.ServicerContext) -> Any:
        obs = wire.loads_payload(wire.join_chunks(chunks, max_bytes=_MAX_BYTES), max_bytes=_MAX_BYTES,
                                 what="observation")
        if not isinstance(obs, wire.TimedObservation):
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, f"expected a TimedObservation, got {type(obs)}")
        self.observations.append(obs)
        with contextlib.suppress(queue.Empty):  # the newest observation replaces one still waiting
            self._queue.get_nowait()
        self._queue.put_nowait(obs)
        return wire.Empty()

    def _get_actions(self, request: Any, context: grpc.ServicerContext) -> Any:
        if self.actions_payload is not None:
            return wire.Actions(data=self.actions_payload)
        if self.fault == "hang":
            self._stopped.wait(60.0)
            return wire.Actions()
        if self.fault == "empty" or not self.setups:
            time.sleep(min(self.obs_queue_timeout, 0.05))
            return wire.Actions()
        try:
            obs = self._queue.get(timeout=self.obs_queue_timeout)
        except queue.Empty:
            return wire.Actions()
        chunk = np.asarray(self.policy(obs, self.setups[-1]), dtype=np.float32)
        if self.fault == "nan":
            chunk = np.full_like(chunk, np.nan)
        elif self.fault == "wrong_dim":
            chunk = np.concatenate([chunk, np.zeros((chunk.shape[0], 1), np.float32)], axis=1)
        actions = [wire.TimedAction(timestamp=obs.timestamp, timestep=obs.timestep + i, action=row)
                   for i, row in enumerate(chunk)]
        self.chunks_sent += 1
        return wire.Actions(data=wire.dumps_payload(actions))

    # -- running ----------------------------------------------------------------------------------

    def start(self) -> PolicyTestServer:
        self._server.start()
        return self

    def stop(self) -> None:
        self._stopped.set()
        self._server.stop(grace=0).wait(5.0)

    def __enter__(self) -> PolicyTestServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--target", default="{}", help="JSON joint name -> target position (ReachPolicy)")
    parser.add_argument("--step", type=float, default=0.05)
    parser.add_argument("--fault", default=None)
    args = parser.parse_args(argv)
    server = PolicyTestServer(ReachPolicy(json.loads(args.target), args.step), fault=args.fault, port=args.port)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    server.start()
    print(f"policy server listening on 127.0.0.1:{server.port}", flush=True)
    try:
        done.wait(600.0)  # a test server never outlives a test run by much
    finally:
        server.stop()


if __name__ == "__main__":
    main()
