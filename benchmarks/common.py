"""What every benchmark shares: payloads, statistics, child processes, loopback-only settings.

Child processes speak to the runner in JSON lines on stdout (:func:`emit`); everything else they
print goes to stderr (or a log file). Every child is started by :class:`Child`, which stops it by
PID (SIGTERM, then SIGKILL after a grace period) and reaps it; :class:`Children` does that for
all of them in a ``finally``, whatever happened.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import queue
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

REPO = Path(__file__).resolve().parents[1]

#: The small message: a 64-character (64-byte) str whose first 10 characters carry the sequence number.
STRING_BYTES = 64
#: The large message: a 640x480 rgb8 image (921,600 bytes of pixels).
IMAGE_SHAPE = (480, 640, 3)
IMAGE_BYTES = IMAGE_SHAPE[0] * IMAGE_SHAPE[1] * IMAGE_SHAPE[2]
PAYLOADS = {"string64": STRING_BYTES, "image640x480": IMAGE_BYTES}

#: Topic names of the relay (the framework prefixes its Zenoh namespace; ROS 2 makes them absolute).
TOPICS = {"string64": ("bench/str_in", "bench/str_out"), "image640x480": ("bench/img_in", "bench/img_out")}

READY = "READY"


def string_payload(seq: int) -> str:
    """The 64-byte string of sequence number ``seq``."""
    head = f"{seq:010d}"
    return head + "x" * (STRING_BYTES - len(head))


def string_seq(text: str) -> int:
    return int(text[:10])


def image_pixels() -> Any:
    """A deterministic 640x480x3 uint8 image (not constant, so nothing can compress it away)."""
    import numpy as np  # noqa: PLC0415  (children only)

    return (np.arange(IMAGE_BYTES, dtype=np.uint32) % 251).astype(np.uint8).reshape(IMAGE_SHAPE)


# -- statistics -----------------------------------------------------------------------------------


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q``-th percentile (0..100) by linear interpolation between closest ranks."""
    if not values:
        raise ValueError("no values")
    ordered = sorted(values)
    pos = (len(ordered) - 1) * q / 100.0
    low = int(pos)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (pos - low)


def summarize_ns(samples_ns: Sequence[int]) -> dict[str, float]:
    """Median, p99, mean, min and max of durations in ns, as microseconds."""
    us = [s / 1000.0 for s in samples_ns]
    return {"n": len(us), "median_us": statistics.median(us), "p99_us": percentile(us, 99.0),
            "mean_us": statistics.fmean(us), "min_us": min(us), "max_us": max(us)}


# -- talking to the runner ------------------------------------------------------------------------


def emit(record: dict[str, Any]) -> None:
    """Send one JSON record to the runner (one line on stdout)."""
    sys.stdout.write(json.dumps(record) + "\n")
    sys.stdout.flush()


def log(message: str) -> None:
    """A progress or diagnostic line of a child (stderr, never parsed)."""
    print(message, file=sys.stderr, flush=True)


class StopFlag:
    """Set by SIGTERM / SIGINT, so a child's serving loop can end cleanly."""

    def __init__(self) -> None:
        self.event = threading.Event()
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, lambda *_: self.event.set())

    def wait(self, timeout: float) -> bool:
        return self.event.wait(timeout)


# -- environment ----------------------------------------------------------------------------------


def available(module: str) -> bool:
    """Whether ``module`` can be found (without importing it)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def free_tcp_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def fastdds_shm_profile() -> str | None:
    """The framework's Fast DDS profile (16 MB shared memory), found without importing rclpy."""
    spec = importlib.util.find_spec("agents_ros2")
    if spec is None or not spec.submodule_search_locations:
        return None
    path = Path(next(iter(spec.submodule_search_locations))) / "fastdds_shm.xml"
    return str(path) if path.is_file() else None


def child_env(ros_domain: int | None = None) -> dict[str, str]:
    """The environment of a child: unbuffered, the repository importable, ROS 2 kept on this host.

    Both the framework's and the raw ROS 2 processes get the same Fast DDS profile (the
    framework's 16 MB shared-memory segment), so images take the same path in both.
    """
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if ros_domain is not None:
        env["ROS_DOMAIN_ID"] = str(ros_domain)
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    profile = fastdds_shm_profile()
    if profile is not None:
        env.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", profile)
    return env


def zenoh_raw_config(listen: list[str], connect: list[str]) -> Any:
    """A plain ``zenoh.Config``: peer, explicit loopback endpoints, multicast scouting off."""
    import zenoh  # noqa: PLC0415  (children only)

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return conf


def zenoh_framework_options(listen: list[str], connect: list[str], namespace: str) -> dict[str, Any]:
    """``transport_options`` of the framework's Zenoh transport with the same endpoints."""
    return {"mode": "peer", "listen": listen, "connect": connect, "namespace": namespace,
            "multicast_scouting": False}


# -- child processes ------------------------------------------------------------------------------


class ChildFailed(RuntimeError):
    """A child exited early, or did not say what it should have in time."""


class Child:
    """One child process: started with ``Popen``, read line by line, stopped and reaped by PID."""

    def __init__(self, name: str, argv: list[str], env: dict[str, str], log_path: Path) -> None:
        self.name = name
        self.log_path = log_path
        self._log: IO[str] = log_path.open("w")
        self._lines: queue.SimpleQueue[str | None] = queue.SimpleQueue()
        self.proc = subprocess.Popen([sys.executable, *argv], cwd=REPO, env=env, stdin=subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=self._log, text=True)
        self._reader = threading.Thread(target=self._read, name=f"read:{name}", daemon=True)
        self._reader.start()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._lines.put(line.rstrip("\n"))
        self._lines.put(None)

    def log_tail(self, chars: int = 2000) -> str:
        self._log.flush()
        try:
            return self.log_path.read_text(errors="replace")[-chars:]
        except OSError:
            return ""

    def records(self, timeout: float) -> Iterator[dict[str, Any]]:
        """The child's JSON records until it closes stdout; ChildFailed if none comes for ``timeout`` s."""
        while True:
            try:
                line = self._lines.get(timeout=timeout)
            except queue.Empty:
                raise ChildFailed(f"{self.name}: nothing for {timeout:g} s\n{self.log_tail()}") from None
            if line is None:
                return
            if line.startswith("{"):
                yield json.loads(line)

    def wait_ready(self, timeout: float) -> None:
        """Wait for the child's READY line."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise ChildFailed(f"{self.name} was not ready within {timeout:g} s\n{self.log_tail()}")
            try:
                line = self._lines.get(timeout=left)
            except queue.Empty:
                continue
            if line is None:
                raise ChildFailed(f"{self.name} exited (rc={self.proc.wait()}) before it was ready\n"
                                  f"{self.log_tail()}")
            if line.strip() == READY:
                return

    def stop(self, grace: float = 10.0) -> int | None:
        """SIGTERM by PID, SIGKILL by PID after ``grace`` s; always reaped. Returns the exit code."""
        try:
            if self.proc.poll() is None:
                os.kill(self.proc.pid, signal.SIGTERM)
                try:
                    self.proc.wait(timeout=grace)
                except subprocess.TimeoutExpired:
                    os.kill(self.proc.pid, signal.SIGKILL)
                    self.proc.wait(timeout=10)
            return self.proc.returncode
        finally:
            # The reader sees end-of-file once the process is gone; close the pipe after it.
            self._reader.join(timeout=2.0)
            if self.proc.stdout is not None and not self._reader.is_alive():
                self.proc.stdout.close()
            self._log.close()


class Children:
    """Every child of a run, stopped in reverse start order by :meth:`stop_all`."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self._children: list[Child] = []

    def start(self, name: str, argv: list[str], env: dict[str, str]) -> Child:
        child = Child(name, argv, env, self.log_dir / f"{name}.log")
        self._children.append(child)
        return child

    def stop(self, child: Child, grace: float = 10.0) -> int | None:
        if child in self._children:
            self._children.remove(child)
        return child.stop(grace)

    def stop_all(self) -> None:
        while self._children:
            self._children.pop().stop(grace=5.0)


def wait_until(predicate: Callable[[], bool], timeout: float, interval: float = 0.01) -> bool:
    """Poll ``predicate`` until it holds or ``timeout`` s pass."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return predicate()


def run_memory_child(suite: str, settings: dict[str, Any], children: Children, progress: Callable[[str], None], *,
                     reps: int, warmup: int, what: str) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Run ``python -m benchmarks.<suite> --reps N --warmup M`` as the suite's child (memory transport).

    N and M come from ``settings`` (``<suite>_reps`` / ``<suite>_warmup``), else ``reps`` / ``warmup``;
    each record's p50 is reported as ``what``. Returns (records, skipped).
    """
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    try:
        child = children.start(suite, ["-m", f"benchmarks.{suite}", "--reps", str(settings.get(f"{suite}_reps", reps)),
                                       "--warmup", str(settings.get(f"{suite}_warmup", warmup))], child_env())
        records += list(child.records(timeout=600))
        children.stop(child)
        for r in records:
            progress(f"{suite:<10} {'memory':<6} {r['mode']:<9} {r['latency_ms']['p50']:8.2f} ms {what}")
    except ChildFailed as exc:
        progress(f"{suite}: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": suite, "transport": "memory", "mode": "framework", "reason": str(exc)[-1500:]})
    return records, skipped


def child_main(argv: list[str] | None, description: str | None, run: Callable[[int, int], None], *, name: str,
               reps: int, warmup: int) -> int:
    """A suite child's command line (``--reps``, ``--warmup``): runs ``run(reps, warmup)``."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reps", type=int, default=reps)
    parser.add_argument("--warmup", type=int, default=warmup)
    args = parser.parse_args(argv)
    run(args.reps, args.warmup)
    log(f"{name} done")
    return 0
