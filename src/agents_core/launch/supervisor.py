"""``Supervisor``: starts one process per component, respawns crashed ones, stops them in order.

Every child is started by the supervisor's own thread (``PR_SET_PDEATHSIG`` fires when the
*thread* that started a child ends, so that thread lives as long as the supervisor). A child
that exits while it should run is respawned after a backoff (``backoff_s`` doubled per
consecutive crash, at most ``max_backoff_s``), up to ``max_retries`` times; then the supervisor
logs the give-up and calls ``on_giveup(component_name)``.

A child killed by a signal cannot remove its shared-memory segments (Zenoh's, Fast DDS's) from
/dev/shm. The supervisor notes the segments each child maps while it runs; after a crash, each
of them is unlinked as soon as no live process maps it any more (peers that received from the
dead child keep its segment mapped until they let go of it).

Given a :class:`~agents_core.launch.fork_server.ForkServer`, children (respawns included) are
forked by it instead of started as fresh interpreters; if it cannot, the child is spawned.

A child's death wakes the supervisor's thread at once (its report pipe ends; for a forked child
the server's exit notice comes too), and a child to respawn without delay is started before the
crashed one's shared-memory segments are looked for (a scan of every process's maps): a respawn
waits for neither a poll period nor the clean-up.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import IO, Any

from ..errors import ComponentError
from .fork_server import ForkedProcess, ForkServer, ForkServerError
from .spec import ComponentSpec

__all__ = ["ChildProcess", "Supervisor"]

logger = logging.getLogger(__name__)

_POLL_S = 0.01
_SHM_DIR = "/dev/shm/"
_SHM_BYTES = _SHM_DIR.encode()


def _mapped_shm(pid: int) -> set[str]:
    """The /dev/shm files process ``pid`` maps now (empty when it is gone)."""
    # Read whole and searched as bytes: a middleware process maps thousands of regions, and
    # splitting every line of every process's maps made a scan cost ~0.15 s of CPU.
    try:
        with open(f"/proc/{pid}/maps", "rb") as maps:
            data = maps.read()
    except OSError:
        return set()
    found: set[str] = set()
    start = data.find(_SHM_BYTES)
    while start != -1:
        end = data.find(b"\n", start)
        end = len(data) if end == -1 else end
        if data[start - 1:start] == b" ":  # the pathname field starts here (not a path merely containing it)
            path = data[start:end].decode("utf-8", "replace").rstrip()
            if "/" not in path[len(_SHM_DIR):]:
                found.add(path.removesuffix(" (deleted)"))
        start = data.find(_SHM_BYTES, end)
    return found


def _open_shm(pid: int) -> set[str]:
    """The /dev/shm files process ``pid`` holds open."""
    found: set[str] = set()
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return found
    for fd in fds:
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith(_SHM_DIR):
            found.add(target)
    return found


def _still_mapped(paths: set[str]) -> set[str]:
    """Those of ``paths`` some live process maps or holds open (a segment shared with others stays)."""
    used: set[str] = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            used |= (_mapped_shm(int(entry)) | _open_shm(int(entry))) & paths
            if used == paths:
                break
    return used


def _segments_since(started: float) -> set[str]:
    """Zenoh and Fast DDS segments created since ``started`` (wall clock), shared port segments excepted.

    A child killed just after it created a segment may not have been seen mapping it; any such
    segment that no live process uses is its leftover (or another crashed process's).
    """
    found: set[str] = set()
    try:
        names = os.listdir(_SHM_DIR)
    except OSError:
        return found
    for name in names:
        if not (name.endswith(".zenoh") or (name.startswith("fastrtps_") and "port" not in name)):
            continue
        with contextlib.suppress(OSError):
            if os.stat(_SHM_DIR + name).st_ctime >= started - 1.0:
                found.add(_SHM_DIR + name)
    return found


#: The longest report line a child may write (a state and an error of at most 2000 characters fit).
MAX_REPORT_CHARS = 16_384


class ChildProcess:
    """One component's process, its reports and its history."""

    def __init__(self, spec: ComponentSpec, fork_server: ForkServer | None = None) -> None:
        self.spec = spec
        #: Forks the process (its respawns too) when given; else a fresh interpreter each time.
        self.fork_server = fork_server
        self.name = spec.component_name
        self.proc: subprocess.Popen[bytes] | ForkedProcess | None = None
        self.state = "unconfigured"
        self.error: str | None = None
        #: Whether a process of this component ever became active (else a give-up is a failed start).
        self.was_active = False
        #: The health its process last reported ("-" before any report).
        self.health = "-"
        self.restarts = 0
        self.crashes = 0
        self.gave_up = False
        self.respawn_at: float | None = None
        #: The process whose exit was last counted as a crash (each exit counts once).
        self.counted_exit: object | None = None
        self.shm: set[str] = set()
        self.spawned_at = 0.0
        #: Called when the process may have ended (its report pipe ended, or the fork server said so).
        self.on_exit: Callable[[], None] | None = None
        self.state_changed = threading.Condition()
        self._reader: threading.Thread | None = None

    @property
    def pid(self) -> int | None:
        return self.proc.pid if self.proc is not None else None

    def spawn(self) -> None:
        """Start the process (forked by :attr:`fork_server` if set) and write its spec to its stdin."""
        server = self.fork_server
        read_fd, write_fd = os.pipe()
        self.spawned_at = time.time()
        try:
            self.proc = self._fork(server, write_fd) if server is not None else None
            if self.proc is None:
                self.proc = subprocess.Popen(
                    [sys.executable, "-m", "agents_core.launch.child", "--report-fd", str(write_fd)],
                    stdin=subprocess.PIPE, pass_fds=(write_fd,), close_fds=True)
        except BaseException:
            os.close(read_fd)
            raise
        finally:
            os.close(write_fd)
        with self.state_changed:
            self.state, self.error, self.health = "starting", None, "-"
        self._reader = threading.Thread(target=self._read_reports, args=(os.fdopen(read_fd, "r"),),
                                        name=f"reports:{self.name}", daemon=True)
        self._reader.start()
        spec = self.spec.to_dict()
        if isinstance(self.proc, ForkedProcess):  # it has the fork server's environment: the changes since
            spec["environment"] = self.proc.environment
        self.send(json.dumps(spec))

    def _fork(self, server: ForkServer, report_fd: int) -> ForkedProcess | None:
        """The process forked by ``server``; None (after a warning) when it cannot fork one."""
        stdin_read, stdin_write = os.pipe()
        try:
            environment = server.environment_changes()  # now, at each start: respawns see the launcher's of then
            proc = server.fork(self.name, stdin_read, report_fd, stdin_write)
            proc.on_exit = self.on_exit
            proc.environment = environment
            return proc
        except ForkServerError as exc:
            os.close(stdin_write)
            logger.warning("component %r: the fork server did not start its process (%s); starting a fresh "
                           "interpreter", self.name, exc)
            return None
        finally:
            os.close(stdin_read)

    def send(self, line: str) -> bool:
        """Write one line to the child's stdin; False when it is gone."""
        proc = self.proc
        if proc is None or proc.stdin is None:
            return False
        try:
            proc.stdin.write(line.encode("utf-8") + b"\n")
            proc.stdin.flush()
            return True
        except (BrokenPipeError, OSError, ValueError):
            return False

    def _read_reports(self, pipe: IO[str]) -> None:
        # The child (and anything it runs) writes here: a line is read at most MAX_REPORT_CHARS at a
        # time, a longer one skipped whole, and only a JSON object counts as a report.
        with pipe:
            while line := pipe.readline(MAX_REPORT_CHARS):
                if not line.endswith("\n"):
                    while line and not line.endswith("\n"):
                        line = pipe.readline(MAX_REPORT_CHARS)
                    continue
                try:
                    report = json.loads(line)
                except ValueError:
                    continue
                if not isinstance(report, dict):
                    continue
                with self.state_changed:
                    if "state" in report:
                        self.state = str(report["state"])
                        self.was_active = self.was_active or self.state == "active"
                    if "health" in report:
                        self.health = str(report["health"])[:40]
                    if "error" in report:
                        self.error = str(report["error"])[:2000]
                    self.state_changed.notify_all()
        with self.state_changed:
            self.state_changed.notify_all()
        if self.on_exit is not None:
            self.on_exit()

    def wait_state(self, states: Sequence[str], timeout: float) -> bool:
        """Wait until the child reports one of ``states``; False on timeout or when it exits first."""
        deadline = time.monotonic() + timeout
        with self.state_changed:
            while self.state not in states:
                if self.proc is not None and self.proc.poll() is not None and self.state not in states:
                    return False
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self.state_changed.wait(min(left, 0.05))
        return True

    def close_pipes(self) -> None:
        proc = self.proc
        if proc is not None and proc.stdin is not None:
            with contextlib.suppress(OSError):
                proc.stdin.close()


def remove_unmapped(paths: set[str]) -> set[str]:
    """Unlink those of ``paths`` that no live process maps; returns the ones still in use."""
    if not paths:
        return set()
    in_use = _still_mapped(paths)
    for path in sorted(paths - in_use):
        try:
            os.unlink(path)
            logger.debug("removed %s, left by a crashed component process", path)
        except FileNotFoundError:
            pass
        except OSError as exc:
            logger.warning("could not remove %s, left by a crashed component process: %s", path, exc)
    return in_use


class Supervisor:
    """Runs ``specs`` as child processes (see the module docstring)."""

    def __init__(self, specs: Sequence[ComponentSpec], *, max_retries: int = 3,
                 on_giveup: Callable[[str], None] | None = None, backoff_s: float = 0.05,
                 max_backoff_s: float = 2.0, start_timeout: float = 60.0,
                 fork_server: ForkServer | None = None) -> None:
        self.children = [ChildProcess(spec, fork_server) for spec in specs]
        # Set when a child may have ended or a spawn is asked for: the thread's wait ends at once.
        self._wake = threading.Event()
        for child in self.children:
            child.on_exit = self._wake.set
        self.max_retries = max_retries
        self.backoff_s = backoff_s
        self.max_backoff_s = max_backoff_s
        self.start_timeout = start_timeout
        self._on_giveup = on_giveup
        self._stopping = threading.Event()
        # The thread ends only after every child has: PR_SET_PDEATHSIG fires when the thread that
        # started a child ends, which would signal the children in the middle of an ordered stop.
        self._finished = threading.Event()
        self._spawn_requests: list[tuple[ChildProcess, threading.Event]] = []
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._orphan_shm: set[str] = set()

    def child(self, name: str) -> ChildProcess:
        for c in self.children:
            if c.name == name:
                return c
        raise ComponentError(f"no component process named {name!r}")

    # -- starting -------------------------------------------------------------------------------

    def start(self) -> None:
        """Start every child and wait until all are active; ComponentError naming the first that is not."""
        self._thread = threading.Thread(target=self._run, name="component-supervisor", daemon=True)
        self._thread.start()
        for child in self.children:
            self._spawn_on_thread(child)
        deadline = time.monotonic() + self.start_timeout
        for child in self.children:
            if not child.wait_state(("active",), max(0.0, deadline - time.monotonic())):
                rc = child.proc.poll() if child.proc is not None else None
                why = child.error or (f"its process exited with status {rc}" if rc is not None
                                      else f"not active after {self.start_timeout:g} s")
                raise ComponentError(f"component {child.name!r} did not start in its process: {why}")

    def _spawn_on_thread(self, child: ChildProcess) -> None:
        done = threading.Event()
        with self._lock:
            self._spawn_requests.append((child, done))
        self._wake.set()
        if not done.wait(30.0):
            raise ComponentError(f"component {child.name!r}: the supervisor did not start its process")
        if child.proc is None:
            raise ComponentError(f"component {child.name!r}: its process could not be started: {child.error}")

    def all_active(self) -> bool:
        return all(c.state == "active" for c in self.children)

    # -- the supervisor's thread ----------------------------------------------------------------

    def _run(self) -> None:
        last_shm_scan = 0.0
        while not self._finished.is_set():
            self._wake.clear()  # before the checks: a wake-up during them ends the next wait at once
            with self._lock:
                requests, self._spawn_requests = self._spawn_requests, []
            for child, done in requests:
                self._spawn(child)
                done.set()
            now = time.monotonic()
            scan = now - last_shm_scan > 0.5
            if scan:
                last_shm_scan = now
                self.remove_orphan_shm()
            for child in self.children:
                self._watch(child, now, scan)
            self._wake.wait(_POLL_S)
        with self._lock:
            requests, self._spawn_requests = self._spawn_requests, []
        for _, done in requests:
            done.set()

    def _spawn(self, child: ChildProcess) -> None:
        try:
            child.spawn()
        except OSError as exc:
            child.error = f"cannot start a process: {exc}"
            child.proc = None

    def _watch(self, child: ChildProcess, now: float, scan_shm: bool) -> None:
        proc = child.proc
        if proc is None:
            return
        if child.respawn_at is not None:
            if now >= child.respawn_at and not self._stopping.is_set():
                self._respawn(child)
            return
        code = proc.poll()
        if code is None:
            if scan_shm or (child.state == "active" and not child.shm):
                child.shm |= _mapped_shm(proc.pid)
            return
        if child.gave_up or child.state == "finalized" or self._stopping.is_set() or child.counted_exit is proc:
            return
        child.counted_exit = proc
        child.crashes += 1
        child.close_pipes()
        # Listed now, before a respawn creates segments of its own; removed after it (the scan is slow).
        self._orphan_shm |= child.shm | _segments_since(child.spawned_at)
        child.shm = set()
        with child.state_changed:
            child.state = "crashed"
            child.state_changed.notify_all()
        if child.restarts >= self.max_retries and not child.was_active and child.error:
            # It never started (a missing model file, a bad config): not a crash, and a respawn would fail alike;
            # start() raises with the child's error, which names what failed ("failed to configure: ...").
            child.gave_up = True
            logger.debug("component %r did not start in its process (pid %d): %s", child.name, proc.pid, child.error)
            self.remove_orphan_shm()
            return
        if child.restarts >= self.max_retries:
            child.gave_up = True
            logger.error("giving up on component %r after %d restart(s) (%d/%d): its process (pid %d) exited with "
                         "status %s", child.name, child.restarts, child.restarts, self.max_retries, proc.pid, code)
            if self._on_giveup is not None:
                try:
                    self._on_giveup(child.name)
                except Exception:
                    logger.exception("the give-up action for %r failed", child.name)
            self.remove_orphan_shm()
            return
        delay = min(self.backoff_s * 2 ** child.restarts, self.max_backoff_s) if child.restarts else 0.0
        child.respawn_at = now + delay
        # One line says what happened and what comes next: "restart 2/3 in 1.0 s".
        logger.error("the process of component %r (pid %d) exited with status %s; restart %d/%d in %.1f s",
                     child.name, proc.pid, code, child.restarts + 1, self.max_retries, delay)
        if delay == 0.0:
            self._respawn(child)
        self.remove_orphan_shm()

    def _respawn(self, child: ChildProcess) -> None:
        child.respawn_at = None
        child.restarts += 1
        logger.warning("respawning the process of %r (restart %d/%d)", child.name, child.restarts, self.max_retries)
        self._spawn(child)

    # -- stopping -------------------------------------------------------------------------------

    def stop(self, timeout: float = 10.0) -> None:
        """Deactivate every child in reverse order, then shut each down; terminate or kill stragglers."""
        self._stopping.set()
        running = [c for c in reversed(self.children) if c.proc is not None and c.proc.poll() is None]
        for child in running:
            if child.state == "active" and child.send("deactivate"):
                child.wait_state(("inactive",), timeout)
        for child in running:
            child.send("shutdown")
            self._reap(child, timeout)
        for child in self.children:
            if child.proc is not None:
                self._reap(child, 0.0)
                child.close_pipes()
                if child.proc.returncode not in (0, None):
                    self._orphan_shm |= child.shm
                child.shm = set()
        self._finished.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.remove_orphan_shm()

    def remove_orphan_shm(self) -> None:
        """Unlink the segments of crashed children that no process maps any more (see the module doc)."""
        with self._lock:
            self._orphan_shm = remove_unmapped(self._orphan_shm)

    @staticmethod
    def _reap(child: ChildProcess, timeout: float) -> None:
        proc = child.proc
        assert proc is not None
        for step, wait in ((None, timeout), (proc.terminate, 2.0), (proc.kill, 5.0)):
            if step is not None:
                if proc.poll() is not None:
                    break
                step()
            try:
                proc.wait(timeout=wait)
                break
            except subprocess.TimeoutExpired:
                continue

    def pids(self) -> dict[str, int | None]:
        """The current process id of each component."""
        return {c.name: c.pid for c in self.children}

    def describe(self) -> list[dict[str, Any]]:
        """Name, pid, state, restarts of each child (for logs and tools)."""
        return [{"name": c.name, "pid": c.pid, "state": c.state, "restarts": c.restarts, "crashes": c.crashes,
                 "gave_up": c.gave_up, "health": c.health} for c in self.children]
