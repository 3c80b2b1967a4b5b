"""Simulated worlds: Reacher-v5 (160x120 camera) driven by the scripted expert, through the framework and alone.

One child process measures, for each transport (memory, and Zenoh / ROS 2 where installed, all in lock-step):

- ``steps_per_s``: environment steps per second inside episodes. framework: ``GymWorld`` publishes each
  observation, the ``ReacherExpert`` component answers on ``action``, the world steps (the episodes' own
  wall time, from the results lines); raw: the same expert's ``act`` and ``env.step`` + ``render`` in a loop.
  The first episode of each side is a warm-up, left out of the step rate.
- ``episodes_per_s``: whole evaluations. framework: ``run_evaluation`` (launcher start, episodes,
  results.jsonl and thumbnails, stop); raw: the same episodes written against the environment alone
  (make, reset, step + render, the success rule, one JSON line per episode, close).

The ratio (framework / raw, higher is better for rates) is the framework's cost; target >= 0.8 for the
step rate. ``python -m benchmarks.sim --episodes N`` is the child; :func:`run_suite` runs it.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import REPO, ChildFailed, Children, available, child_env, emit, free_tcp_port, log

STEPS = 50  # Reacher-v5's episode


def unavailable_reason() -> str | None:
    """Why the sim suite cannot run here, or None."""
    if not (available("gymnasium") and available("mujoco")):
        return "the sim extra (gymnasium, mujoco) is not installed"
    return None


def _raw(episodes: int, seed: int, out: Path) -> tuple[float, float]:
    """(seconds stepping, seconds for the whole loop) of the expert against Reacher-v5 alone."""
    import numpy as np  # noqa: PLC0415
    from evaluate_reacher import ReacherExpert  # noqa: PLC0415

    from agents_core.sim.env_host import make_env  # noqa: PLC0415

    act = ReacherExpert().act
    start = time.perf_counter()
    env = make_env("Reacher-v5", {}, (160, 120))
    stepping = 0.0
    with (out / "raw.jsonl").open("w", encoding="utf-8") as results:
        for episode in range(episodes):
            begin = time.perf_counter()
            observation, _ = env.reset(seed=seed + episode)
            env.render()
            rewards = []
            for _ in range(STEPS):
                observation, reward, _terminated, _truncated, _info = env.step(act(observation))
                env.render()
                rewards.append(float(reward))
            if episode:  # the first episode warms up (first render, caches), on both sides
                stepping += time.perf_counter() - begin
            success = bool(np.linalg.norm(observation[8:10]) < 0.02)
            results.write(json.dumps({"episode": episode, "success": success, "rewards": rewards}) + "\n")
    env.close()
    return stepping, time.perf_counter() - start


def _framework(episodes: int, seed: int, out: Path, transport: str) -> tuple[float, float, int]:
    """(seconds stepping, seconds for the whole evaluation, successes) through run_evaluation."""
    from evaluate_reacher import evaluation  # noqa: PLC0415

    from agents_core.evals import run_evaluation  # noqa: PLC0415

    options = {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"], "connect": []} if transport == "zenoh" else None
    start = time.perf_counter()
    run = run_evaluation(evaluation("expert", episodes, seed), out / transport, transport=transport,
                         transport_options=options, progress=False, report=False)
    total = time.perf_counter() - start
    # The first episode also waits out each new Zenoh publisher's first match (match_timeout): warm-up.
    return sum(r["wall_s"] for r in run.results[1:]), total, run.successes


def run_child(episodes: int, rounds: int, transports: list[str]) -> None:
    sys.path.insert(0, str(REPO / "examples"))
    with tempfile.TemporaryDirectory(prefix="bench-sim-") as tmp:
        out = Path(tmp)
        for _ in range(rounds):
            for transport in transports:
                steps = (episodes - 1) * STEPS  # the first episode of each side warms up
                raw_stepping, raw_total = _raw(episodes, 1000, out)
                fw_stepping, fw_total, successes = _framework(episodes, 1000, out, transport)
                for mode, stepping, total in (("raw", raw_stepping, raw_total), ("framework", fw_stepping, fw_total)):
                    emit({"suite": "sim", "transport": transport, "payload": "reacher_v5_160x120", "mode": mode,
                          "steps_per_s": steps / stepping, "episodes_per_s": episodes / total, "episodes": episodes,
                          **({"successes": successes} if mode == "framework" else {})})


def run_suite(settings: dict[str, Any], transports: list[str], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The sim child on each transport; (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"sim: skipped: {reason}")
        return [], [{"suite": "sim", "transport": "all", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    try:
        child = children.start("sim", ["-m", "benchmarks.sim", "--episodes", str(settings.get("sim_episodes", 5)),
                                       "--rounds", str(settings.get("rounds", 1)),
                                       "--transports", ",".join(transports)], child_env(ros_domain))
        records += list(child.records(timeout=900))
        children.stop(child)
        for r in records:
            progress(f"{'sim':<10} {r['transport']:<6} {r['mode']:<9} {r['steps_per_s']:8.0f} steps/s "
                     f"{r['episodes_per_s']:6.2f} episodes/s")
    except ChildFailed as exc:
        progress(f"sim: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": "sim", "transport": "all", "mode": "both", "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=5, help="at least 2 (the first warms up)")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--transports", default="memory")
    args = parser.parse_args(argv)
    run_child(max(2, args.episodes), args.rounds, [t for t in args.transports.split(",") if t])
    log("sim done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
