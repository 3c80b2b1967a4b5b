"""The policy path: one observation -> action chunk round trip through LeRobotClient, against the raw gRPC stub.

One child process starts the gRPC policy server double of ``tests/servers/policy_server.py`` on 127.0.0.1
(a policy that holds the observed state: the model is not what is measured) and sends the same
observation (6 joint values, one 224x224x3 camera image, a task) over and over:

- raw: what LeRobot's own robot client does per observation, with the channel's stubs: pickle a
  ``TimedObservation``, stream it in chunks (``SendObservations``), ``GetActions``, ``pickle.loads``.
- framework: ``LeRobotClient.inference`` (the contract checks, the restricted unpickler, the chunk as a
  float64 array).

latency = milliseconds per round trip (lower is better). ``python -m benchmarks.vla --reps N`` is the child;
:func:`run_suite` runs it.
"""

from __future__ import annotations

import argparse
import io
import pickle
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .common import ChildFailed, Children, available, child_env, emit, log

JOINTS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def unavailable_reason() -> str | None:
    """Why the vla suite cannot run here, or None."""
    if not (available("grpc") and available("google.protobuf")):
        return "the vla extra (grpcio, protobuf) is not installed"
    return None


def _observation() -> dict[str, Any]:
    rng = np.random.default_rng(0)
    return {"state": {j: float(i) * 0.1 for i, j in enumerate(JOINTS)},
            "images": {"front": rng.integers(0, 255, (224, 224, 3), dtype=np.uint8)}, "task": "pick the cube",
            "timestep": 0}


class _LeRobotInstalled(pickle.Unpickler):
    """Plain (unrestricted) unpickling, as in a process where lerobot is importable: its payload classes
    resolve to the same-field stand-ins, everything else as ``pickle.loads`` would."""

    def find_class(self, module: str, name: str) -> Any:
        if module == "lerobot.async_inference.helpers":
            from agents_core.clients.lerobot import protocol as wire  # noqa: PLC0415

            return getattr(wire, name)
        return super().find_class(module, name)


def run_child(reps: int, warmup: int) -> None:
    import grpc  # noqa: PLC0415

    from agents_core.clients.lerobot import LeRobotClient  # noqa: PLC0415
    from agents_core.clients.lerobot import protocol as wire  # noqa: PLC0415
    from agents_core.models import LeRobotPolicy  # noqa: PLC0415
    from tests.servers.policy_server import PolicyTestServer  # noqa: PLC0415

    model = LeRobotPolicy(name="bench", policy_type="act", actions_per_chunk=50, policy_device="cpu",
                          features={"observation.state": {"dtype": "float32", "shape": [6], "names": JOINTS},
                                    "observation.images.front": {"dtype": "image", "shape": [224, 224, 3],
                                                                 "names": ["height", "width", "channels"]}},
                          actions={"action": {"dtype": "float32", "shape": [6], "names": JOINTS}})
    obs = _observation()
    with PolicyTestServer() as server:
        client = LeRobotClient(model, port=server.port, allow_pickle=True, inference_timeout=10)
        client.check_connection()
        client.initialize()  # the raw side reuses the policy the server loaded for it

        channel = grpc.insecure_channel(f"127.0.0.1:{server.port}")
        send = channel.stream_unary(f"/{wire.SERVICE}/SendObservations",
                                    request_serializer=wire.Observation.SerializeToString,
                                    response_deserializer=wire.Empty.FromString)
        get = channel.unary_unary(f"/{wire.SERVICE}/GetActions", request_serializer=wire.Empty.SerializeToString,
                                  response_deserializer=wire.Actions.FromString)
        raw_observation = {**obs["state"], **obs["images"], "task": obs["task"]}

        def raw() -> Any:
            # The C pickler, as LeRobot's client (its classes are importable there; here the stand-ins' own path).
            payload = pickle.dumps(wire.TimedObservation(time.time(), 0, raw_observation, must_go=True))
            send(wire.chunk_payload(payload), timeout=10)
            answer = get(wire.Empty(), timeout=10)
            return _LeRobotInstalled(io.BytesIO(answer.data)).load()  # LeRobot's client: plain pickle.loads

        def framework() -> Any:
            return client.inference(obs)

        try:
            times_of: dict[str, list[float]] = {"raw": [], "framework": []}
            calls = {"raw": raw, "framework": framework}
            for _ in range(warmup):
                raw()
                framework()
            for rep in range(reps):  # interleaved, alternating which goes first, so drift hits both alike
                for mode in (("raw", "framework") if rep % 2 == 0 else ("framework", "raw")):
                    start = time.perf_counter()
                    calls[mode]()
                    times_of[mode].append((time.perf_counter() - start) * 1000.0)
            for mode, times in times_of.items():
                emit({"suite": "vla", "transport": "grpc", "payload": "6_joints_224x224_image_50_actions",
                      "mode": mode, "latency_ms": {"p50": statistics.median(times),
                                                   "p99": float(np.percentile(times, 99))}, "reps": reps})
        finally:
            channel.close()
            client.deinitialize()


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The vla child (raw then framework); (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"vla: skipped: {reason}")
        return [], [{"suite": "vla", "transport": "grpc", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    try:
        child = children.start("vla", ["-m", "benchmarks.vla", "--reps", str(settings.get("vla_reps", 100)),
                                       "--warmup", str(settings.get("vla_warmup", 10))], child_env())
        records += list(child.records(timeout=600))
        children.stop(child)
        for r in records:
            progress(f"{'vla':<10} {'grpc':<6} {r['mode']:<9} {r['latency_ms']['p50']:8.2f} ms per chunk")
    except ChildFailed as exc:
        progress(f"vla: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": "vla", "transport": "grpc", "mode": "both", "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reps", type=int, default=100)
    parser.add_argument("--warmup", type=int, default=10)
    args = parser.parse_args(argv)
    run_child(args.reps, args.warmup)
    log("vla done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
