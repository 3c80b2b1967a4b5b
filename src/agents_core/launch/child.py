"""The process of one component: ``python -m agents_core.launch.child --report-fd N``.

It reads its :class:`~agents_core.launch.spec.ComponentSpec` as the first line (JSON) of its
stdin, never from argv or the environment (a spec may hold an API key). Then it opens its own
transport, rebuilds the component, configures and activates it, and reports each state to the
launcher as a JSON line on the inherited pipe ``--report-fd``. Further stdin lines are commands
(``deactivate``, ``shutdown``).

It never outlives the launcher: ``PR_SET_PDEATHSIG`` sends it SIGTERM when the launcher dies,
and the end of its stdin (the launcher's end of the pipe closes with the launcher, whatever
killed it) starts the same shutdown. A shutdown that takes longer than
:data:`EXIT_DEADLINE_S` ends the process at once.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import logging
import os
import queue
import signal
import sys
import threading
from typing import IO, Any

__all__ = ["EXIT_DEADLINE_S", "main", "set_parent_death_signal"]

logger = logging.getLogger("agents_core.launch.child")

#: Longest the shutdown may take once the launcher is gone or asked for it.
EXIT_DEADLINE_S = 1.5
#: Longest first line (the spec) read from stdin.
MAX_SPEC_BYTES = 16 * 1024 * 1024
_PR_SET_PDEATHSIG = 1

def set_parent_death_signal(signum: int = signal.SIGTERM) -> bool:
    """Ask Linux to send ``signum`` when the parent dies (``prctl(PR_SET_PDEATHSIG)``); False elsewhere."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(_PR_SET_PDEATHSIG, signum, 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


class _Reporter:
    def __init__(self, fd: int) -> None:
        self._file: IO[str] = os.fdopen(fd, "w", buffering=1)
        self._lock = threading.Lock()

    def send(self, **message: Any) -> None:
        # The launcher may be gone: the end of stdin stops this process then.
        with self._lock, contextlib.suppress(OSError, ValueError):
            self._file.write(json.dumps(message) + "\n")


class _PipeLines:
    """Lines of a pipe read with ``os.read``: no buffered file object, whose lock a thread blocked
    in a read would hold at interpreter exit (and the exit would then abort)."""

    def __init__(self, fd: int) -> None:
        self._fd = fd
        self._buffer = b""

    def readline(self, limit: int) -> bytes | None:
        """The next line with its newline; None at the end of the pipe or past ``limit`` bytes."""
        while b"\n" not in self._buffer:
            if len(self._buffer) > limit:
                return None
            chunk = os.read(self._fd, 65536)
            if not chunk:
                return None
            self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line + b"\n"


def _read_commands(lines: _PipeLines, commands: queue.SimpleQueue[str]) -> None:
    while (raw := lines.readline(4096)) is not None:
        commands.put(raw.decode("utf-8", "replace").strip())
    commands.put("eof")


def _exit_soon(code: int) -> None:
    timer = threading.Timer(EXIT_DEADLINE_S, lambda: os._exit(code))
    timer.daemon = True
    timer.start()


def run(spec_line: bytes, reporter: _Reporter, stdin: _PipeLines) -> int:
    """Build, run and stop the component of ``spec_line``; the process's exit status."""
    from ..transport.registry import resolve_transport  # noqa: PLC0415
    from .recipe_import import import_recipe  # noqa: PLC0415
    from .spec import RECIPE_MODULE, ComponentSpec, decode_value  # noqa: PLC0415

    spec = ComponentSpec.from_dict(json.loads(spec_line))
    if spec.parent_pid and os.getppid() != spec.parent_pid:
        return 1  # the launcher died before PR_SET_PDEATHSIG was set
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format=f"[{spec.component_name} %(process)d] %(levelname)s %(name)s: %(message)s")
    if spec.recipe_path is not None:
        import_recipe(spec.recipe_path, RECIPE_MODULE)
    component = spec.build()
    transport = resolve_transport(spec.transport, **decode_value(spec.transport_options))
    commands: queue.SimpleQueue[str] = queue.SimpleQueue()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: commands.put("signal"))
    threading.Thread(target=_read_commands, args=(stdin, commands), name="launcher-pipe", daemon=True).start()
    try:
        component.runtime.bind(transport)
        component.configure()
        component.activate()
        reporter.send(state=component.lifecycle_state.value)
        while True:
            command = commands.get()
            if command == "deactivate":
                component.deactivate()
                reporter.send(state=component.lifecycle_state.value)
            elif command == "shutdown":
                break
            elif command in ("eof", "signal"):
                # The launcher is gone (or a signal came): stop now, and never hang doing it.
                _exit_soon(0)
                component.hurry_shutdown()
                break
    finally:
        try:
            component.shutdown()
        finally:
            transport.close()
    reporter.send(state="finalized")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agents_core.launch.child", description=__doc__)
    parser.add_argument("--report-fd", type=int, required=True, help="inherited pipe to report states on")
    args = parser.parse_args(argv)
    set_parent_death_signal(signal.SIGTERM)
    reporter = _Reporter(args.report_fd)
    stdin = _PipeLines(sys.stdin.fileno())
    spec_line = stdin.readline(MAX_SPEC_BYTES)
    if spec_line is None:
        reporter.send(error="no complete component spec on stdin")
        return 2
    try:
        return run(spec_line, reporter, stdin)
    except Exception as exc:
        logger.exception("component process failed")
        reporter.send(error=f"{type(exc).__name__}: {exc}")
        return 1


if __name__ == "__main__":
    # A normal exit (not os._exit): Zenoh removes its shared-memory segments from /dev/shm in
    # its exit handlers.
    sys.exit(main())
