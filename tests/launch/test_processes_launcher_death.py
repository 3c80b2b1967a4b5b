"""A component process never outlives its launcher, even in the middle of a configure that never returns.

``slow_configure_recipe.py`` runs as the launcher process with one component in a process of its
own whose ``custom_on_configure`` sleeps (5 s, or an hour: a configure that never returns). The
tests wait for the child's ``configure.<pid>`` marker, then SIGKILL the launcher (or SIGTERM the
child) and poll the child's pid: it must be gone within a few seconds, and its
``custom_on_activate`` (which writes ``active.<pid>``) must never have run.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from agents_core.launch.spec import ComponentSpec
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

from .helpers import REPO, alive, child_pids, leftover_segments, mapped_shm, open_shm, shm_files, wait_for
from .slow_configure_recipe import SlowStart

RECIPE = Path(__file__).with_name("slow_configure_recipe.py")
#: The child should be gone within 2 s of its launcher's death; the assert leaves room for a busy machine.
GONE_WITHIN_S = 5.0
DOMAIN = int(os.environ.get("ROS_DOMAIN_ID") or 1 + os.getpid() % 100)


class SlowRecipe:
    """The launcher process of slow_configure_recipe.py and the pids it started."""

    def __init__(self, tmp: Path, transport: str, configure_s: float) -> None:
        self.markers = tmp / "markers"
        self.markers.mkdir()
        self.log_path = tmp / "launcher.log"
        self._log = self.log_path.open("wb")
        env = dict(os.environ)
        if transport == "ros2":
            env.update(ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(DOMAIN))
        argv = [sys.executable, str(RECIPE), "--transport", transport, "--port", str(free_tcp_port()),
                "--configure-s", str(configure_s), "--markers", str(self.markers)]
        self.proc = subprocess.Popen(argv, stdout=self._log, stderr=subprocess.STDOUT, cwd=REPO, env=env)
        self.kids: set[int] = set()

    def log(self) -> str:
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def configuring_child(self, timeout: float = 60.0) -> int:
        """The pid of the component process once it is inside its configure."""
        def marker() -> int | None:
            if self.proc.poll() is not None:
                raise AssertionError(f"the launcher exited with {self.proc.returncode}:\n{self.log()[-3000:]}")
            self.kids |= set(child_pids(self.proc.pid))
            found = sorted(self.markers.glob("configure.*"))
            return int(found[0].suffix[1:]) if found else None

        pid: int = wait_for(marker, timeout=timeout, what="the component process to enter its configure")
        assert pid in self.kids, (pid, self.kids)
        return pid

    def activated(self) -> list[str]:
        return sorted(p.name for p in self.markers.glob("active.*"))

    def stop(self) -> None:
        """Kill the launcher and, by pid, every process it started (whatever the test left)."""
        if self.proc.poll() is None:
            self.kids |= set(child_pids(self.proc.pid))
            self.proc.kill()
        self.proc.wait(timeout=10.0)
        for pid in self.kids:
            if alive(pid):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        self._log.close()


@contextlib.contextmanager
def slow_recipe(tmp: Path, transport: str, configure_s: float) -> Iterator[SlowRecipe]:
    if transport == "zenoh":
        skip_unless_installed("zenoh")
    else:
        skip_unless_installed("ros2")
    run = SlowRecipe(tmp, transport, configure_s)
    try:
        yield run
    finally:
        run.stop()


def _seconds_until_gone(pid: int, limit: float = GONE_WITHIN_S,
                        reap: subprocess.Popen[bytes] | None = None) -> float | None:
    """Poll ``pid`` (a zombie counts as gone) for up to ``limit`` s; the seconds it took, None if it lives."""
    start = time.monotonic()
    while time.monotonic() - start < limit:
        if reap is not None:
            reap.poll()
        if not alive(pid):
            return time.monotonic() - start
        time.sleep(0.01)
    return None


# --- the child process alone, its parent (this test) alive ---------------------------------------


class LoneChild:
    """``python -m agents_core.launch.child`` started from the test, configuring a SlowStart on ``memory``."""

    def __init__(self, tmp: Path, configure_s: float, **options: bool) -> None:
        self.markers = tmp / "markers"
        self.markers.mkdir()
        spec = ComponentSpec.from_component(SlowStart("slow", configure_s, str(self.markers), **options),
                                            "memory", {}, os.getpid())
        read_fd, write_fd = os.pipe()
        self.proc = subprocess.Popen([sys.executable, "-m", "agents_core.launch.child", "--report-fd", str(write_fd)],
                                     stdin=subprocess.PIPE, stderr=subprocess.DEVNULL, pass_fds=(write_fd,),
                                     cwd=REPO)
        os.close(write_fd)
        self._reports = os.fdopen(read_fd)
        self._read: list[dict[str, str]] = []
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(spec.to_dict()).encode() + b"\n")
        self.proc.stdin.flush()

    def wait_configuring(self) -> None:
        wait_for(lambda: self.proc.poll() is not None or list(self.markers.glob("configure.*")), timeout=30.0,
                 what="the child to enter its configure")
        assert self.proc.poll() is None, self.proc.returncode

    def _all_reports(self) -> list[dict[str, str]]:
        self._read.extend(json.loads(line) for line in self._reports)  # what came since the last call
        return self._read

    def reports(self) -> list[dict[str, str]]:
        """The state and error reports (the health reports, agents_core.launch.child_health, left out)."""
        return [r for r in self._all_reports() if "health" not in r]

    def health_reports(self) -> list[str]:
        return [r["health"] for r in self._all_reports() if "health" in r]

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10.0)
        if self.proc.stdin is not None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
        self._reports.close()


@contextlib.contextmanager
def lone_child(tmp: Path, configure_s: float, **options: bool) -> Iterator[LoneChild]:
    child = LoneChild(tmp, configure_s, **options)
    try:
        yield child
    finally:
        child.close()


@pytest.mark.parametrize("how", ["end of stdin", "shutdown line"])
def test_a_stop_on_the_pipe_during_a_configure_that_never_returns_ends_the_child(tmp_path: Path, how: str) -> None:
    with lone_child(tmp_path, -1.0) as child:
        child.wait_configuring()
        assert child.proc.stdin is not None
        if how == "shutdown line":
            child.proc.stdin.write(b"shutdown\n")
            child.proc.stdin.flush()
        else:
            child.proc.stdin.close()
        gone_s = _seconds_until_gone(child.proc.pid, reap=child.proc)
        assert gone_s is not None, f"the component process did not stop within {GONE_WITHIN_S} s ({how})"
        assert child.proc.wait(timeout=5.0) == 0
        reports = child.reports()
        assert not list(child.markers.glob("active.*"))
        # Asked to stop: reported finalized (the supervisor does not respawn it), never active.
        assert {"state": "active"} not in reports
        if how == "shutdown line":
            assert reports == [{"state": "finalized"}], reports


def test_a_configure_that_raises_is_reported_in_one_line_with_status_1(tmp_path: Path) -> None:
    with lone_child(tmp_path, 0.0, fail=True) as child:
        assert child.proc.wait(timeout=30.0) == 1
        reports = child.reports()
    assert any("configure failed on purpose" in r.get("error", "") for r in reports), reports
    assert not list(child.markers.glob("active.*"))


def test_a_quick_configure_still_activates_and_stops_cleanly(tmp_path: Path) -> None:
    with lone_child(tmp_path, 0.0) as child:
        wait_for(lambda: list(child.markers.glob("active.*")), timeout=30.0, what="the component to activate")
        assert child.proc.stdin is not None
        child.proc.stdin.write(b"deactivate\nshutdown\n")
        child.proc.stdin.flush()
        assert child.proc.wait(timeout=30.0) == 0
        assert child.reports() == [{"state": "active"}, {"state": "inactive"}, {"state": "finalized"}]
        assert child.health_reports()[:1] == ["healthy"]


def test_the_end_of_stdin_during_a_deactivate_that_never_returns_ends_the_child(tmp_path: Path) -> None:
    with lone_child(tmp_path, 0.0, stuck_deactivate=True) as child:
        wait_for(lambda: list(child.markers.glob("active.*")), timeout=30.0, what="the component to activate")
        assert child.proc.stdin is not None
        child.proc.stdin.write(b"deactivate\n")
        child.proc.stdin.flush()
        wait_for(lambda: list(child.markers.glob("deactivate.*")), timeout=10.0, what="the deactivate to begin")
        child.proc.stdin.close()  # the launcher is gone while the main thread is stuck in user code
        gone_s = _seconds_until_gone(child.proc.pid, reap=child.proc)
        assert gone_s is not None, f"the component process outlived its launcher by {GONE_WITHIN_S} s"


# --- a launcher and its component process -------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(("transport", "configure_s"), [
    pytest.param("zenoh", -1.0, marks=pytest.mark.zenoh, id="zenoh-configure-never-returns"),
    pytest.param("zenoh", 5.0, marks=pytest.mark.zenoh, id="zenoh-configure-takes-5s"),
    pytest.param("ros2", -1.0, marks=pytest.mark.ros2, id="ros2-configure-never-returns"),
])
def test_launcher_sigkilled_during_configure_the_child_exits_without_activating(
        tmp_path: Path, transport: str, configure_s: float) -> None:
    shm_before = shm_files()
    with slow_recipe(tmp_path, transport, configure_s) as run:
        child = run.configuring_child()
        configure_started = time.monotonic()
        launcher_segments = mapped_shm(run.proc.pid)
        child_segments = (mapped_shm(child) | open_shm(child)) - launcher_segments
        run.proc.kill()
        run.proc.wait(timeout=5.0)
        gone_s = _seconds_until_gone(child)
        print(f"{transport}: child {child} gone {gone_s} s after its launcher's SIGKILL")
        assert gone_s is not None, f"the component process outlived its launcher by {GONE_WITHIN_S} s"
        if configure_s > 0:
            # Until the configure would have ended: a child that lived on would have activated by then.
            time.sleep(max(0.0, configure_s + 1.0 - (time.monotonic() - configure_started)))
        assert run.activated() == [], "the component activated although its launcher was gone"
    if transport == "zenoh":
        # The child's own segments are gone; the SIGKILLed launcher's remain (nothing can clean up
        # after a SIGKILL in the process itself): remove those for the next tests. (Other tests on
        # this machine may leave segments meanwhile: only the two processes' own are looked at.)
        leftovers = leftover_segments(shm_before)
        assert not leftovers & child_segments, leftovers & child_segments
        for name in leftovers & launcher_segments:
            (Path("/dev/shm") / name).unlink(missing_ok=True)


@pytest.mark.slow
@pytest.mark.zenoh
def test_sigterm_to_a_child_stuck_in_configure_exits_it_promptly(tmp_path: Path) -> None:
    with slow_recipe(tmp_path, "zenoh", -1.0) as run:
        child = run.configuring_child()
        os.kill(child, signal.SIGTERM)
        gone_s = _seconds_until_gone(child)
        print(f"child {child} gone {gone_s} s after SIGTERM during its configure")
        assert gone_s is not None, f"a SIGTERM did not end the component process within {GONE_WITHIN_S} s"
        assert run.activated() == []
        # The launcher sees its component fail to start, names it, and does not leave a process behind.
        wait_for(lambda: run.proc.poll() is not None, timeout=30.0, what="the launcher to give up")
        assert "component 'slow' did not start in its process" in run.log()
        assert run.activated() == []
