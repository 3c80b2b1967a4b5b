"""``python -m agents_core.demo eval``: score the Reacher-v5 scripted expert against a random agent.

Runs a few lock-step episodes of each (``examples/evaluate_reacher.py``: Gymnasium's MuJoCo
Reacher, success = the fingertip within 2 cm of the target at the end), prints their success
rates and where the results and reports are. Needs the ``sim`` extra (``nox -s demo -- eval``
installs it) and the checkout's ``examples/`` folder.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

from .support.install_hint import install_hint

__all__ = ["main"]

#: The checkout's examples folder (beside src/).
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _example() -> ModuleType | None:
    path = EXAMPLES / "evaluate_reacher.py"
    if not path.is_file():
        return None
    sys.path.insert(0, str(EXAMPLES))  # its `example_cli` import
    spec = importlib.util.spec_from_file_location("evaluate_reacher", path)
    if spec is None or spec.loader is None:
        return None
    module = importlib.util.module_from_spec(spec)
    sys.modules["evaluate_reacher"] = module
    spec.loader.exec_module(module)
    return module


def main(argv: list[str] | None = None) -> int:
    """Run the evaluation demo (see the module docs); returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m agents_core.demo eval", description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=5, help="episodes per agent")
    parser.add_argument("--seed", type=int, default=1000, help="episode i resets with seed + i")
    parser.add_argument("--out", type=Path, default=Path("eval-demo"), help="where the results go")
    parser.add_argument("--transport", choices=["memory", "zenoh", "ros2"], default="memory")
    args = parser.parse_args(argv)
    missing = [m for m in ("gymnasium", "mujoco") if importlib.util.find_spec(m) is None]
    if missing:
        print(f"The evaluation demo needs {', '.join(missing)}: {install_hint('sim')}")
        return 2
    example = _example()
    if example is None:
        print(f"The evaluation demo runs examples/evaluate_reacher.py from a checkout; none beside {EXAMPLES.parent}")
        return 2
    from .evals import run_evaluation  # noqa: PLC0415

    print(f"Scoring two agents on Reacher-v5 over {args.episodes} seeded episodes each (lock-step, "
          f"{args.transport}); success: the fingertip within 2 cm of the target after 50 steps.", flush=True)
    for agent in ("expert", "random"):
        run = run_evaluation(example.evaluation(agent, args.episodes, args.seed), args.out / agent,
                             transport=args.transport)
        print(f"  {agent:>6}: {run.successes}/{len(run.results)} succeeded ({100 * run.success_rate:.0f} %)"
              f"; results in {run.out_dir / 'results.jsonl'}", flush=True)
        if run.report is not None:
            print(f"          report: {run.report.resolve()}", flush=True)
        if run.interrupted:
            return 130
    print(f"Done. Open the reports in a browser, or compare the two: agentsctl eval compare {args.out / 'expert'} "
          f"{args.out / 'random'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
