"""A pre-imported process server that forks component processes, so each starts like a thread.

A fresh interpreter per component pays the imports (the framework, the middleware, the
component's module) every time. Instead, the launcher process starts one **fork server** the
first time a recipe asks for ``multiprocessing=True``: ``python -m agents_core.launch.fork_server``,
a fresh interpreter of its own, started by ``subprocess`` (so whatever threads or middleware
sessions the launcher holds, the server holds none). It imports the framework, the component
process entry point (:mod:`agents_core.launch.child`), the transport adapter and the component
classes' modules, then forks one process per request. The server is shared by every launcher of
the process and lives until the launcher process ends (like ``multiprocessing``'s forkserver).

Forking is safe only in a process with no thread that may hold a lock and no middleware
session: the server runs no recipe code (the recipe file itself is still imported by each
component process, cheaply, since everything it imports is loaded) and counts its threads
(``/proc/self/task``) after each import. The server imports numpy first (the framework imports it
at first use): its OpenBLAS pool stops its threads around a fork (``pthread_atfork``), and the count
after the base imports is the baseline. A
preloaded module that starts more threads makes the server refuse to fork, and the launcher
falls back to a fresh interpreter per component.

A transport adapter may declare what else the server imports, and how to fork safely with it,
in a module of its package named ``fork_support`` (``agents_ros2.fork_support``; the core finds
it by that name and never imports the middleware itself). The module must import no middleware
when loaded; it provides ``preload()`` (import the adapter, the middleware's modules, its
generated message types: no context, no session, nothing initialised) and may provide
``before_fork()`` (raise to refuse the fork), ``after_fork_parent()`` and ``after_fork_child()``,
called around each fork. The threads ``preload()`` starts are the adapter's to make safe with
those hooks (ROS 2's tracing library starts two, and exports hooks for this very purpose); they
join the baseline. Without such a module, the middleware packages named in
:data:`NOT_PRELOADED` (ROS 2's client library starts threads when it is loaded) are never
preloaded: a component process loads them after the fork.

The protocol, on a ``SOCK_SEQPACKET`` Unix socket pair (one JSON object per packet):

* launcher -> server ``{"op": "preload", "modules": [...], "path": [...], "adapter": "..."}``: load
  the adapter's ``fork_support`` (if it has one), then import the modules (the path entries go in
  front of ``sys.path``); errors are ignored (the component process reports them).
* launcher -> server ``{"op": "fork", "id": n, "name": ...}`` with two descriptors attached
  (``SCM_RIGHTS``): the read end of the component's command pipe (its stdin) and the write end
  of its report pipe. The reply is ``{"id": n, "pid": p}`` or ``{"id": n, "error": "..."}``.
* server -> launcher ``{"exit": pid, "status": s}``: a component process ended (``s`` as
  ``Popen.returncode``: negative for a signal).

The spec (which may hold secrets) is never seen by the server: the launcher writes it on the
component's command pipe, as for a spawned process. A forked component process's argv is the
server's (no secret in it); its environment, the server's, gets the launcher's changes since from
the spec (:mod:`.fork_environment`). It dies with the launcher: its command pipe ends (only the
launcher holds the write end), the server exits when its socket ends and each forked process has
``PR_SET_PDEATHSIG`` set towards the server. The server is the subreaper of its component
processes: what one started is re-parented to the server if it dies without ending it (SIGKILL,
a crash), and the server ends it (:class:`~.descendants.Orphans`; a process its own imports
started is left alone). A pass of its loop that fails is logged and the server goes on.

Opt out with ``AGENTS_PROCESS_START=spawn`` (or ``Launcher(process_start="spawn")``); where
fork or descriptor passing is not available (not Linux) the spawn path is used anyway.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import dataclasses
import importlib
import importlib.util
import json
import logging
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable
from typing import IO, Any

from .descendants import Orphans, become_subreaper, children
from .fork_environment import FIXED_AT_PRELOAD, CannotCarry, environment_changes, fixed_environment
from .process_start import PROCESS_START_ENV, fork_available, process_start

__all__ = [
    "PROCESS_START_ENV",
    "ForkServer",
    "ForkServerError",
    "ForkedProcess",
    "adapter_module",
    "fork_available",
    "fork_server",
    "prepare",
    "process_start",
]

logger = logging.getLogger(__name__)

#: Always imported by the server: what every component process needs. numpy comes first, by name: the
#: message types import it only at first use, and its OpenBLAS pool must be in the thread baseline.
BASE_MODULES = ("numpy", "agents_core.launch.child", "agents_core.launch.spec", "agents_core.launch.recipe_import",
                "agents_core.transport.registry", "agents_core.components.component_base")
#: Not imported by the server unless an adapter's fork support loaded them: they start threads when
#: loaded (rclpy's tracing library).
NOT_PRELOADED = ("agents_ros2", "rclpy")
#: The module of an adapter's package that says what the server may preload for it (see above).
FORK_SUPPORT_MODULE = "fork_support"
#: How long a fork request may wait for its reply.
FORK_TIMEOUT_S = 10.0
_MAX_PACKET = 1 << 20


class ForkServerError(OSError):
    """The fork server could not start a process (gone, unsafe to fork, or it refused)."""


# -- the launcher side --------------------------------------------------------------------------


class ForkedProcess:
    """A component process forked by the server: the part of ``subprocess.Popen`` the supervisor uses."""

    def __init__(self, server: ForkServer, pid: int, stdin: IO[bytes]) -> None:
        self.pid = pid
        self.stdin: IO[bytes] | None = stdin
        self.returncode: int | None = None
        #: Called (on the server's reader thread) once the process has ended.
        self.on_exit: Callable[[], None] | None = None
        self.environment: dict[str, str | None] = {}  # the changes it applies (sent with its spec)
        self._server = server
        self._exited = threading.Event()

    def set_exit(self, status: int) -> None:
        self.returncode = status
        self._exited.set()
        if self.on_exit is not None:
            self.on_exit()

    def poll(self) -> int | None:
        if self.returncode is None and self._server.gone and not _alive(self.pid):
            # The server (its parent) is gone, so its status is unknown; it got PR_SET_PDEATHSIG's SIGTERM.
            self.set_exit(-signal.SIGTERM)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            left = 0.05 if deadline is None else min(0.05, deadline - time.monotonic())
            if left <= 0:
                raise subprocess.TimeoutExpired(f"component process {self.pid}", timeout or 0.0)
            self._exited.wait(left)
        assert self.returncode is not None
        return self.returncode

    def send_signal(self, signum: int) -> None:
        if self.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signum)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return False


class ForkServer:
    """The launcher's handle on a running fork server (see the module docstring)."""

    def __init__(self) -> None:
        self._sock, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.environment = dict(os.environ)  # the server's, which its forked processes start with
        self._fixed = set(FIXED_AT_PRELOAD)  # what its preloaded modules read when imported
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "agents_core.launch.fork_server", "--socket-fd", str(theirs.fileno())],
                stdin=subprocess.DEVNULL, pass_fds=(theirs.fileno(),), close_fds=True, env=self.environment)
        finally:
            theirs.close()
        self.gone = False
        self._send_lock = threading.Lock()
        self._replies: dict[int, dict[str, Any]] = {}
        self._children: dict[int, ForkedProcess] = {}
        self._early_exits: dict[int, int] = {}
        self._changed = threading.Condition()
        self._next_id = 0
        self._reader = threading.Thread(target=self._read, name="fork-server", daemon=True)
        self._reader.start()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def _send(self, message: dict[str, Any], fds: Iterable[int] = ()) -> None:
        data = json.dumps(message).encode("utf-8")
        with self._send_lock:
            try:
                socket.send_fds(self._sock, [data], list(fds))
            except OSError as exc:
                raise ForkServerError(f"the fork server is gone: {exc}") from exc

    def preload(self, modules: Iterable[str], path: Iterable[str] = (), adapter: str | None = None) -> None:
        """Have the server import ``modules`` (with ``path`` in front of its ``sys.path``); no reply.

        ``adapter``: the transport adapter's module, whose package's ``fork_support`` is loaded first.
        """
        self._send({"op": "preload", "modules": sorted(set(modules)), "path": list(path), "adapter": adapter})
        if adapter:
            self._fixed.update(fixed_environment(f"{adapter.partition('.')[0]}.{FORK_SUPPORT_MODULE}"))

    def environment_changes(self) -> dict[str, str | None]:
        """The changes since the server started (:mod:`.fork_environment`); ForkServerError: spawn instead."""
        try:
            return environment_changes(self.environment, self._fixed)
        except CannotCarry as exc:
            raise ForkServerError(str(exc)) from exc

    def fork(self, name: str, stdin_read: int, report_write: int, stdin_write: int) -> ForkedProcess:
        """A new component process reading commands from ``stdin_read`` and reporting on ``report_write``.

        The caller keeps (and closes) its copies of the two descriptors; ``stdin_write`` becomes
        the returned process's ``stdin``.
        """
        with self._changed:
            self._next_id += 1
            request = self._next_id
        self._send({"op": "fork", "id": request, "name": name}, (stdin_read, report_write))
        deadline = time.monotonic() + FORK_TIMEOUT_S
        with self._changed:
            while request not in self._replies:
                left = deadline - time.monotonic()
                if self.gone or left <= 0:
                    raise ForkServerError("the fork server is gone" if self.gone
                                          else f"no reply from the fork server in {FORK_TIMEOUT_S:g} s")
                self._changed.wait(left)
            reply = self._replies.pop(request)
            if "pid" not in reply:
                raise ForkServerError(str(reply.get("error", "the fork server refused")))
            pid = int(reply["pid"])
            child = ForkedProcess(self, pid, os.fdopen(stdin_write, "wb"))
            self._children[pid] = child
            if pid in self._early_exits:  # it ended before this thread saw the reply
                child.set_exit(self._early_exits.pop(pid))
        return child

    def _read(self) -> None:
        while True:
            try:
                data = self._sock.recv(_MAX_PACKET)
            except OSError:
                data = b""
            if not data:
                break
            try:
                message = json.loads(data)
                exit_of = (int(message["exit"]), int(message["status"])) if "exit" in message else None
                reply_to = int(message["id"]) if exit_of is None and "id" in message else None
            except (ValueError, TypeError, KeyError):  # not a message of the server's: ignored
                continue
            with self._changed:
                if exit_of is not None:
                    pid, status = exit_of
                    child = self._children.pop(pid, None)
                    if child is not None:
                        child.set_exit(status)
                    else:
                        self._early_exits[pid] = status
                elif reply_to is not None:
                    self._replies[reply_to] = message
                self._changed.notify_all()
        with self._changed:
            self.gone = True
            self._changed.notify_all()

    def close(self, timeout: float = 2.0) -> None:
        """End the server (its component processes get PR_SET_PDEATHSIG's SIGTERM)."""
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)
        self._sock.close()
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=5.0)


_server: ForkServer | None = None
_server_lock = threading.Lock()


def fork_server() -> ForkServer:
    """This process's fork server, started on first use (and again if it has died)."""
    global _server  # noqa: PLW0603  # one server per launcher process, like multiprocessing's
    with _server_lock:
        if _server is None or _server.gone or _server.proc.poll() is not None:
            if _server is None:
                atexit.register(_close_server)
            _server = ForkServer()
        return _server


def _close_server() -> None:
    global _server
    with _server_lock:
        server, _server = _server, None
    if server is not None:
        server.close()


def adapter_module(transport: object) -> str | None:
    """The module of the transport adapter ``transport`` (a name or a transport object) names, if known."""
    if transport is None or isinstance(transport, str):
        from ..errors import TransportNotAvailableError  # noqa: PLC0415
        from ..transport.registry import TRANSPORT_ENV_VAR, describe_transport_kind  # noqa: PLC0415

        name = transport or os.environ.get(TRANSPORT_ENV_VAR, "").strip()
        if not name:
            return None
        try:
            return describe_transport_kind(name).factory_module()  # its descriptor says what builds it
        except TransportNotAvailableError:
            return None
    driver = getattr(transport, "driver", None)  # a DriverTransport around a third-party driver
    module = type(transport).__module__
    return type(driver).__module__ if driver is not None and module.startswith("agents_core.") else module


def prepare(modules: Iterable[str], path: Iterable[str] = (), adapter: str | None = None) -> ForkServer | None:
    """Start the fork server if needed and have it import ``modules`` (and what ``adapter`` declares).

    None where it cannot run.
    """
    try:
        server = fork_server()
        server.preload([*BASE_MODULES, *(m for m in modules if m and m != "__main__"), *([adapter] if adapter else [])],
                       path, adapter)
    except (OSError, ForkServerError) as exc:
        logger.warning("cannot use a fork server for component processes (%s): starting each in a fresh "
                       "interpreter", exc)
        return None
    return server


# -- the server ---------------------------------------------------------------------------------


def _thread_count() -> int:
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return threading.active_count()


_fork_supports: list[Any] = []
#: Those of NOT_PRELOADED that a fork support loaded (and vouches for): importing them is safe now.
_vouched: set[str] = set()


def _load_fork_support(adapter: str) -> int:
    """Load the ``fork_support`` of ``adapter``'s package and run its ``preload()``; the threads it started."""
    name = f"{adapter.partition('.')[0]}.{FORK_SUPPORT_MODULE}"
    if any(support.__name__ == name for support in _fork_supports):
        return 0
    try:
        if importlib.util.find_spec(name) is None:
            return 0
    except (ImportError, ValueError):
        return 0
    before = _thread_count()
    try:
        support = importlib.import_module(name)
        preload = getattr(support, "preload", None)
        if callable(preload):
            preload()
    except Exception as exc:  # the adapter is unusable here: the component process reports why
        logger.debug("fork support %s failed: %s", name, exc)
        return 0
    _fork_supports.append(support)
    _vouched.update(name for name in NOT_PRELOADED if name in sys.modules)
    return _thread_count() - before


def _preload(request: dict[str, Any]) -> int:
    """Import what ``request`` names; the threads the adapter's fork support started (it vouches for them)."""
    for entry in reversed([str(p) for p in request.get("path", [])]):
        if entry not in sys.path:
            sys.path.insert(0, entry)
    adapter = request.get("adapter")
    vouched = _load_fork_support(adapter) if isinstance(adapter, str) and adapter else 0
    for name in map(str, request.get("modules", [])):
        top = name.partition(".")[0]
        if top in NOT_PRELOADED and top not in _vouched:
            continue  # unless an adapter's fork support has loaded it, with hooks for its threads
        with contextlib.suppress(Exception):  # the component process reports the error, with context
            importlib.import_module(name)
    return vouched


def _run_hooks(supports: list[Any], step: str) -> None:
    for support in supports:
        hook = getattr(support, step, None)
        if callable(hook):
            hook()


def _fork() -> int:
    """``os.fork()`` between the adapters' hooks; raises when one refuses (or the fork fails)."""
    prepared: list[Any] = []  # those whose before_fork ran: only they get an after_fork_*
    try:
        for support in _fork_supports:
            _run_hooks([support], "before_fork")
            prepared.append(support)
        pid = os.fork()
    except BaseException:
        _run_hooks(prepared, "after_fork_parent")
        raise
    _run_hooks(prepared, "after_fork_child" if pid == 0 else "after_fork_parent")
    return pid


def _reap_ended(sock: socket.socket, forked: set[int], orphans: Orphans) -> tuple[bool, set[int]]:
    """Reap every child that ended (a component process's end is told to the launcher): whether one was a
    component process or an orphan (its children are orphans too), and the pids reaped."""
    orphaning, reaped = False, set()
    for _ in range(100_000):
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            break
        if pid == 0:
            break
        reaped.add(pid)
        if orphans.reaped(pid):
            orphaning = True
        if pid not in forked:  # an orphan this server ended, or a process its own imports started
            continue
        orphaning = True
        forked.discard(pid)
        with contextlib.suppress(OSError):
            sock.send(json.dumps({"exit": pid, "status": os.waitstatus_to_exitcode(status)}).encode())
    return orphaning, reaped


def _reap(sock: socket.socket, forked: set[int], orphans: Orphans) -> None:
    """Reap every child that ended, then end the orphans of a component process that died without ending
    them (re-parented to this subreaper); the other new children are the server's own (:class:`Orphans`)."""
    died, _ = _reap_ended(sock, forked, orphans)
    for _ in range(1000):
        kids = set(children(os.getpid())) - forked
        more, reaped = _reap_ended(sock, forked, orphans)  # one that died while the children were read
        died |= more
        if not more:
            orphans.sort(kids - reaped, orphaned=died)
            return
    orphans.sort(set(), orphaned=died)


def _wakeup_pipe() -> tuple[int, int]:
    """A pipe that SIGCHLD writes to (``signal.set_wakeup_fd``): its read and write ends."""
    wake_read, wake_write = os.pipe()
    os.set_blocking(wake_read, False)
    os.set_blocking(wake_write, False)
    signal.set_wakeup_fd(wake_write)
    signal.signal(signal.SIGCHLD, lambda *_: None)  # a handler, so that SIGCHLD writes to the wakeup fd
    return wake_read, wake_write


def _leave_server(sock: socket.socket, *wake: int) -> None:
    """In a forked child: drop what was the server's (its SIGCHLD wake-up, its socket)."""
    signal.set_wakeup_fd(-1)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    for fd in wake:
        os.close(fd)
    sock.close()


@dataclasses.dataclass
class _State:
    wake: tuple[int, int]  # the SIGCHLD wake-up pipe
    threads: int  # the thread count forking is safe with
    forked: set[int] = dataclasses.field(default_factory=set)  # component processes forked, not reaped
    orphans: Orphans = dataclasses.field(default_factory=Orphans)


_AGAIN = (-1, -1, "")  # what a pass that the loop goes on after returns


def _serve_once(sock: socket.socket, state: _State) -> tuple[int, int, str] | None:
    """One pass of :func:`serve`: ``_AGAIN``, or what :func:`serve` returns."""
    forked, orphans, wake_read = state.forked, state.orphans, state.wake[0]
    ready = select.select([sock.fileno(), wake_read], [], [], orphans.timeout())[0]
    orphans.kill_due()
    if wake_read in ready:
        with contextlib.suppress(BlockingIOError):
            os.read(wake_read, 4096)
        _reap(sock, forked, orphans)
    if sock.fileno() not in ready:
        return _AGAIN
    try:
        data, fds, _, _ = socket.recv_fds(sock, _MAX_PACKET, 2)
    except OSError:
        data, fds = b"", []
    if not data:
        orphans.kill_all()
        return None  # the launcher is gone or done: the component processes see their pipes end
    try:
        request = json.loads(data)
    except ValueError:
        request = None
    if not isinstance(request, dict) or not isinstance(request.get("id", 0), (int, type(None))):
        for fd in fds:  # a packet that is not a request: dropped, with what came with it
            os.close(fd)
        return _AGAIN
    if request.get("op") == "preload":
        _reap(sock, forked, orphans)  # so that only what the imports start is new after them
        with contextlib.suppress(TypeError):
            state.threads += _preload(request)
        _reap(sock, forked, orphans)  # what the imports started is the server's own
        return _AGAIN
    reply: dict[str, Any] = {"id": request.get("id")}
    if len(fds) != 2:
        reply["error"] = "a fork request needs two descriptors"
    elif _thread_count() > state.threads:
        reply["error"] = "an imported module started a thread in the fork server: forking is unsafe"
    else:
        try:
            pid = _fork()
        except Exception as exc:
            pid = -1
            reply["error"] = f"cannot fork: {exc}"
        if pid == 0:
            _leave_server(sock, *state.wake)
            return fds[0], fds[1], str(request.get("name", ""))
        if pid > 0:
            forked.add(pid)
            reply["pid"] = pid
    for fd in fds:
        os.close(fd)
    sock.send(json.dumps(reply).encode())
    return _AGAIN


def serve(sock: socket.socket, baseline_threads: int) -> tuple[int, int, str] | None:
    """Answer requests until the launcher's end closes (None); in a forked child, its descriptors and name.

    A pass that fails is logged and the server goes on: every component process stops with the server.
    """
    server = os.getpid()
    state = _State(_wakeup_pipe(), baseline_threads)
    _reap(sock, state.forked, state.orphans)  # what the base imports started is the server's own
    while True:
        try:
            result = _serve_once(sock, state)
        except Exception:
            if os.getpid() != server:
                raise  # a forked child never serves
            logger.exception("fork server: a pass of its loop failed; it goes on")
            time.sleep(0.05)  # an error that repeats does not spin
            continue
        if result is not _AGAIN:
            return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agents_core.launch.fork_server", description=__doc__)
    parser.add_argument("--socket-fd", type=int, required=True, help="inherited SOCK_SEQPACKET socket")
    args = parser.parse_args(argv)
    # Ctrl-C reaches the whole process group: the launcher decides when the server ends.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    server_pid = os.getpid()
    become_subreaper()  # the orphans of a component process killed outright come here, to be ended
    sock = socket.socket(fileno=args.socket_fd)
    for name in BASE_MODULES:
        importlib.import_module(name)
    forked = serve(sock, _thread_count())
    if forked is None:
        return 0
    # A forked component process: the server's frames are gone; run it, then exit normally (the
    # middleware's exit handlers remove its shared-memory segments).
    from .child import run_forked  # noqa: PLC0415

    stdin_fd, report_fd, name = forked
    return run_forked(stdin_fd, report_fd, server_pid, name)


if __name__ == "__main__":
    sys.exit(main())
