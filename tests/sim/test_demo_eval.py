"""``nox -s demo -- eval`` (``python -m agents_core.demo eval``): the Reacher expert scored against a random agent."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path


def test_the_evaluation_demo_scores_both_agents_and_says_where(tmp_path: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "agents_core.demo", "eval", "--episodes", "3", "--out",
                             str(tmp_path)], capture_output=True, text=True, timeout=240, check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    out = result.stdout
    assert "expert: 3/3 succeeded (100 %)" in out
    assert f"results in {tmp_path / 'random' / 'results.jsonl'}" in out
    for agent in ("expert", "random"):
        lines = (tmp_path / agent / "results.jsonl").read_text(encoding="utf-8").splitlines()
        assert [json.loads(line)["seed"] for line in lines] == [1000, 1001, 1002]
