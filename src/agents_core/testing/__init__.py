"""The transport conformance suite as a pytest plugin: run it on your own transport with one line.

A package that ships a transport (registered under the ``agents_core.transports`` entry-point
group) runs the suite that every built-in transport passes by putting one line in the
``conftest.py`` of its tests directory (or of its project root)::

    pytest_plugins = ["agents_core.testing"]

The plugin is opt-in on purpose (no ``pytest11`` auto-loading): it adds tests to the run, so it
must never appear in the pytest runs of projects that merely have agents-core installed. It
needs pytest 8 or newer.

What it does:

* **The suite.** The tests of :mod:`agents_core.testing.suite` are collected as if they were
  defined in the ``conftest.py`` that enables the plugin (node ids read
  ``tests/conftest.py::test_request_reply[zenoh]``; tracebacks point into ``suite.py``). They
  are collected when pytest collects that conftest's directory (``pytest``, ``pytest tests``, or
  the node id itself), never when you name other test files. If that ``conftest.py`` lies above
  what pytest collects (a root ``conftest.py`` with ``testpaths = ["tests"]``), the suite is
  collected once, under the first collected directory below it.
* **The fixture.** ``transport_pair`` yields ``(a, b)``, two transports that reach each other;
  it is parametrized over every installed transport: ``memory``, ``zenoh``, ``ros2`` and every
  name under the ``agents_core.transports`` or ``agents_core.conformance_pairs`` entry-point
  groups. Your own tests may request it too. How each pair is built:
  :mod:`agents_core.testing.pairs` (a third-party transport without a pair factory is tested as
  one instance used from both sides).
* **Markers.** Each parameter carries a marker named after its transport and the
  ``conformance`` marker, all registered here (``--strict-markers`` accepts them):
  ``pytest -m loopmem`` runs the suite on the ``loopmem`` transport only, ``-m "not ros2"``
  leaves ROS 2 out, ``-m "not conformance"`` leaves the suite out.
* **Skips.** A built-in transport whose extra is not installed (no ``zenoh`` / ``rclpy``
  module) is skipped with the ``pip install`` that fixes it; so is a transport that raises
  :class:`~agents_core.errors.TransportNotAvailableError` when opened, and a third-party
  transport whose modules are missing. Any other error fails the test.

Where ``pytest_plugins`` is not allowed (a ``conftest.py`` below the rootdir), import the
plugin's hooks and fixture instead; they then apply to that directory only::

    from agents_core.testing import *  # noqa: F403

Loaded with ``-p agents_core.testing`` and no such ``conftest.py``, the plugin provides the
fixture and the markers but collects no suite (there is no directory to attach it to).
"""

from __future__ import annotations

import contextlib
import importlib
import sys
import types
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from ..errors import TransportNotAvailableError
from ..support.lazy import lazy_facade
from ..transport.contract import Transport
from .pairs import BUILTIN_PAIRS, conformance_transports, missing_requirement, pair_factory
from .pairs import PAIR_ENTRY_POINT_GROUP as PAIR_ENTRY_POINT_GROUP

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__, own=(
        "CONFORMANCE_MARKER", "SUITE_MODULE", "ConformanceSuite", "pytest_collect_file", "pytest_configure",
        "pytest_generate_tests", "pytest_make_collect_report", "transport_pair"))

#: The module that holds the suite's ``test_*`` functions.
SUITE_MODULE = f"{__name__}.suite"

#: The marker every parameter of ``transport_pair`` carries (besides its transport's name).
CONFORMANCE_MARKER = "conformance"

# The suite is imported by ConformanceSuite, not by pytest's own importer, so ask for assertion
# rewriting explicitly (plain `assert`s then report their operands, as in any test module).
if SUITE_MODULE not in sys.modules:
    pytest.register_assert_rewrite(SUITE_MODULE)

_PARAMS = pytest.StashKey[list[Any]]()
_PARAMETRIZED = pytest.StashKey[set[str]]()
_ATTACHED = pytest.StashKey[set[Path]]()


class ConformanceSuite(pytest.Module):
    """The shipped suite, collected as a module whose path is the ``conftest.py`` that enables the plugin.

    Taking the conftest's path (not ``suite.py``'s, which may lie in site-packages, outside the
    rootdir) keeps node ids inside the project and lets ``pytest <node id>`` re-run one test.
    """

    def _getobj(self) -> types.ModuleType:
        # The module is imported by name: importing it by path would put its parent folder on sys.path.
        return importlib.import_module(SUITE_MODULE)


def pytest_configure(config: pytest.Config) -> None:
    """Register one marker per installed transport and the ``conformance`` marker."""
    for name in conformance_transports():
        config.addinivalue_line("markers", f"{name}: the conformance suite on the {name} transport (agents_core)")
    config.addinivalue_line("markers", f"{CONFORMANCE_MARKER}: the agents_core transport conformance suite")


def _params(config: pytest.Config) -> list[Any]:
    """One ``pytest.param`` per installed transport, with its markers and, if its extra is absent, a skip."""
    params = config.stash.get(_PARAMS, None)
    if params is None:
        params = []
        for name in conformance_transports():
            marks = [getattr(pytest.mark, name), getattr(pytest.mark, CONFORMANCE_MARKER)]
            reason = missing_requirement(name)
            if reason is not None:
                marks.append(pytest.mark.skip(reason=reason))
            params.append(pytest.param(name, marks=marks, id=name))
        config.stash[_PARAMS] = params
    return params


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrize every test that requests ``transport_pair`` over the installed transports."""
    if "transport_pair" not in metafunc.fixturenames:
        return
    # Once per test, even if the hooks are registered twice (pytest_plugins and an import).
    done = metafunc.config.stash.setdefault(_PARAMETRIZED, set())
    if metafunc.definition.nodeid in done:
        return
    done.add(metafunc.definition.nodeid)
    metafunc.parametrize("transport_pair", _params(metafunc.config), indirect=True)


@pytest.fixture
def transport_pair(request: pytest.FixtureRequest) -> Iterator[tuple[Transport, Transport]]:
    """``(a, b)``: two transports of one kind that reach each other; both closed after the test.

    ``a`` publishes, serves and declares; ``b`` subscribes, requests and observes.
    """
    name = getattr(request, "param", None)
    if not isinstance(name, str):
        pytest.fail("transport_pair is parametrized by the agents_core.testing plugin; enable it in conftest.py")
    with contextlib.ExitStack() as stack:
        try:
            pair = stack.enter_context(pair_factory(name)())
        except TransportNotAvailableError as exc:
            pytest.skip(f"{name} transport not available here: {exc}")
        except ModuleNotFoundError as exc:
            if name in BUILTIN_PAIRS:
                raise  # the extra is installed (checked at collection), so this is a bug to report
            pytest.skip(f"{name} transport not available here: {exc}")
        yield pair


def _enabling_conftests(config: pytest.Config) -> list[Path]:
    """The ``conftest.py`` files that enable this plugin, by ``pytest_plugins`` or by importing its hooks."""
    found = []
    for name, plugin in config.pluginmanager.list_name_plugin():
        # pytest registers each conftest module under its absolute path.
        if not isinstance(plugin, types.ModuleType) or not name or not name.endswith("conftest.py"):
            continue
        declared = getattr(plugin, "pytest_plugins", ())
        if isinstance(declared, str):
            declared = [declared]
        if __name__ in declared or getattr(plugin, "transport_pair", None) is transport_pair:
            found.append(Path(name))
    return found


def _collected_whole(session: pytest.Session, conftest: Path) -> bool:
    """Whether pytest collects ``conftest``'s directory as a whole (or names the conftest itself)."""
    anchor = conftest.parent
    return session.isinitpath(conftest) or any(session.isinitpath(p) for p in (anchor, *anchor.parents))


def _claim(session: pytest.Session, conftest: Path) -> bool:
    """True the first time the suite of ``conftest`` is attached in this session."""
    attached = session.stash.setdefault(_ATTACHED, set())
    if conftest in attached:
        return False
    attached.add(conftest)
    return True


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> ConformanceSuite | None:
    """Collect the suite when pytest reaches a ``conftest.py`` that enables the plugin."""
    if file_path.name != "conftest.py" or file_path not in _enabling_conftests(parent.config):
        return None
    if not _collected_whole(parent.session, file_path) or not _claim(parent.session, file_path):
        return None
    return ConformanceSuite.from_parent(parent, path=file_path)


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, pytest.CollectReport,
                                                                          pytest.CollectReport]:
    """Collect the suite under an initial directory that lies below the enabling ``conftest.py``.

    That conftest is never offered to :func:`pytest_collect_file` then (a root ``conftest.py``
    with ``testpaths = ["tests"]``), so the suite goes to the first such directory.
    """
    report = yield
    if not isinstance(collector, pytest.Directory) or not report.passed:
        return report
    session = collector.session
    if not session.isinitpath(collector.path):
        return report
    for conftest in _enabling_conftests(collector.config):
        below = conftest.parent in collector.path.parents
        if below and not _collected_whole(session, conftest) and _claim(session, conftest):
            report.result.append(ConformanceSuite.from_parent(collector, path=conftest))
    return report
