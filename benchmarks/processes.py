"""Processes: the five-component recipe with ``multiprocessing=True`` vs in one process; crash respawn.

Start-up: from ``Launcher.start()`` to all five components of
:func:`benchmarks.parts.five_stage_recipe` active, with each component in its own process
(``framework`` in the records) against the same recipe in one process (the reference, recorded
as ``raw`` so that the report's ratio is multiprocessing / one process). Each repetition builds a
new launcher; the first one in the process is a warm-up and is not counted.

Fork vs spawn: with ``multiprocessing=True`` the component processes are forked by the launcher's
pre-imported fork server (``process_start="fork"``, the default); the same recipe with
``process_start="spawn"`` (a fresh interpreter each) runs interleaved with it, rep by rep, in the
same process (``spawn_*`` fields). ``first_launch_ms`` is the warm-up, which starts the fork
server. ``uss_median_mb``: the memory only a component process holds (USS, from
``/proc/<pid>/smaps_rollup``), median over every component process of every repetition.

Respawn: with the recipe running in processes, SIGKILL one component's process and time until
its new process reports ``active`` to the launcher (median of ``processes_respawns``; the
launcher's ``on_process_fail`` backoff gives the first respawn no delay). The Zenoh launcher
listens on a fixed loopback port, which its children connect to.

``python -m benchmarks.processes --transport zenoh|ros2 --mode framework|raw --reps N --respawns M``
prints one record.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

from .common import ChildFailed, Children, child_env, emit, free_tcp_port

SUITE = "processes"


def uss_mb(pid: int) -> float:
    """Memory only this process holds (USS: Private_Clean + Private_Dirty of /proc/<pid>/smaps_rollup), MB."""
    total_kb = 0
    with open(f"/proc/{pid}/smaps_rollup") as f:
        for line in f:
            if line.startswith(("Private_Clean:", "Private_Dirty:", "Private_Hugetlb:")):
                total_kb += int(line.split()[1])
    return total_kb / 1024.0


def _launcher(transport: str, rep: int, multiprocessing: bool, start: str = "fork") -> Any:
    from agents_core import Launcher  # noqa: PLC0415

    from .common import zenoh_framework_options  # noqa: PLC0415
    from .parts import five_stage_recipe  # noqa: PLC0415

    options: dict[str, Any] = {}
    if transport == "zenoh":
        options = zenoh_framework_options([f"tcp/127.0.0.1:{free_tcp_port()}"], [],
                                          f"processes_{os.getpid()}_{rep}")
    launcher = Launcher(transport=transport, transport_options=options, process_start=start)
    launcher.add_pkg(components=five_stage_recipe(f"processes{rep}"), multiprocessing=multiprocessing)
    return launcher


def start_once(transport: str, rep: int, multiprocessing: bool, start: str = "fork",
               uss: list[float] | None = None) -> float:
    launcher = _launcher(transport, rep, multiprocessing, start)
    began = time.perf_counter()
    launcher.start()
    while not launcher.all_active():
        time.sleep(0.001)
    took = time.perf_counter() - began
    if uss is not None and launcher.supervisor is not None:
        uss.extend(uss_mb(pid) for pid in launcher.supervisor.pids().values() if pid is not None)
    launcher.stop()
    return took


def respawn_times(transport: str, count: int, start: str = "fork") -> list[float]:
    """SIGKILL a component process ``count`` times (round robin); seconds until it is active again."""
    launcher = _launcher(transport, 999, True, start)
    launcher.on_process_fail(max_retries=count + 1)
    launcher.start()
    times: list[float] = []
    try:
        supervisor = launcher.supervisor
        assert supervisor is not None
        for i in range(count):
            child = supervisor.children[i % len(supervisor.children)]
            old_pid = child.pid
            assert old_pid is not None
            killed = time.perf_counter()
            os.kill(old_pid, signal.SIGKILL)
            deadline = time.monotonic() + 30.0
            while not (child.pid != old_pid and child.state == "active"):
                if time.monotonic() > deadline:
                    raise RuntimeError(f"{child.name} was not active again 30 s after SIGKILL")
                time.sleep(0.0005)
            times.append(time.perf_counter() - killed)
            time.sleep(0.2)  # let the other processes settle before the next kill
    finally:
        launcher.stop()
    return times


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", choices=["zenoh", "ros2"], required=True)
    parser.add_argument("--mode", choices=["framework", "raw"], required=True)
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--respawns", type=int, default=10)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    multiprocessing = args.mode == "framework"
    first = time.perf_counter()
    start_once(args.transport, 0, multiprocessing)  # warm-up (with fork: starts the fork server)
    first_s = time.perf_counter() - first
    times: list[float] = []
    spawn_times: list[float] = []
    uss: list[float] = []
    spawn_uss: list[float] = []
    for rep in range(1, args.reps + 1):  # fork and spawn interleaved, in the same process
        times.append(start_once(args.transport, rep, multiprocessing, "fork", uss))
        if multiprocessing:
            spawn_times.append(start_once(args.transport, 100 + rep, True, "spawn", spawn_uss))
    record: dict[str, Any] = {"suite": SUITE, "payload": "five_components", "times_s": times,
                              "median_ms": statistics.median(times) * 1000.0, "min_ms": min(times) * 1000.0,
                              "max_ms": max(times) * 1000.0}
    if multiprocessing:
        record.update(first_launch_ms=first_s * 1000.0, spawn_times_s=spawn_times,
                      spawn_median_ms=statistics.median(spawn_times) * 1000.0,
                      uss_median_mb=statistics.median(uss), spawn_uss_median_mb=statistics.median(spawn_uss))
    if multiprocessing and args.respawns > 0:
        respawns = respawn_times(args.transport, args.respawns)
        spawn_respawns = respawn_times(args.transport, args.respawns, "spawn")
        record.update(respawn_s=respawns, respawn_median_ms=statistics.median(respawns) * 1000.0,
                      respawn_max_ms=max(respawns) * 1000.0, spawn_respawn_s=spawn_respawns,
                      spawn_respawn_median_ms=statistics.median(spawn_respawns) * 1000.0)
    emit(record)
    return 0


def run_suite(transports: list[str], settings: dict[str, Any], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """One child per cross-process transport and mode; (records, skipped)."""
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    for transport in transports:
        if transport == "memory":
            continue  # in one process by design: multiprocessing=True is refused there
        for mode in ("raw", "framework"):
            env = child_env(ros_domain if transport == "ros2" else None)
            child = children.start(f"processes-{transport}-{mode}", [
                "-m", "benchmarks.processes", "--transport", transport, "--mode", mode,
                "--reps", str(settings["processes_reps"]), "--respawns", str(settings["processes_respawns"])], env)
            try:
                for record in child.records(timeout=300.0):
                    record.update(transport=transport, mode=mode)
                    records.append(record)
                    what = "multiprocessing" if mode == "framework" else "one process"
                    progress(f"{'processes':<10} {transport:<6} {what:<15} start -> active median "
                             f"{record['median_ms']:8.1f} ms (n={len(record['times_s'])})"
                             + (f" (spawn {record['spawn_median_ms']:.1f} ms; USS per process "
                                f"{record['uss_median_mb']:.1f} MB, spawn {record['spawn_uss_median_mb']:.1f} MB)"
                                if "spawn_median_ms" in record else "")
                             + (f"; respawn SIGKILL -> active median {record['respawn_median_ms']:.0f} ms "
                                f"(max {record['respawn_max_ms']:.0f}, n={len(record['respawn_s'])}; spawn "
                                f"{record['spawn_respawn_median_ms']:.0f} ms)"
                                if "respawn_median_ms" in record else ""))
                rc = children.stop(child)
                if rc != 0:
                    raise ChildFailed(f"exited with {rc}\n{child.log_tail()}")
            except ChildFailed as exc:
                progress(f"processes {transport} {mode}: FAILED: {str(exc).splitlines()[0]}")
                skipped.append({"suite": SUITE, "transport": transport, "mode": mode, "reason": str(exc)[-1500:]})
            finally:
                children.stop(child)
    return records, skipped


if __name__ == "__main__":
    sys.exit(main())
