"""``run_evaluation``: run an :class:`~agents_core.evals.Evaluation`'s episodes and write its results directory.

The world and the recipe run under one :class:`~agents_core.Launcher` on the transport asked for
(the world in a process of its own with ``world_process=True``: every component then gets one).
Each episode is one call of the world's ``run_episode`` action through ``<world>/execute_method``,
so it is the same on every transport and wherever the world runs. Episodes run one after another.

The output directory (the format s7-evalreport's report reads, docs/evaluate.md):
``evaluation.json`` (written at the start, rewritten at the end), ``results.jsonl`` (one line per
finished episode, flushed as each ends: Ctrl-C keeps what finished), ``frames/`` (thumbnails) and
``report.html``.

What can go wrong ends one episode, not the evaluation: the world reports an environment that
raised, hung or returned NaN as ``ended="error"`` with a reason; a world process that dies
(its pid gone or changed under a running episode) is ``ended="world_died"``, and the next episode
waits (bounded) for the launcher to respawn it. Ctrl-C stops the running episode
(``ended="interrupted"``), writes the report of what finished and returns.

``workers=N`` (memory transport) runs N worlds side by side, each with its own recipe and launcher.
"""

from __future__ import annotations

import concurrent.futures
import datetime as dt
import json
import os
import queue
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any, Protocol

from attrs import define, field

from ..errors import ConfigError
from ..launch.launcher import Launcher
from ..support.version import package_version
from ..transport.registry import TRANSPORT_ENV_VAR
from .evaluation import Evaluation

__all__ = ["EpisodeHooks", "EvaluationRun", "run_evaluation"]

#: Seconds the runner waits, beyond an episode's own limits, before calling it lost.
EPISODE_MARGIN_S = 30.0
#: Seconds a world in its own process gets to come back after it died.
RESPAWN_WAIT_S = 60.0


class EpisodeHooks(Protocol):
    """Called around each episode, in the runner's process (e.g. an episode recorder)."""

    def on_episode_start(self, episode: int, seed: int) -> None:
        """Episode ``episode`` is about to reset with ``seed``."""

    def on_episode_end(self, result: dict[str, Any]) -> None:
        """Episode ended: ``result`` is its results.jsonl line."""


@define
class EvaluationRun:
    """What :func:`run_evaluation` did: where, the episodes' lines, whether Ctrl-C cut it short."""

    out_dir: Path
    results: list[dict[str, Any]] = field(factory=list)
    interrupted: bool = False
    report: Path | None = None

    @property
    def successes(self) -> int:
        """Episodes that succeeded."""
        return sum(1 for r in self.results if r["success"])

    @property
    def success_rate(self) -> float:
        """Successes over finished episodes (0 when none finished)."""
        return self.successes / len(self.results) if self.results else 0.0


def _now() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")


def _progress(total: int, enabled: bool) -> Any:
    if not enabled:
        return None
    from .progress import EpisodeProgress  # noqa: PLC0415

    return EpisodeProgress(total, stream=sys.stderr)


def _write_report(out_dir: Path) -> Path | None:
    from .report import write_report  # noqa: PLC0415

    return write_report(out_dir)


def _failed(episode: int, seed: int, ended: str, reason: str, wall_s: float) -> dict[str, Any]:
    return {"episode": episode, "seed": seed, "success": False, "reward_sum": 0.0, "steps": 0,
            "time_to_success_s": None, "steps_to_success": None, "wall_s": wall_s, "ended": ended,
            "reason": reason, "rewards": [], "frames": []}


def _line(episode: int, result: Mapping[str, Any]) -> dict[str, Any]:
    keys = ("seed", "success", "reward_sum", "steps", "time_to_success_s", "steps_to_success", "wall_s", "ended",
            "reason", "rewards", "frames")
    return {"episode": episode, **{k: result.get(k) for k in keys}}


class _Episodes:
    """Runs episodes through the world's ``run_episode`` service, telling a dead world from a slow one."""

    def __init__(self, launcher: Launcher, world: Any, evaluation: Evaluation, out_dir: Path) -> None:
        self.launcher, self.world, self.evaluation, self.out_dir = launcher, world, evaluation, out_dir
        self.name = world.component_name
        config = world.config
        self.call_timeout = (evaluation.max_wall_s or 0.0) + EPISODE_MARGIN_S + config.step_timeout
        if evaluation.max_wall_s is None:
            steps = evaluation.max_steps or config.max_steps or 10_000
            self.call_timeout += steps * (config.step_timeout if config.clock == "lockstep" else 1.0)
        self.call_timeout = min(self.call_timeout, 86_000.0)
        self.gone = False

    def _pid(self) -> int | None:
        supervisor = self.launcher.supervisor
        return None if supervisor is None else supervisor.pids().get(self.name)

    def _crashes(self) -> int:
        supervisor = self.launcher.supervisor
        return 0 if supervisor is None else supervisor.child(self.name).crashes

    def _crashed_since(self, crashes: int, wait: float = 0.0) -> bool:
        """Whether the world's process crashed since it had ``crashes`` (waiting up to ``wait`` s to be told)."""
        if self.launcher.supervisor is None:
            return False
        deadline = time.monotonic() + wait
        while self._crashes() == crashes:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)
        return True

    def _submit(self, episode: int, seed: int) -> concurrent.futures.Future[dict[str, Any]]:
        """:meth:`_call` on a daemon thread of its own: a request left waiting on a world that died (on ROS 2 it
        waits out its whole timeout) must hold up neither the next episode's request nor the interpreter's exit."""
        future: concurrent.futures.Future[dict[str, Any]] = concurrent.futures.Future()

        def call() -> None:
            if not future.set_running_or_notify_cancel():
                return
            try:
                future.set_result(self._call(episode, seed))
            except BaseException as exc:
                future.set_exception(exc)

        threading.Thread(target=call, name=f"eval-episode-{episode}", daemon=True).start()
        return future

    def _call(self, episode: int, seed: int) -> dict[str, Any]:
        kwargs = {"seed": seed, "max_steps": self.evaluation.max_steps, "max_wall_s": self.evaluation.max_wall_s,
                  "frames_dir": str(self.out_dir / "frames"), "frame_prefix": f"ep{episode:04d}"}
        reply = self.launcher.transport.request(f"{self.name}/execute_method",
                                                {"method": "run_episode", "kwargs": kwargs,
                                                 "timeout": self.call_timeout}, timeout=self.call_timeout + 5.0)
        result = reply.get("result")
        if not isinstance(result, dict):
            raise ConfigError(f"world {self.name!r}: run_episode answered {result!r}")
        return result

    def answers(self, timeout: float) -> bool:
        """Whether the world answers on ``execute_method`` within ``timeout`` s (asked again until then).

        A request sent before this process's client has discovered a (re)started world may be lost on
        ROS 2 (the dead server still looks ready), and would then wait out the whole episode's timeout: the
        episode is only sent once this same service answers (``stop_episode``: nothing runs between episodes).
        """
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                self.launcher.transport.request(f"{self.name}/execute_method", {"method": "stop_episode"},
                                                timeout=min(2.0, max(left, 0.1)))
                return True
            except Exception:  # not there yet: no server, or no answer in time
                time.sleep(0.1)

    def wait_respawned(self) -> bool:
        deadline = time.monotonic() + RESPAWN_WAIT_S
        while time.monotonic() < deadline:
            if self._pid() is not None and self.launcher.all_active():
                return self.answers(deadline - time.monotonic())
            time.sleep(0.1)
        return False

    def run(self, episode: int, seed: int) -> dict[str, Any]:
        start = time.monotonic()
        if self.gone:
            return _failed(episode, seed, "world_died", "the world process died and did not come back", 0.0)
        crashes = self._crashes()
        future = self._submit(episode, seed)
        try:
            while True:
                try:
                    return _line(episode, future.result(timeout=0.2))
                except concurrent.futures.TimeoutError:
                    if self._crashed_since(crashes):
                        return self._died(episode, seed, start, "the world process died during the episode")
        except KeyboardInterrupt:
            self.interrupt()
            try:
                return _line(episode, future.result(timeout=10.0))
            except Exception:
                raise KeyboardInterrupt from None
        except Exception as exc:
            if self._crashed_since(crashes, wait=3.0):
                return self._died(episode, seed, start, f"the world process died ({type(exc).__name__}: {exc})")
            return _failed(episode, seed, "error", f"run_episode failed: {type(exc).__name__}: {exc}",
                           time.monotonic() - start)

    def _died(self, episode: int, seed: int, start: float, reason: str) -> dict[str, Any]:
        result = _failed(episode, seed, "world_died", reason, time.monotonic() - start)
        if not self.wait_respawned():
            self.gone = True
        return result

    def interrupt(self) -> None:
        if self.launcher.supervisor is None:
            self.world.stop_episode()

    def close(self) -> None:
        """Nothing to wait for: a request still out ends with the launcher's transport."""


def _metadata(evaluation: Evaluation, world: Any, agents: Sequence[Any], transport: str | None,
              seeds: list[int]) -> dict[str, Any]:
    """evaluation.json, as written at the start (``finished`` still None)."""
    return {
        "name": evaluation.name, "world": world.env_id,
        "recipe": evaluation.recipe_name or " + ".join(type(c).__name__ for c in agents),
        "transport": transport or os.environ.get(TRANSPORT_ENV_VAR, "").strip() or "memory",
        "clock": world.config.clock, "episodes": len(seeds), "seeds": seeds,
        "success_rule": world.success_rule.describe(),
        "limits": {"max_steps": evaluation.max_steps, "max_wall_s": evaluation.max_wall_s},
        "started": _now(), "finished": None, "interrupted": False, "agents_core_version": package_version()}


def _run_episodes(episodes: _Episodes, seeds: list[int], hooks: Sequence[EpisodeHooks], bar: Any,
                  run: EvaluationRun) -> None:
    """Each episode in turn, its line written and flushed as it ends; stops at Ctrl-C."""
    with (run.out_dir / "results.jsonl").open("a", encoding="utf-8") as results:
        for index, episode_seed in enumerate(seeds):
            for hook in hooks:
                hook.on_episode_start(index, episode_seed)
            try:
                line = episodes.run(index, episode_seed)
            except KeyboardInterrupt:
                run.interrupted = True
                return
            results.write(json.dumps(line) + "\n")
            results.flush()
            run.results.append(line)
            for hook in hooks:
                hook.on_episode_end(line)
            if bar is not None:
                bar.episode_done(bool(line["success"]), float(line["wall_s"]))
            if line["ended"] == "interrupted":
                run.interrupted = True
                return


def _run_parallel(runners: Sequence[_Episodes], seeds: list[int], hooks: Sequence[EpisodeHooks], bar: Any,
                  run: EvaluationRun) -> None:
    """The episodes spread over several worlds, each on a thread of its own; lines written as episodes end."""
    jobs: queue.SimpleQueue[tuple[int, int]] = queue.SimpleQueue()
    for job in enumerate(seeds):
        jobs.put(job)
    done: queue.SimpleQueue[dict[str, Any]] = queue.SimpleQueue()
    stop, hook_lock = threading.Event(), threading.Lock()

    def work(runner: _Episodes) -> None:
        while not stop.is_set():
            try:
                index, episode_seed = jobs.get_nowait()
            except queue.Empty:
                return
            with hook_lock:
                for hook in hooks:
                    hook.on_episode_start(index, episode_seed)
            done.put(runner.run(index, episode_seed))

    threads = [threading.Thread(target=work, args=(r,), name=f"eval-worker-{i}", daemon=True)
               for i, r in enumerate(runners)]
    for thread in threads:
        thread.start()

    def record(line: dict[str, Any], results: IO[str]) -> None:
        results.write(json.dumps(line) + "\n")
        results.flush()
        run.results.append(line)
        with hook_lock:
            for hook in hooks:
                hook.on_episode_end(line)
        if bar is not None:
            bar.episode_done(bool(line["success"]), float(line["wall_s"]))
        if line["ended"] == "interrupted":
            run.interrupted = True

    with (run.out_dir / "results.jsonl").open("a", encoding="utf-8") as results:
        try:
            while len(run.results) < len(seeds) and (any(t.is_alive() for t in threads) or not done.empty()):
                try:
                    record(done.get(timeout=0.2), results)
                except queue.Empty:
                    continue
        except KeyboardInterrupt:
            run.interrupted = True
            stop.set()
            for runner in runners:
                runner.interrupt()
            for thread in threads:
                thread.join(timeout=15.0)
            while not done.empty():
                record(done.get_nowait(), results)
    run.results.sort(key=lambda line: int(line["episode"]))


def _launcher(components: Sequence[Any], transport: str | None, options: Mapping[str, Any] | None,
              world_process: bool, respawns: int) -> Launcher:
    launcher = Launcher(transport=transport, transport_options=options, quiet=True)
    launcher.add_pkg(components=list(components), multiprocessing=world_process)
    if world_process:
        launcher.on_process_fail(max_retries=respawns)
    return launcher


def _start(launcher: Launcher, name: str, timeout: float) -> None:
    launcher.start()
    deadline = time.monotonic() + timeout
    while not launcher.all_active():
        if time.monotonic() > deadline:
            raise ConfigError(f"evaluation {name!r}: the components were not all active after {timeout:g} s")
        time.sleep(0.05)


def run_evaluation(evaluation: Evaluation, out_dir: str | Path, *, transport: str | None = "memory",
                   transport_options: Mapping[str, Any] | None = None, episodes: int | None = None,
                   seed: int | None = None, world_process: bool = False,
                   episode_hooks: Sequence[EpisodeHooks] = (), progress: bool = True,
                   report: bool = True, start_timeout: float = 120.0, respawns: int = 3,
                   workers: int = 1) -> EvaluationRun:
    """Run ``evaluation``'s episodes and write its results directory ``out_dir`` (see the module docs).

    :param transport: ``"memory"``, ``"zenoh"``, ``"ros2"`` (None: ``AGENTS_TRANSPORT``).
    :param episodes: / ``seed``: override the evaluation's.
    :param world_process: run the components in processes of their own (a cross-process transport).
    :param episode_hooks: called around each episode (see :class:`EpisodeHooks`).
    :param progress: show episodes done, success so far and the time left on stderr.
    :param report: write ``report.html`` at the end.
    :param respawns: with ``world_process``, how many times a crashed component process is started again.
    :param workers: episodes run at once, each set in a world (and recipe) of its own: memory transport only
        (each launcher has its own). Results are the same as with one worker (lock-step: each episode depends
        only on its seed); lines are written in the order episodes end. Episode hooks may then overlap.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"run_evaluation: workers must be an int >= 1, got {workers!r}")
    if workers > 1 and (transport or os.environ.get(TRANSPORT_ENV_VAR, "").strip() or "memory") != "memory":
        raise ConfigError(f"run_evaluation: workers={workers} runs several worlds side by side, which only the "
                          f"memory transport keeps apart; use workers=1 on {transport!r}")
    seeds = evaluation.seed_list(episodes, seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.jsonl").unlink(missing_ok=True)
    world = evaluation.world()
    agents = list(evaluation.recipe())
    meta = _metadata(evaluation, world, agents, transport, seeds)
    (out / "evaluation.json").write_text(json.dumps(meta, indent=2), encoding="utf-8")
    sets = [(world, agents)] + [(evaluation.world(), list(evaluation.recipe())) for _ in range(1, workers)]
    launchers = [_launcher([w, *a], transport, transport_options, world_process, respawns) for w, a in sets]
    run = EvaluationRun(out_dir=out)
    bar = _progress(len(seeds), progress)
    runners: list[_Episodes] = []
    try:
        for launcher, (set_world, _agents) in zip(launchers, sets, strict=True):
            _start(launcher, evaluation.name, start_timeout)
            runner = _Episodes(launcher, set_world, evaluation, out)
            if not runner.answers(start_timeout):
                raise ConfigError(f"evaluation {evaluation.name!r}: the world {runner.name!r} does not answer "
                                  f"requests after {start_timeout:g} s")
            runners.append(runner)
        if workers == 1:
            _run_episodes(runners[0], seeds, episode_hooks, bar, run)
        else:
            _run_parallel(runners, seeds, episode_hooks, bar, run)
    except KeyboardInterrupt:
        run.interrupted = True
    finally:
        for runner in runners:
            runner.close()
        if bar is not None:
            bar.close()
        for launcher in launchers:
            launcher.stop()
        meta.update(finished=_now(), interrupted=run.interrupted)
        (out / "evaluation.json").write_text(json.dumps(meta, indent=2), encoding="utf-8")
    if report:
        run.report = _write_report(out)
    return run
