"""The process of one component: ``python -m agents_core.launch.child --report-fd N``.

It reads its :class:`~agents_core.launch.spec.ComponentSpec` as the first line (JSON) of its
stdin, never from argv or the environment (a spec may hold an API key). Then it opens its own
transport, rebuilds the component, configures and activates it, and reports each state to the
launcher as a JSON line on the inherited pipe ``--report-fd``. Further stdin lines are commands
(``deactivate``, ``shutdown``).

It never outlives the launcher, in any state, stopped (SIGSTOP) included. It notices the
launcher's death two ways: the end of stdin (the launcher's end of the pipe closes with the
launcher, whatever killed it) and, as a fallback, its parent pid changing; ``PR_SET_PDEATHSIG``
makes Linux send SIGCONT when the launcher dies, so a stopped process runs again and notices
(:mod:`.descendants`: a SIGTERM would wait, pending, for a continue that never comes). The
processes the component starts end with it: the process is their subreaper, and every way out
ends them first (:func:`~.descendants.end_descendants`). Both watches run on threads of their
own, which arm the exit deadline themselves, so user code stuck on the main thread (a deactivate that never returns)
cannot keep the process alive. Everything up to the activation (importing the recipe, building
the component, opening the transport, configure, activate) runs on a startup thread, so the main
thread stays free for the signal handlers and the commands. When the launcher dies, or a
SIGTERM/SIGINT or ``shutdown`` comes, before the component is active, it is never activated: the
process closes its transport and exits at once (``os._exit``), whatever the configure is doing.
Once active, the same events start a shutdown. Either way a stop that takes longer than
:data:`EXIT_DEADLINE_S` ends the process with ``os._exit``.

A thread that holds the GIL forever (a C extension that never releases it) cannot be
interrupted from Python: only a SIGKILL ends such a process (PR_SET_PDEATHSIG's SIGTERM is
handled in Python).
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
import time
from collections.abc import Callable
from typing import IO, TYPE_CHECKING, Any, NoReturn

from .. import telemetry
from ..errors import AgentsError
from .child_health import start_health_reports
from .descendants import end_descendants, guard_process
from .short_errors import debug_requested

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..transport.contract import Transport
    from .spec import ComponentSpec

__all__ = ["EXIT_DEADLINE_S", "main", "run_forked", "set_parent_death_signal"]

logger = logging.getLogger("agents_core.launch.child")

#: Longest the shutdown may take once the launcher is gone or asked for it.
EXIT_DEADLINE_S = 1.5
#: Longest first line (the spec) read from stdin.
MAX_SPEC_BYTES = 16 * 1024 * 1024
#: How often the launcher-watch thread checks that the launcher is still this process's parent.
PARENT_POLL_S = 0.1
_PR_SET_PDEATHSIG = 1
_PR_SET_NAME = 15
#: Commands that end the process: the launcher is gone (end of stdin, another parent), a signal, a stop.
_STOPS = frozenset({"eof", "parent-gone", "signal", "shutdown"})


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
        # Inherited (pass_fds) or received (SCM_RIGHTS) without close-on-exec: a program the component
        # runs must not get the launcher's report pipe (it could forge states, and keep it open).
        os.set_inheritable(fd, False)
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


def _read_commands(lines: _PipeLines, commands: queue.SimpleQueue[str], launcher_gone: Callable[[], None]) -> None:
    while (raw := lines.readline(4096)) is not None:
        commands.put(raw.decode("utf-8", "replace").strip())
    # The launcher's end closes only when it is gone (it closes it itself only after this process exited).
    launcher_gone()
    commands.put("eof")


def _watch_parent(parent_pid: int, commands: queue.SimpleQueue[str], launcher_gone: Callable[[], None]) -> None:
    """The fallback when neither the pipe nor PR_SET_PDEATHSIG tells: another process became the parent
    (the launcher's end of the pipe may live on in a process it forked)."""
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    launcher_gone()
    commands.put("parent-gone")


def _next_command(commands: queue.SimpleQueue[str]) -> str:
    # Short waits: the signal handlers run on the main thread between two of them.
    while True:
        with contextlib.suppress(queue.Empty):
            return commands.get(timeout=PARENT_POLL_S)


def _leave(code: int) -> NoReturn:
    """``os._exit(code)``, after ending the processes the component started."""
    with contextlib.suppress(Exception):
        end_descendants(0.2)
    os._exit(code)


def _exit_soon(code: int) -> None:
    timer = threading.Timer(EXIT_DEADLINE_S, lambda: _leave(code))
    timer.daemon = True
    timer.start()


class _Startup:
    """Builds, configures and activates the component on a thread of its own (see the module docstring).

    It puts ``started`` or ``failed`` on the command queue when done. :meth:`abandon` makes sure
    the component is not activated afterwards (unless its activation has already begun).
    """

    def __init__(self, spec: ComponentSpec, commands: queue.SimpleQueue[str]) -> None:
        self.spec = spec
        self.component: Component | None = None
        self.transport: Transport | None = None
        self.error: BaseException | None = None
        self._commands = commands
        self._lock = threading.Lock()
        self._abandoned = False
        self._activating = False
        self._thread = threading.Thread(target=self._run, name="component-startup", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def abandon(self) -> bool:
        """Never activate the component from now on; False when its activation has already begun.

        Never waits for user code: the lock guards only the two flags.
        """
        with self._lock:
            self._abandoned = True
            return not self._activating

    def _run(self) -> None:
        from ..transport.namespace import namespaced  # noqa: PLC0415
        from ..transport.registry import resolve_transport  # noqa: PLC0415
        from .recipe_import import import_recipe  # noqa: PLC0415
        from .spec import RECIPE_MODULE, decode_value  # noqa: PLC0415

        spec = self.spec
        stage = "build"  # what failed, in the error the launcher shows ("failed to configure: ...")
        try:
            spec.extend_import_path()  # the recipe's sibling modules, wherever it was started from
            if spec.recipe_path is not None:
                import_recipe(spec.recipe_path, RECIPE_MODULE)
            component = spec.build()
            transport = namespaced(resolve_transport(spec.transport, **decode_value(spec.transport_options)),
                                   spec.namespace, owns_inner=True)
            with self._lock:
                self.component, self.transport = component, transport
            component.runtime.bind(transport)
            stage = "configure"
            component.configure()
            with self._lock:
                if self._abandoned:
                    return
                self._activating = True
            stage = "activate"
            component.activate()
        except BaseException as exc:  # carried to the main thread, which raises it (SystemExit included)
            with contextlib.suppress(AttributeError, TypeError):
                setattr(exc, "agents_stage", stage)  # noqa: B010  # read by _serve's one error line
            self.error = exc
            self._commands.put("failed")
            return
        self._commands.put("started")

    def close(self) -> None:
        """Shut down what was built after a failed startup (the startup thread has ended)."""
        if self.component is not None:
            try:
                self.component.shutdown()
            finally:
                if self.transport is not None:
                    self.transport.close()
        elif self.transport is not None:
            self.transport.close()


def _abandon_startup(startup: _Startup, reporter: _Reporter, why: str) -> NoReturn:
    """Leave a component that is not active yet: no activation, the transport closed, exit within the deadline.

    The startup thread may be stuck in user code: the process ends with ``os._exit``, after a
    best-effort close of the transport (its peers see the component go at once) bounded by
    :data:`EXIT_DEADLINE_S`.
    """
    _exit_soon(0)
    if startup.abandon():
        logger.warning("stopping before the component is active (%s): it will not be activated", why)
    else:
        logger.warning("stopping while the component activates (%s)", why)
    if startup.transport is not None:
        with contextlib.suppress(Exception):
            startup.transport.close()
    if why in ("signal", "shutdown"):
        reporter.send(state="finalized")  # stopped on request: the supervisor does not respawn it
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    _leave(0)


def _watch_launcher(parent_pid: int, stdin: _PipeLines, commands: queue.SimpleQueue[str],
                    startup: _Startup) -> None:
    """Start the threads that read the launcher's commands and notice when it is gone."""
    once = threading.Lock()

    def launcher_gone() -> None:
        # On the watching threads, whatever the main thread is doing (stuck in a configure, a
        # deactivate or a shutdown): no activation from now on, and the process ends in time.
        if once.acquire(blocking=False):
            startup.abandon()
            _exit_soon(0)

    threading.Thread(target=_read_commands, args=(stdin, commands, launcher_gone), name="launcher-pipe",
                     daemon=True).start()
    threading.Thread(target=_watch_parent, args=(parent_pid, commands, launcher_gone), name="launcher-watch",
                     daemon=True).start()


def _await_startup(startup: _Startup, commands: queue.SimpleQueue[str], reporter: _Reporter) -> list[str]:
    """Wait for the component to be active; the commands for it that came meanwhile.

    A stop meanwhile ends the process (:func:`_abandon_startup`); a failed startup raises its error.
    """
    deferred: list[str] = []
    while (command := _next_command(commands)) != "started":
        if command == "failed":
            error = startup.error
            try:
                startup.close()
            finally:
                raise error if error is not None else RuntimeError("the component's startup failed")
        if command in _STOPS:
            _abandon_startup(startup, reporter, command)
        if command != "fire-trigger":  # a firing before the activation is dropped, as a step would be
            deferred.append(command)
    return deferred


def run(spec_line: bytes, reporter: _Reporter, stdin: _PipeLines, parent_pid: int = 0) -> int:
    """Build, run and stop the component of ``spec_line``; the process's exit status.

    ``parent_pid``: the process expected as parent (the fork server's, for a forked process);
    by default the launcher's, from the spec.
    """
    from ..events import Event  # noqa: PLC0415
    from .spec import ComponentSpec  # noqa: PLC0415

    spec = ComponentSpec.from_dict(json.loads(spec_line))
    spec.apply_environment()  # a forked process: the launcher's environment as it is now, before anything reads it
    parent_pid = parent_pid or spec.parent_pid or os.getppid()
    if os.getppid() != parent_pid:
        return 1  # the launcher died before PR_SET_PDEATHSIG was set
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format=f"[{spec.component_name} %(process)d] %(levelname)s %(name)s: %(message)s")
    # The launcher's telemetry settings, else the standard variables (OTEL_EXPORTER_OTLP_ENDPOINT).
    settings = telemetry.TelemetrySettings(**spec.telemetry) if spec.telemetry else telemetry.settings_from_env()
    telemetry.configure(settings, spec.component_name, spec.component_name)
    commands: queue.SimpleQueue[str] = queue.SimpleQueue()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: commands.put("signal"))
    startup = _Startup(spec, commands)
    _watch_launcher(parent_pid, stdin, commands, startup)
    startup.start()
    deferred = _await_startup(startup, commands, reporter)
    component, transport = startup.component, startup.transport
    if component is None or transport is None:
        raise RuntimeError("the component's startup reported success without a component")
    try:
        reporter.send(state=component.lifecycle_state.value)
        start_health_reports(component, reporter.send)  # the launcher's rows show it (child_health)
        while True:
            command = deferred.pop(0) if deferred else _next_command(commands)
            if command == "fire-trigger":  # the launcher saw the trigger event fire (spec.LauncherEvent)
                if isinstance(component.trigger, Event):
                    component.trigger.trigger()
            elif command == "deactivate":
                # stop(): deactivate only when active; an outside deactivate may have come first.
                component.stop()
                reporter.send(state=component.lifecycle_state.value)
            elif command == "shutdown":
                break
            elif command in _STOPS:
                # The launcher is gone (or a signal came): stop now, and never hang doing it.
                _exit_soon(0)
                component.hurry_shutdown()
                break
    finally:
        try:
            component.shutdown()
        finally:
            transport.close()
            telemetry.shutdown()  # what is buffered is exported before the process ends
    reporter.send(state="finalized")
    return 0


def _watch_parent_until(parent_pid: int, done: threading.Event) -> None:
    """Until ``done``: end the process when its parent is gone (the spec has not come yet, so there
    is nothing to shut down; PR_SET_PDEATHSIG only continues a stopped process)."""
    while not done.wait(PARENT_POLL_S):
        if os.getppid() != parent_pid:
            _leave(1)


def _serve(reporter: _Reporter, stdin: _PipeLines, parent_pid: int = 0) -> int:
    spec_read = threading.Event()
    threading.Thread(target=_watch_parent_until, args=(parent_pid or os.getppid(), spec_read),
                     name="launcher-watch-early", daemon=True).start()
    try:
        spec_line = stdin.readline(MAX_SPEC_BYTES)
    finally:
        spec_read.set()
    if spec_line is None:
        reporter.send(error="no complete component spec on stdin")
        return 2
    try:
        return run(spec_line, reporter, stdin, parent_pid)
    except Exception as exc:
        stage = getattr(exc, "agents_stage", None)
        failed = f"failed to {stage}: " if stage else ""
        if isinstance(exc, AgentsError) and not debug_requested():  # the one line (AGENTS_DEBUG=1: the traceback)
            logger.error("component process %s%s: %s", failed, type(exc).__name__, exc)
        else:
            logger.exception("component process %sfailed", failed)
        reporter.send(error=f"{failed}{type(exc).__name__}: {exc}")
        return 1
    finally:
        with contextlib.suppress(Exception):
            end_descendants()  # what the component started ends with it


def run_forked(stdin_fd: int, report_fd: int, server_pid: int, name: str) -> int:
    """The entry of a process forked by :mod:`agents_core.launch.fork_server`; its exit status.

    Same contract as :func:`main`: the spec comes on ``stdin_fd`` (made this process's stdin),
    states go to ``report_fd``; the process ends when the server (its parent) or the launcher
    (the end of its command pipe) is gone.
    """
    guard_process()
    if os.getppid() != server_pid:
        return 1  # the server ended before PR_SET_PDEATHSIG was set
    if name:  # what ps and top show instead of the server's name (at most 15 bytes)
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None).prctl(_PR_SET_NAME, ctypes.c_char_p(f"agents:{name}".encode()[:15]), 0, 0, 0)
    os.dup2(stdin_fd, 0)
    os.close(stdin_fd)
    return _serve(_Reporter(report_fd), _PipeLines(0), server_pid)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agents_core.launch.child", description=__doc__)
    parser.add_argument("--report-fd", type=int, required=True, help="inherited pipe to report states on")
    args = parser.parse_args(argv)
    guard_process()
    return _serve(_Reporter(args.report_fd), _PipeLines(sys.stdin.fileno()))


if __name__ == "__main__":
    # A normal exit (not os._exit): Zenoh removes its shared-memory segments from /dev/shm in
    # its exit handlers.
    sys.exit(main())
