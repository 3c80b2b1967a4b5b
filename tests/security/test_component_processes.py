"""A component process never outlives its launcher, stopped or not, and what it starts ends with it, killed
outright or not (issue 36, item 11). Real processes: a launcher running ``spawning_recipe.py`` on Zenoh with
the component in a process of its own, which starts two ``sleep`` processes (one orphaned at once).
With a child that ignores SIGTERM and a second component, the fork server that ends a killed component's
orphans goes on (and the bystander with it), and leaves alone the process its own import of a module
started (review s9, findings 1 and 6)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

from ..launch.helpers import REPO, alive, child_pids, direct_children, parent_pid, wait_for

pytestmark = pytest.mark.timeout(120)
RECIPE = Path(__file__).with_name("spawning_recipe.py")
GONE_WITHIN_S = 10.0


class _Run:
    def __init__(self, tmp: Path, *options: str) -> None:
        self.markers = tmp / "markers"
        self.markers.mkdir()
        self.log_path = tmp / "launcher.log"
        self._log = self.log_path.open("wb")
        self.proc = subprocess.Popen([sys.executable, str(RECIPE), "--port", str(free_tcp_port()),
                                      "--markers", str(self.markers), *options], stdout=self._log,
                                     stderr=subprocess.STDOUT, cwd=REPO,
                                     env={**os.environ, "SPAWNING_MARKERS": str(self.markers)})
        self.pids: set[int] = set()

    def log(self) -> str:
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def started(self) -> tuple[int, list[int]]:
        """The component process's pid and the pids of the sleeps it started, once both are up."""
        def found() -> tuple[int, list[int]] | None:
            if self.proc.poll() is not None:
                raise AssertionError(f"the launcher exited with {self.proc.returncode}:\n{self.log()[-3000:]}")
            files = sorted(self.markers.glob("pids.*"))
            if not files or files[0].read_text().count("\n") < 2:
                return None
            return int(files[0].suffix[1:]), [int(p) for p in files[0].read_text().split()]

        component, sleeps = wait_for(found, timeout=60.0, what="the component to start its processes")
        self.pids |= {component, *sleeps, *child_pids(self.proc.pid)}
        return component, sleeps

    def bystander(self) -> tuple[int, dict[int, int]]:
        """The bystander component's pid and, by importer pid, the helpers its module's import started."""
        def found() -> int | None:
            files = list(self.markers.glob("bystander.*"))
            return int(files[0].suffix[1:]) if files else None

        bystander = wait_for(found, timeout=60.0, what="the bystander component to start")
        helpers = {int(f.suffix[1:]): int(f.read_text()) for f in self.markers.glob("helper.*")}
        self.pids |= {bystander, *helpers.values()}
        return bystander, helpers

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)
        for pid in self.pids:  # whatever the test left, by pid
            if alive(pid):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGCONT)
                    os.kill(pid, signal.SIGKILL)
        self._log.close()


def _running(tmp: Path, *options: str) -> Iterator[_Run]:
    skip_unless_installed("zenoh")
    if not sys.platform.startswith("linux"):
        pytest.skip("PR_SET_CHILD_SUBREAPER and /proc are Linux's")
    r = _Run(tmp, *options)
    try:
        yield r
    finally:
        r.close()


@pytest.fixture
def run(tmp_path: Path) -> Iterator[_Run]:
    yield from _running(tmp_path)


@pytest.fixture
def stubborn(tmp_path: Path) -> Iterator[_Run]:
    """The spawner's direct child ignores SIGTERM, and a bystander component runs beside it."""
    yield from _running(tmp_path, "--stubborn", "--bystander")


def _gone_within(pids: list[int], limit: float) -> float | None:
    start = time.monotonic()
    while time.monotonic() - start < limit:
        if not any(alive(p) for p in pids):
            return time.monotonic() - start
        time.sleep(0.05)
    return None


def test_a_stopped_component_process_ends_when_its_launcher_is_killed(run: _Run) -> None:
    component, sleeps = run.started()
    os.kill(component, signal.SIGSTOP)
    time.sleep(0.2)
    run.proc.send_signal(signal.SIGKILL)
    run.proc.wait(timeout=10)
    gone = _gone_within([component], GONE_WITHIN_S)
    assert gone is not None, f"the SIGSTOPped component process {component} outlived its launcher"
    print(f"stopped component gone {gone:.2f} s after its launcher's SIGKILL")
    assert _gone_within(sleeps, GONE_WITHIN_S) is not None, "what the component started outlived it"


def test_what_a_component_starts_ends_with_a_clean_stop(run: _Run) -> None:
    component, sleeps = run.started()
    assert all(alive(p) for p in sleeps)
    run.proc.send_signal(signal.SIGTERM)
    run.proc.wait(timeout=30)
    assert _gone_within([component], GONE_WITHIN_S) is not None
    assert _gone_within(sleeps, GONE_WITHIN_S) is not None, \
        f"processes {[p for p in sleeps if alive(p)]} started by the component outlived a clean stop"


def test_what_a_component_starts_ends_when_the_component_is_killed_outright(run: _Run) -> None:
    component, sleeps = run.started()
    assert all(alive(p) for p in sleeps)
    os.kill(component, signal.SIGKILL)  # it cannot end them itself: they are re-parented to the fork server
    assert _gone_within([component], GONE_WITHIN_S) is not None
    gone = _gone_within(sleeps, GONE_WITHIN_S)
    assert gone is not None, f"processes {[p for p in sleeps if alive(p)]} started by the killed component outlived it"
    print(f"a SIGKILLed component's processes gone {gone:.2f} s after it")
    assert run.proc.poll() is None, "the launcher goes on (it gives up on the component)"


def _kill_spawner(run: _Run) -> tuple[int, int, list[int], dict[int, int]]:
    """SIGKILL the spawner once both components are up: the fork server, the bystander, the spawner's
    sleeps (re-parented to the server) and the helpers that importing the bystander's module started."""
    component, sleeps = run.started()
    bystander, helpers = run.bystander()
    server = parent_pid(component)
    assert parent_pid(bystander) == server and server in helpers, "both forked by the server, which imported"
    run.pids.add(server)
    os.kill(component, signal.SIGKILL)
    assert _gone_within([component], GONE_WITHIN_S) is not None
    return server, bystander, sleeps, helpers


def test_the_fork_server_outlives_the_orphan_of_a_killed_component_that_ignores_sigterm(stubborn: _Run) -> None:
    """The orphan ignores SIGTERM and has a child that does too (an orphan's orphan, re-parented to the server
    when the orphan is SIGKILLed): both end, the server and the bystander go on."""
    direct = stubborn.started()[1][0]
    grandchild = wait_for(lambda: direct_children(direct), timeout=10.0, what="the stubborn child's own child")
    stubborn.pids |= set(grandchild)
    server, bystander, sleeps, _ = _kill_spawner(stubborn)
    sleeps = [*sleeps, *grandchild]
    gone = _gone_within(sleeps, GONE_WITHIN_S)
    assert gone is not None, f"orphans {[p for p in sleeps if alive(p)]} outlived the killed component"
    print(f"the killed component's orphans (one ignores SIGTERM) gone {gone:.2f} s after it")
    time.sleep(1.0)  # the server's passes after the SIGKILL it sent
    assert alive(server), f"the fork server died:\n{stubborn.log()[-3000:]}"
    assert alive(bystander), "the bystander component stopped with the server"
    assert "OverflowError" not in stubborn.log() and "Traceback" not in stubborn.log()


def test_the_process_the_fork_servers_own_import_started_is_no_orphan(stubborn: _Run) -> None:
    server, bystander, sleeps, helpers = _kill_spawner(stubborn)
    assert _gone_within(sleeps, GONE_WITHIN_S) is not None, "the killed component's orphans are still ended"
    time.sleep(1.0)
    assert alive(helpers[server]), "the fork server ended the helper its import of bystander_component started"
    assert alive(bystander) and alive(server)
