"""``agentsctl eval run``: an evaluation file runs from the command line; Ctrl-C keeps the episodes that finished."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from agents_core.testing.helpers import wait_for

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "evaluate_reacher.py"


def _agentsctl(*args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    env.pop("AGENTS_TRANSPORT", None)
    return subprocess.Popen([sys.executable, "-m", "agents_core.cli", "eval", "run", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _lines(path: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()] if path.is_file() else []


def test_eval_run_scores_the_example(tmp_path: Path) -> None:
    proc = _agentsctl(str(EXAMPLE), "--episodes", "3", "--seed", "7", "--out", str(tmp_path))
    out, err = proc.communicate(timeout=180)
    assert proc.returncode == 0, err[-3000:]
    assert "reacher-expert: 3/3 episodes succeeded (100 %)" in out
    assert [line["seed"] for line in _lines(tmp_path / "results.jsonl")] == [7, 8, 9]
    assert json.loads((tmp_path / "evaluation.json").read_text(encoding="utf-8"))["seeds"] == [7, 8, 9]


def test_ctrl_c_stops_cleanly_and_keeps_what_finished(tmp_path: Path) -> None:
    proc = _agentsctl(f"{EXAMPLE}:evaluation", "--episodes", "500", "--out", str(tmp_path))
    try:
        assert wait_for(lambda: len(_lines(tmp_path / "results.jsonl")) >= 2, timeout=120, interval=0.1)
        proc.send_signal(signal.SIGINT)
        _out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    assert proc.returncode == 130, err[-3000:]
    lines = _lines(tmp_path / "results.jsonl")
    assert 2 <= len(lines) < 500
    assert [line["episode"] for line in lines] == list(range(len(lines)))
    assert all(line["ended"] == "truncated" for line in lines[:-1]) and lines[-1]["ended"] in ("truncated",
                                                                                                 "interrupted")
    meta = json.loads((tmp_path / "evaluation.json").read_text(encoding="utf-8"))
    assert meta["interrupted"] is True and meta["finished"] is not None


def test_eval_run_names_what_is_missing(tmp_path: Path) -> None:
    proc = _agentsctl(f"{EXAMPLE}:nothing_here", "--out", str(tmp_path))
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert "defines no 'nothing_here'" in err
