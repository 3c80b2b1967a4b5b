"""The memory and cortex benchmarks run and report what benchmarks/README.md says (small counts: no timing asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.common import child_env
from benchmarks.memory import committed, measure

REPO = Path(__file__).resolve().parent.parent


def test_the_memory_bench_stores_every_value_on_both_sides_and_reports_each_figure(tmp_path: Path) -> None:
    pytest.importorskip("emem", reason="the memory extra is not installed")
    lines: list[str] = []
    records = measure(12, 2, 3, tmp_path, lines.append)  # 12 values: rounded down to whole batches of 5
    assert sorted((r["payload"], r["mode"], r["round"]) for r in records) == sorted(
        (payload, mode, rnd) for payload in ("string", "method_call") for mode in ("raw", "framework")
        for rnd in (0, 1))
    for r in records:
        assert r["search_median_us"] > 0
        assert r["payload"] == "method_call" or (r["writes_per_s"] > 0 and r["values"] == 10)
    # The warm-up's 10 and two rounds of 10 each, committed on both sides.
    assert committed(tmp_path / "raw.db") == committed(tmp_path / "framework.db") == 30
    assert len(lines) == 6


def test_the_cortex_bench_child_reports_the_overhead_of_a_step() -> None:
    done = subprocess.run([sys.executable, "-m", "benchmarks.cortex", "--reps", "3", "--warmup", "1"], cwd=REPO,
                          env=child_env(), capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    record = json.loads([line for line in done.stdout.splitlines() if line.startswith("{")][-1])
    assert record["suite"] == "cortex" and record["reps"] == 3
    assert 0 < record["latency_ms"]["p50"] <= record["latency_ms"]["p99"] < 5000
