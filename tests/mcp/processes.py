"""Child processes of the MCP tests: started in their own group, ended by PID (SIGTERM, then SIGKILL)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess


def stop_group(proc: subprocess.Popen[str], timeout: float = 15.0) -> None:
    """End ``proc``'s process group: SIGTERM, SIGKILL after ``timeout`` s; always reaped, its pipe closed."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=5)
    if proc.stdout is not None:
        proc.stdout.close()
