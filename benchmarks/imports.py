"""Import cost: a fresh ``python -c "import agents_core"`` against a fresh ``python -c "import numpy"``.

numpy is the baseline: a process that handles images or arrays pays for it anyway (the message
types import it at their first use of an array, not before), so the ratio shows the framework's
cost on the scale of one well-known import (issue 14 asks for ``import agents_core`` at most 1.5
times ``import numpy``; issue 29, the recipe's names at most 1.0 times). Two framework statements are measured:

- ``package``: ``import agents_core`` (names are lazy: nothing else is loaded until used);
- ``ros_names``: ``from agents_core.ros import Topic, Launcher, String``, what a relay recipe
  needs (the launcher, the component runtime, the type table; no model stack).

Each repetition starts one interpreter per statement, the order rotating from one repetition to
the next so that drift hits all alike; one unmeasured round first fills the OS file cache and the
bytecode caches. Two figures per statement, medians over the repetitions:

- ``wall`` (ms): the child process from spawn to exit, as the parent's clock sees it (interpreter
  start-up and shutdown included, the same for both sides);
- ``import`` (ms): the import statement alone, timed inside the child.

The raw record (numpy) is shared by both statements: it is measured once per repetition.

``python -m benchmarks.imports --reps N`` prints the records.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

from .common import REPO, child_env, emit

#: payload -> the framework's statement; the raw side of every payload is RAW.
FRAMEWORK = {
    "package": "import agents_core",
    "ros_names": "from agents_core.ros import Topic, Launcher, String",
}
RAW = "import numpy"

#: What a child runs: the statement between two clock reads, then the time and how many modules it added.
_CHILD = ("import sys, time\n"
          "before = len(sys.modules)\n"
          "t0 = time.perf_counter()\n"
          "{statement}\n"
          "took = time.perf_counter() - t0\n"
          "print(took, len(sys.modules) - before)\n")

#: A fresh interpreter that takes longer than this to import is broken, not slow.
CHILD_TIMEOUT_S = 60.0


class ImportFailed(RuntimeError):
    """A measured interpreter exited with an error or did not finish in time."""


def measure_once(statement: str, env: dict[str, str]) -> tuple[float, float, int]:
    """One fresh interpreter running ``statement``: (wall s, import s, modules added)."""
    start = time.perf_counter()
    try:
        result = subprocess.run([sys.executable, "-c", _CHILD.format(statement=statement)], cwd=REPO, env=env,
                                capture_output=True, text=True, timeout=CHILD_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired as exc:  # subprocess.run has killed and reaped it
        raise ImportFailed(f"{statement!r} took over {CHILD_TIMEOUT_S:.0f} s") from exc
    wall = time.perf_counter() - start
    if result.returncode != 0:
        raise ImportFailed(f"{statement!r} exited with {result.returncode}: {result.stderr.strip()[-1500:]}")
    took, modules = result.stdout.split()
    return wall, float(took), int(modules)


def measure(reps: int, progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """``reps`` interleaved rounds of every statement; one record per (payload, mode)."""
    env = child_env()
    cases = [("raw", RAW), *((payload, statement) for payload, statement in FRAMEWORK.items())]
    for _, statement in cases:  # warm-up: bytecode and file caches; not counted
        measure_once(statement, env)
    samples: dict[str, list[tuple[float, float, int]]] = {key: [] for key, _ in cases}
    for rep in range(reps):
        shift = rep % len(cases)
        for key, statement in cases[shift:] + cases[:shift]:
            samples[key].append(measure_once(statement, env))
        if progress is not None:
            progress(f"{'imports':<10} round {rep + 1}/{reps}: " + ", ".join(
                f"{key} {samples[key][-1][0] * 1000:.0f} ms" for key, _ in cases))

    def record(key: str, statement: str) -> dict[str, Any]:
        walls = [s[0] for s in samples[key]]
        imports = [s[1] for s in samples[key]]
        return {"suite": "imports", "transport": "none", "statement": statement, "wall_s": walls,
                "import_s": imports, "wall_ms": statistics.median(walls) * 1000.0,
                "import_ms": statistics.median(imports) * 1000.0, "modules": samples[key][-1][2]}

    records = []
    for payload, statement in FRAMEWORK.items():
        records.append({**record(payload, statement), "payload": payload, "mode": "framework"})
        records.append({**record("raw", RAW), "payload": payload, "mode": "raw"})
    return records


def run_suite(settings: dict[str, Any], progress: Callable[[str], None]) -> tuple[list[dict[str, Any]],
                                                                                   list[dict[str, str]]]:
    """The import figures; (records, skipped)."""
    try:
        records = measure(int(settings["import_reps"]), progress)
    except ImportFailed as exc:
        progress(f"imports: FAILED: {str(exc).splitlines()[0]}")
        return [], [{"suite": "imports", "transport": "none", "mode": "both", "reason": str(exc)}]
    for r in records:
        if r["mode"] == "framework":
            raw = next(x for x in records if x["mode"] == "raw" and x["payload"] == r["payload"])
            progress(f"{'imports':<10} {r['payload']:<10} wall median {r['wall_ms']:7.1f} ms vs numpy "
                     f"{raw['wall_ms']:7.1f} ms ({r['wall_ms'] / raw['wall_ms']:.2f}x); import alone "
                     f"{r['import_ms']:.1f} ms vs {raw['import_ms']:.1f} ms; {r['modules']} modules "
                     f"vs {raw['modules']} (n={len(r['wall_s'])})")
    return records, []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reps", type=int, default=5)
    args = parser.parse_args(argv)
    for record in measure(args.reps, lambda line: print(line, file=sys.stderr, flush=True)):
        emit(record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
