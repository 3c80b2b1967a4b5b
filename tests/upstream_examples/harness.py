"""Running an upstream-style recipe file unchanged: in this process on memory, or as a script on Zenoh.

A recipe here ends, as upstream's do, with ``launcher.bringup()`` (which blocks). In this process
:func:`launched_here` runs the file in a thread with ``Launcher.bringup`` wrapped so the test gets
the launcher, and ``multiprocessing=True`` turned off (memory lives in one process). On Zenoh,
:func:`launched_as_script` starts ``python recipe.py`` with the transport chosen through the
environment (``AGENTS_TRANSPORT`` and ``AGENTS_ZENOH_*``), as a user would, and stops it by PID.
The stand-in servers' ports reach a recipe through ``UPSTREAM_*_PORT`` variables (:data:`PORT_VARS`).
"""

from __future__ import annotations

import contextlib
import os
import runpy
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
