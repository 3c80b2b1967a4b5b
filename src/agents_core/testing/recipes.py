"""Testing a recipe file in a process of its own, on every installed cross-process transport.

A recipe test starts ``python recipe.py --transport NAME ...`` as a child process, waits until the
recipe prints ``READY`` on its stdout, asks it over the transport from the test process, and
stops it by PID. The ``recipe_transport`` fixture is parametrized over the cross-process
transports (``zenoh``, ``ros2``), as anyio's ``anyio_backend`` is over its backends, so such a
test is written once::

    from agents_core.testing.recipes import recipe_transport, run_recipe  # the fixture, by name

    def test_my_recipe_answers(recipe_transport, tmp_path):
        with run_recipe("my_recipe.py", recipe_transport, tmp_path):
            asker = recipe_transport.open_asker()
            ...

The recipe must accept ``--transport NAME`` and, for Zenoh, ``--listen ENDPOINT`` (the loopback
endpoint it listens on and the asker connects to), print ``READY`` once its launcher is active,
and stop on SIGINT. A transport whose processes meet only through a router (its descriptor's
``needs_router``, rmw_zenoh) gets one per test: the descriptor's ``router`` module in a child
process on a free loopback port, stopped by PID after the test; the recipe reaches it through the
environment the descriptor's ``router_environment`` gives (rmw_zenoh: its own
``ZENOH_CONFIG_OVERRIDE``), so it runs unchanged, and the asker connects to it.

Everything stays on this host: Zenoh on an explicit ``tcp/127.0.0.1`` port with multicast
scouting off; ROS 2 with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` in a domain of this
process's own (:func:`~agents_core.testing.pairs.private_ros_environment`). A transport whose
extra is not installed is skipped with the ``pip install`` that fixes it. Each parameter carries
the marker named after its transport (``pytest -m zenoh``); register the markers where
``--strict-markers`` is on (the :mod:`agents_core.testing` plugin does).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import pytest

from ..transport.contract import Transport
from ..transport.descriptor import TransportDescriptor
from ..transport.registry import TRANSPORT_ALIASES, describe_transport_kind, resolve_transport
from .helpers import free_tcp_port, wait_for
from .pairs import missing_requirement

__all__ = [
    "CROSS_PROCESS_TRANSPORTS",
    "RecipeProcess",
    "RecipeTransport",
    "open_recipe_transport",
    "recipe_environment",
    "recipe_transport",
    "recipe_transport_params",
    "run_recipe",
]

#: The built-in transports that reach another process (their descriptors say ``cross-process``).
CROSS_PROCESS_TRANSPORTS = tuple(name for name in TRANSPORT_ALIASES if describe_transport_kind(name).cross_process)

#: Environment variables of the test process that must not reach a recipe: they would pick
#: its transport or its Zenoh endpoints instead of the ones the harness gives on its command line.
_INHERITED_SETTINGS = ("AGENTS_ZENOH_", "AGENTS_TRANSPORT")
#: How long a test's router may take to listen.
ROUTER_READY_S = 30.0


@dataclass(frozen=True)
class RecipeTransport:
    """One cross-process transport, set up for a recipe child process and for the test that asks it.

    :param name: the transport's name, as ``--transport`` takes it.
    :param endpoint: a transport reached at endpoints (Zenoh): the loopback endpoint the recipe
        listens on; None otherwise.
    :param domain_id: ROS 2: the private domain both processes use; None otherwise.
    :param options: what the transport's descriptor's ``isolate`` gave (both sides open with it).
    :param router: a transport that needs a router: the router's process (``endpoint`` is where it
        listens); stopped by :meth:`close` (or :meth:`end`).
    """

    name: str
    endpoint: str | None = None
    domain_id: int | None = None
    options: Mapping[str, Any] = field(default_factory=dict, compare=False)
    router: RecipeProcess | None = field(default=None, compare=False)
    _opened: list[Transport] = field(default_factory=list, compare=False, repr=False)

    @property
    def descriptor(self) -> TransportDescriptor:
        """What the transport says it can do (:mod:`agents_core.transport.descriptor`)."""
        return describe_transport_kind(self.name)

    @property
    def recipe_args(self) -> list[str]:
        """The recipe's command-line arguments that select this transport."""
        args = ["--transport", self.name]
        if self.endpoint is not None and self.router is None:
            args += ["--listen", self.endpoint]
        return args

    @property
    def environment(self) -> dict[str, str]:
        """The environment variables a recipe process needs besides :func:`recipe_environment` (the router's)."""
        hook = self.descriptor.router_environment
        if self.router is None or self.endpoint is None or hook is None:
            return {}
        return dict(hook(self.endpoint))

    def open_asker(self) -> Transport:
        """A transport in this process that reaches the recipe's; closed by :meth:`close`."""
        if self.endpoint is not None:
            return self._open(self.name, **self.descriptor.reach([self.endpoint], "peer"))
        return self._open(self.name, **self.options)

    def open_recipe_side(self) -> Transport:
        """A transport in this process configured as the recipe child's would be (Zenoh: listening on the endpoint).

        For a recipe run inside the test process; closed by :meth:`close`.
        """
        if self.endpoint is not None and self.router is None:
            return self._open(self.name, **self.descriptor.listen(self.endpoint))
        return self.open_asker()

    def _open(self, name: str, **options: Any) -> Transport:
        transport = resolve_transport(name, **options)
        self._opened.append(transport)
        return transport

    def close(self) -> None:
        """Close every transport this object opened, newest first, then stop the router (by its PID) if this
        transport has one: the router is stopped even when closing a transport raises (the first such error is
        raised once every transport was tried)."""
        failure: BaseException | None = None
        try:
            for _ in range(len(self._opened)):
                try:
                    self._opened.pop().close()
                except Exception as exc:
                    failure = failure or exc
        finally:
            if self.router is not None:
                self.router.stop()
                shutil.rmtree(self.router.log_path.parent, ignore_errors=True)
        if failure is not None:
            raise failure

    def end(self) -> None:
        """The same as :meth:`close`."""
        self.close()


def open_recipe_transport(name: str) -> RecipeTransport:
    """Set up transport ``name`` on this host for a recipe test, as its descriptor says.

    A transport reached at endpoints gets a free loopback one; one with an ``isolate`` sets up its
    private space (ROS 2: the private domain, in ``os.environ``, which rcl reads when a context
    starts: the test process's plain rclpy nodes too); one that needs a router gets one started on a
    free loopback endpoint (:meth:`RecipeTransport.close` stops it).
    """
    descriptor = describe_transport_kind(name)
    if descriptor.needs_router and descriptor.router:
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        router = RecipeProcess(descriptor.router, [endpoint], Path(tempfile.mkdtemp(prefix="router-")) / "router.log")
        try:
            router.wait_ready(ROUTER_READY_S)
        except BaseException:
            router.stop()
            raise
        return RecipeTransport(name, endpoint=endpoint, router=router)
    if descriptor.endpoints:
        return RecipeTransport(name, endpoint=f"tcp/127.0.0.1:{free_tcp_port()}")
    if descriptor.isolate is not None:
        options = descriptor.isolate()
        domain = options.get("domain_id")
        return RecipeTransport(name, domain_id=domain if isinstance(domain, int) else None, options=options)
    return RecipeTransport(name)


def recipe_transport_params() -> list[Any]:
    """One ``pytest.param`` per cross-process transport: marked with its name, skipped if its extra is absent."""
    params = []
    for name in CROSS_PROCESS_TRANSPORTS:
        marks: list[Any] = [getattr(pytest.mark, name)]  # the marker named after the transport
        reason = missing_requirement(name)
        descriptor = describe_transport_kind(name)
        if reason is None and descriptor.needs_router and not descriptor.router:
            reason = f"{name} needs a router and its descriptor names no router module for the harness to start"
        if reason is not None:
            marks.append(pytest.mark.skip(reason=reason))
        params.append(pytest.param(name, marks=marks, id=name))
    return params


@pytest.fixture(params=recipe_transport_params())
def recipe_transport(request: pytest.FixtureRequest) -> Iterator[RecipeTransport]:
    """A :class:`RecipeTransport` for each installed cross-process transport; its askers closed after the test."""
    transport = open_recipe_transport(request.param)
    try:
        yield transport
    finally:
        transport.end()


def recipe_environment(**extra: str) -> dict[str, str]:
    """The environment of a recipe child process: this one's, less transport settings, ROS 2 kept on this host."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(_INHERITED_SETTINGS)}
    env["PYTHONUNBUFFERED"] = "1"  # READY must reach the test at once, not at exit
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.update(extra)
    return env


class RecipeProcess:
    """A recipe running in a child process: started at once, its stdout read by a thread, stderr to ``log``."""

    def __init__(self, recipe: str | Path, args: Sequence[str], log: Path, *, cwd: Path | None = None,
                 env: Mapping[str, str] | None = None) -> None:
        # A module name runs with -m (the recipe may use relative imports); a path runs as a script.
        target = ["-m", recipe] if isinstance(recipe, str) and not recipe.endswith(".py") else [str(recipe)]
        self.log_path = log
        self._log: IO[str] = log.open("w")
        self.lines: list[str] = []
        self.proc = subprocess.Popen([sys.executable, *target, *args], cwd=cwd,
                                     env=dict(env) if env is not None else recipe_environment(),
                                     stdout=subprocess.PIPE, stderr=self._log, text=True, start_new_session=True)
        # Read stdout to the end: a recipe that prints much after READY must never block on a full pipe.
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    @property
    def pid(self) -> int:
        """The recipe process's id."""
        return self.proc.pid

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def wait_ready(self, timeout: float = 60.0) -> None:
        """Wait (bounded) for ``READY`` on the recipe's stdout; fail the test with its output otherwise."""
        if not wait_for(lambda: "READY" in self.lines or self.proc.poll() is not None, timeout=timeout,
                        interval=0.05) or "READY" not in self.lines:
            pytest.fail(f"the recipe did not start within {timeout} s (exit status {self.proc.poll()}):\n"
                        f"{self.output()}")

    def output(self, limit: int = 3000) -> str:
        """The last ``limit`` characters of the recipe's stdout and stderr (also after :meth:`stop`)."""
        if not self._log.closed:
            self._log.flush()
        stdout = "\n".join(self.lines)[-limit:]
        return f"--- stdout ---\n{stdout}\n--- stderr ---\n{self.log_path.read_text(errors='replace')[-limit:]}"

    def stop(self, timeout: float = 15.0) -> int | None:
        """SIGINT to the recipe's process group, SIGKILL after ``timeout`` s; always reaped. Returns its exit status."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10.0)
        self._reader.join(timeout=5.0)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._log.close()
        return self.proc.returncode


@contextlib.contextmanager
def run_recipe(recipe: str | Path, transport: RecipeTransport, tmp_path: Path, args: Sequence[str] = (), *,
               cwd: Path | None = None, ready_timeout: float | None = 60.0, env: Mapping[str, str] | None = None,
               transport_args: bool = True) -> Iterator[RecipeProcess]:
    """Run ``recipe`` (a module name or a file) on ``transport`` until the block ends; then stop it by PID.

    ``args`` follow the transport's own arguments (none when ``transport_args`` is false: a recipe that
    picks its transport from ``env``, e.g. ``AGENTS_TRANSPORT``, as upstream's do); ``env`` is added to the
    recipe's environment. ``ready_timeout`` None: do not wait for ``READY`` (a recipe that never prints it).
    The transports ``transport`` opened in the block are closed before the recipe
    stops. If the block fails, the recipe's output is written to this process's stderr (pytest shows it
    with the failure).
    """
    process = RecipeProcess(recipe, [*(transport.recipe_args if transport_args else []), *args],
                            tmp_path / "recipe.log", cwd=cwd,
                            env=recipe_environment(**transport.environment, **(env or {})))
    try:
        if ready_timeout is not None:
            process.wait_ready(ready_timeout)
        yield process
    except BaseException:
        transport.close()
        process.stop()
        sys.stderr.write(f"recipe {recipe} on {transport.name}:\n{process.output()}\n")
        raise
    else:
        transport.close()  # the askers go first, while the recipe still answers them
        process.stop()
