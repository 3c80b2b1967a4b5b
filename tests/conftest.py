"""Shared fixtures and helpers for the test suite.

``recipe_transport`` (from :mod:`agents_core.testing.recipes`) parametrizes a recipe-process test
over the installed cross-process transports; see that module for the harness that runs the recipe.
"""

from __future__ import annotations

import gc
import os

import pytest

from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.testing.recipes import recipe_transport
from agents_core.transport import MemoryTransport

__all__ = ["free_tcp_port", "recipe_transport", "wait_for"]

# Launchers print status lines on stderr by default (agents_core.launch.report); the suite's
# output, and the recipes it starts as child processes, stay quiet. The report's tests turn them on.
os.environ.setdefault("AGENTS_QUIET", "1")


@pytest.fixture(scope="module", autouse=True)
def _collect_garbage_per_module():
    """Collect each module's garbage at its end, so that a socket or file left for the collector is reported
    on that module's last test (pytest's unraisable-exception check, an error under ``filterwarnings = error``)
    instead of as a nameless error after the whole run."""
    yield
    gc.collect()


@pytest.fixture
def memory() -> MemoryTransport:
    transport = MemoryTransport()
    yield transport
    transport.close()
