""":class:`agents_core.launch.descendants.Orphans` on real child processes of this test (review s9, findings 1
and 6): a child filed as this process's own is never signalled, and an orphan already SIGKILLed leaves no
timeout (it used to leave ``inf``, which ``select`` cannot take)."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from agents_core.launch.descendants import Orphans

from .helpers import alive, wait_for

pytestmark = [pytest.mark.timeout(60),
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")]


@pytest.fixture
def started() -> Iterator[list[subprocess.Popen[bytes]]]:
    procs: list[subprocess.Popen[bytes]] = []
    yield procs
    for proc in procs:  # by pid, whatever the test left
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=5.0)


def _stubborn(procs: list[subprocess.Popen[bytes]]) -> subprocess.Popen[bytes]:
    """``sleep 30`` that ignores SIGTERM, once it does."""
    proc = subprocess.Popen(["sh", "-c", "trap '' TERM; exec sleep 30"])
    procs.append(proc)

    def execed() -> bool:
        with open(f"/proc/{proc.pid}/cmdline", "rb") as f:
            return f.read().startswith(b"sleep")

    wait_for(execed, timeout=10.0, what="the shell to set its trap and exec sleep")
    return proc


def test_an_orphan_sigkilled_leaves_no_timeout_and_the_servers_own_child_is_left_alone(
        started: list[subprocess.Popen[bytes]]) -> None:
    own = subprocess.Popen(["sleep", "30"])
    started.append(own)
    orphans = Orphans(grace=0.05)
    assert orphans.sort({own.pid}, orphaned=False) == 0
    assert orphans.timeout() is None
    orphan = _stubborn(started)
    assert orphans.sort({own.pid, orphan.pid}, orphaned=True) == 1  # only the new one
    due = orphans.timeout()
    assert due is not None and 0.0 <= due <= 0.05
    time.sleep(0.2)
    assert alive(orphan.pid), "it ignores SIGTERM"
    orphans.kill_due()
    assert orphans.timeout() is None, "nothing is due: the SIGKILLed one waits only to be reaped"
    assert orphan.wait(timeout=5.0) == -9
    assert orphans.reaped(orphan.pid), "it was an orphan: what it leaves behind is too"
    assert orphans.sort({own.pid}, orphaned=True) == 0
    assert own.poll() is None, "the child filed as its own was never signalled"
    assert not orphans.reaped(own.pid)
