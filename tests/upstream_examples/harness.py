"""Running an upstream-style recipe file unchanged: in this process on memory, or as a script on Zenoh.

A recipe here ends, as upstream's do, with ``launcher.bringup()`` (which blocks). In this process
:func:`launched_here` runs the file in a thread with ``Launcher.bringup`` wrapped so the test gets
the launcher, and ``multiprocessing=True`` turned off (memory lives in one process). On Zenoh,
:func:`launched_as_script` starts ``python recipe.py`` with the transport chosen through the
environment (``AGENTS_TRANSPORT`` and ``AGENTS_ZENOH_*``), as a user would, and stops it by PID.
The stand-in servers' ports reach a recipe through ``UPSTREAM_*_PORT`` variables (:data:`PORT_VARS`).

Upstream's recipes that leave ``multiprocessing`` off run in their own processes too:
:func:`launched_in_processes` starts ``python -m tests.upstream_examples.harness recipe.py``, which runs
the file as ``python recipe.py`` would (:func:`run_recipe_file`) with every ``add_pkg()`` given
``multiprocessing=True`` when ``AGENTS_MULTIPROCESSING=1`` (:data:`MULTIPROCESSING_ENV`), and prints
``READY`` once every component process is active. The recipe file itself is unchanged.
"""

from __future__ import annotations

import contextlib
import os
import runpy
import sys
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher
from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.testing.recipes import RecipeProcess, recipe_environment
from agents_core.transport.contract import Transport
from agents_core.transport.registry import resolve_transport

RECIPES = Path(__file__).resolve().parent / "recipes"

#: The repository root: ``tests`` is importable from there (the wrapper runs as ``-m tests.upstream_examples.harness``).
ROOT = Path(__file__).resolve().parents[2]
#: ``1`` in a recipe's environment: :func:`run_recipe_file` launches every ``add_pkg()`` with ``multiprocessing=True``.
MULTIPROCESSING_ENV = "AGENTS_MULTIPROCESSING"

#: The environment variables a recipe reads its stand-in servers' ports from.
PORT_VARS = ("UPSTREAM_OLLAMA_PORT", "UPSTREAM_ROBOML_PORT", "UPSTREAM_ROBOML_RESP_PORT", "UPSTREAM_CHROMA_PORT")


class RecipeFailed(AssertionError):
    """The recipe file raised before its launcher was up (an upstream user would see this error)."""


@contextlib.contextmanager
def launched_here(recipe: Path, ports: Mapping[str, int], monkeypatch: pytest.MonkeyPatch,
                  timeout: float = 60.0) -> Iterator[Launcher]:
    """Run ``recipe`` on the memory transport in this process; yield its launcher once every component is active."""
    monkeypatch.setenv("AGENTS_TRANSPORT", "memory")
    for var, port in ports.items():
        monkeypatch.setenv(var, str(port))
    launchers: list[Launcher] = []
    errors: list[BaseException] = []
    bringup, add_pkg = Launcher.bringup, Launcher.add_pkg

    def recording_bringup(self: Launcher) -> None:
        launchers.append(self)
        bringup(self)

    def one_process_add_pkg(self: Launcher, *args: Any, **kwargs: Any) -> None:
        kwargs["multiprocessing"] = False  # the memory transport lives in one process
        add_pkg(self, *args, **kwargs)

    monkeypatch.setattr(Launcher, "bringup", recording_bringup)
    monkeypatch.setattr(Launcher, "add_pkg", one_process_add_pkg)

    def run() -> None:
        try:
            runpy.run_path(str(recipe), run_name="__upstream_recipe__")
        except BaseException as exc:  # reported to the test below
            errors.append(exc)

    thread = threading.Thread(target=run, name=f"recipe-{recipe.stem}", daemon=True)
    thread.start()
    try:
        up = wait_for(lambda: bool(errors) or (bool(launchers) and launchers[0].all_active()), timeout=timeout,
                      interval=0.05)
        if errors:
            raise RecipeFailed(f"{recipe.name}: {type(errors[0]).__name__}: {errors[0]}") from errors[0]
        if not up:
            raise RecipeFailed(f"{recipe.name}: not every component was active within {timeout} s")
        yield launchers[0]
    finally:
        for launcher in launchers:
            launcher.request_stop()
        thread.join(30)
    if errors:
        raise RecipeFailed(f"{recipe.name} stopped with {type(errors[0]).__name__}: {errors[0]}") from errors[0]


@contextlib.contextmanager
def launched_as_script(recipe: Path, ports: Mapping[str, int], tmp_path: Path) -> Iterator[tuple[RecipeProcess,
                                                                                                  Transport]]:
    """Run ``python recipe`` on Zenoh (a private loopback endpoint and namespace); yield it and a Zenoh asker."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    namespace = f"upstream{os.getpid()}x{free_tcp_port()}"
    env = recipe_environment(AGENTS_TRANSPORT="zenoh", AGENTS_ZENOH_MODE="peer", AGENTS_ZENOH_LISTEN=endpoint,
                             AGENTS_ZENOH_NAMESPACE=namespace, **{k: str(v) for k, v in ports.items()})
    process = RecipeProcess(recipe, [], tmp_path / "recipe.log", cwd=recipe.parent, env=env)
    asker = resolve_transport("zenoh", mode="peer", listen=[], connect=[endpoint], multicast_scouting=False,
                              namespace=namespace)
    try:
        yield process, asker
    except BaseException:
        asker.close()
        process.stop()
        raise AssertionError(f"recipe {recipe.name} on zenoh:\n{process.output()}") from None
    asker.close()
    process.stop()


def ask_until(transport: Transport, topic: Any, value: Any, done: Any, *, timeout: float = 60.0,
              every: float = 3.0) -> bool:
    """Publish ``value`` on ``topic`` every ``every`` s until ``done()`` (discovery can drop the first ones)."""
    pub = transport.create_publisher(topic)
    try:
        return wait_for(lambda: done() or (pub.publish(value), False)[1], timeout=timeout, interval=every)
    finally:
        pub.close()


def run_recipe_file(recipe: Path, argv: list[str] | None = None) -> None:
    """Run ``recipe`` as ``python recipe`` would (as ``__main__``, its directory first on ``sys.path``).

    With ``AGENTS_MULTIPROCESSING=1`` each ``add_pkg()`` gets ``multiprocessing=True`` (one process per
    component), whatever the recipe passed; ``READY`` is printed once every component is active.
    """
    add_pkg, bringup = Launcher.add_pkg, Launcher.bringup
    in_processes = os.environ.get(MULTIPROCESSING_ENV, "").strip() == "1"

    def chosen_add_pkg(self: Launcher, *args: Any, **kwargs: Any) -> None:
        if in_processes:
            kwargs["multiprocessing"] = True
        add_pkg(self, *args, **kwargs)

    def announcing_bringup(self: Launcher) -> None:
        def announce() -> None:
            # A hang guard only: the test waits for READY with its own (longer) bound.
            if wait_for(self.all_active, timeout=600.0, interval=0.2):
                print("READY", flush=True)

        threading.Thread(target=announce, name="recipe-ready", daemon=True).start()
        bringup(self)

    setattr(Launcher, "add_pkg", chosen_add_pkg)  # noqa: B010  (a method replaced for this process only)
    setattr(Launcher, "bringup", announcing_bringup)  # noqa: B010
    sys.argv = [str(recipe), *(argv or [])]
    sys.path[0] = str(recipe.parent)  # as ``python recipe.py`` has it (``-m`` put the working directory there)
    runpy.run_path(str(recipe), run_name="__main__")


@contextlib.contextmanager
def launched_in_processes(recipe: Path, ports: Mapping[str, int | str], tmp_path: Path, *,
                          ready_timeout: float = 180.0,
                          env: Mapping[str, str] | None = None) -> Iterator[tuple[RecipeProcess, Transport]]:
    """Run ``recipe`` on Zenoh with ``multiprocessing=True`` (:func:`run_recipe_file`); yield it and a Zenoh asker.

    Waits (bounded by ``ready_timeout``, a hang guard) until every component process is active.
    """
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    namespace = f"upstreammp{os.getpid()}x{free_tcp_port()}"
    extra = dict(env or {})
    # The caller's path entries (stand-ins) first, then the repository (the harness module), then ours.
    python_path = os.pathsep.join(p for p in (extra.pop("PYTHONPATH", ""), str(ROOT),
                                              os.environ.get("PYTHONPATH", "")) if p)
    child_env = recipe_environment(AGENTS_TRANSPORT="zenoh", AGENTS_ZENOH_MODE="peer",
                                   AGENTS_ZENOH_LISTEN=endpoint, AGENTS_ZENOH_NAMESPACE=namespace,
                                   PYTHONPATH=python_path, **{MULTIPROCESSING_ENV: "1"},
                                   **{k: str(v) for k, v in ports.items()}, **extra)
    process = RecipeProcess("tests.upstream_examples.harness", [str(recipe)], tmp_path / "recipe.log",
                            cwd=recipe.parent, env=child_env)
    asker = resolve_transport("zenoh", mode="peer", listen=[], connect=[endpoint], multicast_scouting=False,
                              namespace=namespace)
    try:
        process.wait_ready(ready_timeout)
        yield process, asker
    except BaseException:
        asker.close()
        process.stop()
        raise AssertionError(f"recipe {recipe.name} on zenoh, multiprocessing=True:\n{process.output()}") from None
    asker.close()
    process.stop()


if __name__ == "__main__":
    run_recipe_file(Path(sys.argv[1]).resolve(), sys.argv[2:])
