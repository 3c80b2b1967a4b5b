"""Item 8 of issue 38: a component in its own process shows its health in the launcher's rows (it showed
``-``), and ``health_status`` prints as its name (it printed ``2``). The failing component's process also
logs its failure once, then counts it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from agents_core.components import Component
from agents_core.status import HealthStatus
from agents_core.testing.helpers import free_tcp_port

RECIPE = Path(__file__).with_name("flaky_recipe.py")
REPO = Path(__file__).resolve().parents[2]


def test_health_status_prints_as_its_name() -> None:
    ticker = Component(inputs=[], outputs=[], trigger=1.0, component_name="ticker")
    assert str(ticker.health_status) == "HEALTHY" and f"{HealthStatus.COMPONENT_FAILURE}" == "COMPONENT_FAILURE"
    assert HealthStatus.COMPONENT_FAILURE == 2 and f"{HealthStatus.COMPONENT_FAILURE:d}" == "2"


@pytest.mark.zenoh
def test_a_component_process_shows_its_health() -> None:
    pytest.importorskip("zenoh")
    env = {k: v for k, v in os.environ.items() if not k.startswith("AGENTS_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, str(RECIPE), "4"], capture_output=True, text=True, timeout=120,
                          check=False, env={**env, "AGENTS_ZENOH_PORT": str(free_tcp_port())})
    assert done.returncode == 0, done.stderr[-3000:]
    rows = [line for line in done.stderr.splitlines() if " flaky " in line and "own process" in line]
    assert any("component_failure" in row for row in rows), done.stderr[-3000:]
    failures = [line for line in done.stderr.splitlines() if "step failed (COMPONENT_FAILURE)" in line]
    assert len(failures) <= 2, failures  # once (and a summary at most), not ~80 times
