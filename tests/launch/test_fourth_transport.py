"""A fourth transport, registered from a test package as a third party would, run by the CLI, the UI and the launcher.

Nothing in agents_core names ``zenloop`` (Zenoh's driver under another name, cross-process) or
``memloop`` (the memory driver under another name, in-process): what the CLI, the UI's attach
mode and the multiprocess launcher need comes from their descriptors
(``tests/fourth_transport/descriptor.py``), registered by an ``agents_core.transports`` entry
point in a ``.dist-info`` folder on the path.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from agents_core import Launcher, Topic
from agents_core.errors import ConfigError
from agents_core.launch.report import describe_transport
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed
from agents_core.transport.registry import available_transports, describe_transport_kind, resolve_transport
from tests.cli.cli_recipe import build
from tests.cli.helpers import REPO, cli_env, start, stop, wait_until
from tests.fourth_transport.descriptor import install_entry_points


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The entry points registering the two transports, on this process's path and on its children's."""
    where = install_entry_points(tmp_path / "site")
    monkeypatch.syspath_prepend(str(where))
    yield where


def _env(site: Path, **extra: str) -> dict[str, str]:
    path = os.pathsep.join([str(site), str(REPO / "src"), str(REPO)])
    return cli_env(PYTHONPATH=path, **extra)


def _cli(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "agents_core.cli", *args], cwd=REPO, env=_env(site),
                          capture_output=True, text=True, timeout=60, check=False)


def test_the_registry_knows_them_by_their_descriptors(site: Path) -> None:
    assert {"zenloop", "memloop"} <= set(available_transports())
    zenloop, memloop = describe_transport_kind("zenloop"), describe_transport_kind("memloop")
    assert zenloop.cross_process and zenloop.attachable and zenloop.endpoints
    assert not memloop.cross_process and not memloop.attachable and memloop.in_process
    assert zenloop.reach(["tcp/127.0.0.1:1"]) == {"mode": "client", "connect": ["tcp/127.0.0.1:1"], "listen": []}


def test_the_in_process_one_runs_a_recipe_and_refuses_what_it_cannot_do(site: Path) -> None:
    launcher = Launcher(transport="memloop", quiet=True)
    launcher.add_pkg(components=build("all"))
    with launcher:
        assert launcher.transport.name == "memloop" and not launcher.transport.capabilities.cross_process
        assert wait_until(launcher.all_active, timeout=10.0, interval=0.05)
    launcher = Launcher(transport="memloop", quiet=True)
    launcher.add_pkg(components=build("listener"), multiprocessing=True)
    with pytest.raises(ConfigError, match="'memloop' lives in one process"):
        launcher.start()
    done = _cli(site, "topics", "list", "--transport", "memloop")
    assert done.returncode == 1 and "memloop transport lives inside one process" in done.stderr, done.stderr
    done = _cli(site, "ui", "--transport", "memloop")
    assert done.returncode == 1 and "not 'memloop'" in done.stderr, done.stderr
    done = _cli(site, "topics", "list", "--transport", "zenloopp")
    assert done.returncode == 1 and "did you mean 'zenloop'" in done.stderr, done.stderr


def test_the_in_process_one_carries_values_in_one_process(site: Path) -> None:
    transport = resolve_transport("memloop")
    got: list[object] = []
    try:
        sub = transport.create_subscription(Topic("x", "String"), got.append)
        transport.create_publisher(Topic("x", "String")).publish("hi")
        assert wait_until(lambda: got == ["hi"], timeout=5.0, interval=0.02)
        sub.close()
    finally:
        transport.close()


@pytest.mark.slow
@pytest.mark.zenoh
def test_cli_ui_and_processes_on_the_cross_process_one(site: Path, tmp_path: Path) -> None:
    """``agentsctl run`` starts a recipe with a process per component on zenloop; the CLI and the UI reach it."""
    skip_unless_installed("zenoh")
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    here = resolve_transport("zenloop", **describe_transport_kind("zenloop").listen(endpoint))
    try:  # the launch report's line is the descriptor's
        assert describe_transport(here) == f"zenloop (the test's own; listen {endpoint})"
    finally:
        here.close()
    log = tmp_path / "recipe.log"
    recipe = start("run", "tests/fourth_transport/recipe.py", "--transport", "zenloop",
                   env=_env(site, AGENTS_ZENOH_LISTEN=endpoint), log=log)
    options = ["--transport", "zenloop", "--connect", endpoint]
    try:
        def pids() -> dict[str, int] | None:
            assert recipe.poll() is None, log.read_text()
            for line in log.read_text(errors="replace").splitlines():
                if line.startswith("PIDS "):
                    return dict(json.loads(line[5:]))
            return None

        assert wait_until(lambda: pids() is not None, timeout=120.0), log.read_text()
        children = pids()
        assert children is not None and set(children) == {"talker", "listener"}
        assert recipe.pid not in children.values() and len(set(children.values())) == 2

        def both_active() -> bool:
            done = _cli(site, "components", "list", "--json", *options)
            return done.returncode == 0 and sorted((c["name"], c["state"]) for c in json.loads(done.stdout)) == [
                ("listener", "active"), ("talker", "active")]
        assert wait_until(both_active, timeout=60.0), log.read_text()

        pytest.importorskip("starlette", reason="the web UI needs the 'ui' extra")
        import httpx  # noqa: PLC0415 - after the skip check

        port = free_tcp_port()
        ui_log = tmp_path / "ui.log"
        ui = start("ui", *options, "--port", str(port), "--seconds", "90", env=_env(site), log=ui_log)
        try:
            def described() -> bool:
                assert ui.poll() is None, ui_log.read_text()
                try:
                    reply = httpx.get(f"http://127.0.0.1:{port}/api/interfaces", timeout=5.0)
                except httpx.HTTPError:
                    return False
                return reply.status_code == 200 and {"talker", "listener"} <= {
                    c["name"] for c in reply.json()["components"]}
            assert wait_until(described, timeout=60.0), ui_log.read_text()
        finally:
            stop(ui)
    finally:
        stop(recipe)
