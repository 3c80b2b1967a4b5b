"""``agentsctl foxglove``: its refusals are one line on stderr, never a traceback or a bind."""

from __future__ import annotations

import pytest

pytest.importorskip("typer")
pytest.importorskip("foxglove")

from ..cli.helpers import cli


def test_off_loopback_is_refused_before_anything_opens() -> None:
    done = cli("foxglove", "--transport", "zenoh", "--host", "0.0.0.0", "--seconds", "0.1", timeout=60)
    assert done.returncode == 1, done.stderr
    assert done.stderr.startswith("error: ") and "--insecure-remote" in done.stderr
    assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1


def test_the_memory_transport_is_refused() -> None:
    done = cli("foxglove", "--transport", "memory", "--seconds", "0.1", timeout=60)
    assert done.returncode == 1 and "lives inside one process" in done.stderr
    assert "Traceback" not in done.stderr


def test_help_names_the_command() -> None:
    done = cli("--help", timeout=60)
    assert done.returncode == 0 and "foxglove" in done.stdout
