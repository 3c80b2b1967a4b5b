"""This repository's conformance run: the shipped plugin, enabled for this directory only.

The suite itself lives in ``agents_core.testing.suite`` and is collected here, under this
``conftest.py`` (``pytest tests/conformance``, ``-m memory`` / ``-m zenoh`` / ``-m ros2``). A
``conftest.py`` below the rootdir may not use ``pytest_plugins``, so the plugin's hooks and fixture
are imported instead (see ``agents_core.testing``); a transport package of your own needs only
``pytest_plugins = ["agents_core.testing"]`` in its top ``conftest.py``.
"""

from __future__ import annotations

from agents_core.testing import (
    pytest_collect_file,
    pytest_configure,
    pytest_generate_tests,
    pytest_make_collect_report,
    transport_pair,
)

__all__ = [
    "pytest_collect_file",
    "pytest_configure",
    "pytest_generate_tests",
    "pytest_make_collect_report",
    "transport_pair",
]
