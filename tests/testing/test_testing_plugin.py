"""The conformance suite as a plugin: a transport installed through an entry point runs it with one line.

Each test builds, in ``tmp_path``, a fake installed distribution (a ``*.dist-info`` folder whose
``entry_points.txt`` registers two tiny transports under ``agents_core.transports``, and a pair
factory for one of them under ``agents_core.conformance_pairs``) and a project whose
``conftest.py`` is the one line ``pytest_plugins = ["agents_core.testing"]``, then runs
``python -m pytest`` there in a subprocess (bounded by a timeout) with ``PYTHONPATH`` on the fake
distribution. ``loopmem`` has a pair factory of its own; ``solomem`` has none and gets the
default pair (one instance used from both sides).
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

#: Tests per transport in the shipped suite: every registered type round-trips, then 13 more on topics,
#: requests and presence, and 8 on long-running goals (agents_core.testing.goals_suite).
SUITE_TESTS = len(__import__("agents_core.supported_types", fromlist=["x"]).registered_types()) + 13 + 8
#: Tests of the suite that take no transport pair, collected once (a driver without goals says so).
PAIRLESS_TESTS = 1

TRANSPORT_MODULE = '''
"""Two tiny transports for the plugin test: the memory transport under other names."""

from __future__ import annotations

import contextlib

from agents_core.transport import MemoryTransport


class LoopMemTransport(MemoryTransport):
    """The memory transport, registered as "loopmem" (with a pair factory)."""


class SoloMemTransport(MemoryTransport):
    """The memory transport, registered as "solomem" (no pair factory: the default pair)."""


OPENED = []


@contextlib.contextmanager
def loopmem_pair():
    transport = LoopMemTransport()
    OPENED.append(transport)
    try:
        yield transport, transport
    finally:
        transport.close()
'''

ENTRY_POINTS = '''
[agents_core.transports]
loopmem = loopmem_transport:LoopMemTransport
solomem = loopmem_transport:SoloMemTransport

[agents_core.conformance_pairs]
loopmem = loopmem_transport:loopmem_pair
'''

#: A project's own test: the fixture serves it too, with the pair each transport registered (or the default).
PROJECT_TEST = '''
import loopmem_transport


def test_own_test_gets_the_registered_pair(transport_pair, request):
    a, b = transport_pair
    name = request.node.callspec.params["transport_pair"]
    if name == "loopmem":  # its own pair factory opened it
        assert type(a).__name__ == "LoopMemTransport" and a in loopmem_transport.OPENED
    if name == "solomem":  # no pair factory: one resolve_transport("solomem") used from both sides
        assert type(a).__name__ == "SoloMemTransport" and a is b
'''


@pytest.fixture
def site(tmp_path: Path) -> Path:
    """A folder that looks like site-packages with the ``loopmem`` distribution installed."""
    site = tmp_path / "site"
    dist_info = site / "loopmem-0.1.dist-info"
    dist_info.mkdir(parents=True)
    (dist_info / "METADATA").write_text("Metadata-Version: 2.1\nName: loopmem\nVersion: 0.1\n")
    (dist_info / "entry_points.txt").write_text(ENTRY_POINTS)
    (site / "loopmem_transport.py").write_text(TRANSPORT_MODULE)
    return site


def _project(root: Path, ini: str) -> Path:
    root.mkdir()
    (root / "conftest.py").write_text('pytest_plugins = ["agents_core.testing"]\n')
    (root / "pytest.ini").write_text(textwrap.dedent(ini))
    return root


def _pytest(project: Path, site: Path, *args: str) -> str:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    env["PYTHONPATH"] = os.pathsep.join([str(site), *filter(None, [os.environ.get("PYTHONPATH")])])
    # A ROS domain of this run's own and discovery on this host, as the nox session sets them.
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args], cwd=project,
                          env=env, capture_output=True, text=True, timeout=240, check=False)
    out = proc.stdout + proc.stderr
    assert proc.returncode in (0, 5), f"pytest failed (exit {proc.returncode}):\n{out[-6000:]}"
    return out


def _count(out: str, what: str) -> int:
    found = re.search(rf"(\d+) {what}", _summary(out))
    return int(found.group(1)) if found else 0


def _summary(out: str) -> str:
    return next(line for line in reversed(out.splitlines()) if line.strip())


STRICT_INI = """\
    [pytest]
    addopts = -ra --strict-markers --strict-config
    filterwarnings = error
"""


def test_collects_the_suite_for_every_installed_transport(tmp_path: Path, site: Path) -> None:
    project = _project(tmp_path / "project", STRICT_INI)
    out = _pytest(project, site, "--collect-only", "-q")
    ids = [line for line in out.splitlines() if "::" in line]
    per_transport = {name: sum(f"[{name}]" in i or f"[{name}-" in i for i in ids)
                     for name in ("memory", "zenoh", "ros2", "rmw_zenoh", "loopmem", "solomem")}
    # Every transport, built in or installed, is a parameter, whether or not its extra is here.
    assert per_transport == dict.fromkeys(per_transport, SUITE_TESTS), per_transport
    assert len(ids) == 6 * SUITE_TESTS + PAIRLESS_TESTS, "the suite must be collected exactly once"
    assert all(i.startswith("conftest.py::test_") for i in ids), ids[:3]


def test_marker_selects_the_entry_point_transport_only(tmp_path: Path, site: Path) -> None:
    project = _project(tmp_path / "project", STRICT_INI)
    out = _pytest(project, site, "--collect-only", "-q", "-m", "loopmem")
    ids = [line for line in out.splitlines() if "::" in line]
    assert len(ids) == SUITE_TESTS and all("loopmem" in i for i in ids), ids[:3]
    # memory, zenoh, ros2, rmw_zenoh and the two entry-point transports
    total, deselected = 6 * SUITE_TESTS + PAIRLESS_TESTS, 5 * SUITE_TESTS + PAIRLESS_TESTS
    assert f"{SUITE_TESTS}/{total} tests collected ({deselected} deselected)" in out, _summary(out)


def test_suite_passes_on_entry_point_transports(tmp_path: Path, site: Path) -> None:
    project = _project(tmp_path / "project", STRICT_INI)
    (project / "test_own.py").write_text(PROJECT_TEST)
    out = _pytest(project, site, "-m", "loopmem or solomem", "-v")
    passed = [line for line in out.splitlines() if " PASSED " in line]
    # The whole suite on each, plus the project's own test on each.
    assert _count(out, "passed") == 2 * SUITE_TESTS + 2, _summary(out)
    assert len(passed) == 2 * SUITE_TESTS + 2 and all("loopmem" in p or "solomem" in p for p in passed), passed[:3]
    assert "failed" not in _summary(out) and "skipped" not in _summary(out), _summary(out)


def test_built_in_transports_run_or_skip_as_the_environment_allows(tmp_path: Path, site: Path) -> None:
    project = _project(tmp_path / "project", STRICT_INI)
    # One quick test per transport is enough to see each one run or skip with its reason.
    out = _pytest(project, site, "-m", "memory or zenoh or ros2", "-k", "missing_service", "-rs")
    expected_passed = 1
    for name, module in (("zenoh", "zenoh"), ("ros2", "rclpy")):
        if importlib.util.find_spec(module) is None:
            assert f"{name} transport not available here: the '{name}' extra is not installed" in out, out[-3000:]
        else:
            expected_passed += 1
    assert _count(out, "passed") == expected_passed, _summary(out)
    assert _count(out, "skipped") == 3 - expected_passed, _summary(out)


def test_suite_is_not_added_when_other_files_are_named(tmp_path: Path, site: Path) -> None:
    project = _project(tmp_path / "project", STRICT_INI)
    (project / "test_other.py").write_text("def test_alone():\n    pass\n")
    out = _pytest(project, site, "test_other.py")
    assert _count(out, "passed") == 1, _summary(out)


def test_root_conftest_with_testpaths_still_collects_the_suite_once(tmp_path: Path, site: Path) -> None:
    project = _project(tmp_path / "project", STRICT_INI + "    testpaths = tests\n")
    (project / "tests").mkdir()
    (project / "tests" / "test_other.py").write_text("def test_alone():\n    pass\n")
    out = _pytest(project, site, "--collect-only", "-q", "-m", "loopmem or not conformance")
    ids = [line for line in out.splitlines() if "::" in line]
    assert len(ids) == SUITE_TESTS + PAIRLESS_TESTS + 1, ids[:5]
    assert "tests/test_other.py::test_alone" in ids
