"""``agentsctl eval run EVALUATION``: run an evaluation and write its results directory.

``EVALUATION`` is a Python file defining ``evaluation`` (an :class:`~agents_core.evals.Evaluation`, or a
function of no arguments returning one), ``file.py:name`` for another name, or ``package.module:name``.
Exit status: 0 when it ran, 130 when Ctrl-C stopped it (what finished is kept), 1 on a bad argument.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from .connection import fail
from .evals import eval_app

if TYPE_CHECKING:
    from ..evals import Evaluation

__all__ = ["load_evaluation", "run"]


def _from_file(path: Path, attr: str) -> Any:
    sys.path.insert(0, str(path.resolve().parent))  # the file's own imports work as with `python file.py`
    name = f"agents_eval_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise fail(f"cannot import {str(path)!r}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    if not hasattr(module, attr):
        raise fail(f"{str(path)!r} defines no {attr!r} (give file.py:NAME for another name)")
    return getattr(module, attr)


def load_evaluation(target: str) -> Evaluation:
    """The :class:`~agents_core.evals.Evaluation` that ``target`` names (see the module docs)."""
    from ..evals import Evaluation  # noqa: PLC0415 - keeps agentsctl's start cheap

    where, _, attr = target.partition(":")
    if where.endswith(".py") or Path(where).is_file():
        path = Path(where)
        if not path.is_file():
            raise fail(f"evaluation file {where!r} does not exist")
        found = _from_file(path, attr or "evaluation")
    else:
        if not attr:
            raise fail(f"{target!r}: give a file.py or module:NAME")
        try:
            found = getattr(importlib.import_module(where), attr)
        except (ImportError, AttributeError) as exc:
            raise fail(f"cannot load {target!r}: {exc}") from None
    if callable(found) and not isinstance(found, Evaluation):
        found = found()
    if not isinstance(found, Evaluation):
        raise fail(f"{target!r} is a {type(found).__name__}, not an Evaluation")
    return found


@eval_app.command("run")
def run(evaluation: Annotated[str, typer.Argument(help="file.py, file.py:NAME or module:NAME")],
        episodes: Annotated[int | None, typer.Option("--episodes", "-n", min=1, help="episodes to run")] = None,
        seed: Annotated[int | None, typer.Option("--seed", "-s", help="episode i resets with seed + i")] = None,
        transport: Annotated[str, typer.Option("--transport", "-t", help="memory, zenoh or ros2")] = "memory",
        out: Annotated[Path | None, typer.Option("--out", "-o", help="results directory (default eval-NAME)")] = None,
        world_process: Annotated[bool, typer.Option(
            "--world-process", help="run the world and the agent in processes of their own")] = False,
        connect: Annotated[list[str] | None, typer.Option("--connect", help="Zenoh endpoint(s) to connect to")] = None,
        workers: Annotated[int, typer.Option("--workers", "-w", min=1,
                                             help="episodes at once, each in a world of its own (memory)")] = 1,
        ) -> None:
    """Run an evaluation's episodes; write results.jsonl, evaluation.json, frames/ and report.html."""
    if transport not in ("memory", "zenoh", "ros2"):
        raise fail(f"unknown transport {transport!r}; use memory, zenoh or ros2")
    from ..evals import run_evaluation  # noqa: PLC0415

    chosen = load_evaluation(evaluation)
    directory = out if out is not None else Path(f"eval-{chosen.name}")
    options = {"connect": list(connect)} if connect and transport == "zenoh" else None
    result = run_evaluation(chosen, directory, transport=transport, transport_options=options, episodes=episodes,
                            seed=seed, world_process=world_process, workers=workers)
    print(f"{chosen.name}: {result.successes}/{len(result.results)} episodes succeeded "
          f"({100 * result.success_rate:.0f} %)", flush=True)
    print(f"results: {result.out_dir / 'results.jsonl'}", flush=True)
    if result.report is not None:
        print(f"report: {result.report}", flush=True)
    if result.interrupted:
        print("interrupted: the episodes that finished are kept", file=sys.stderr, flush=True)
        raise typer.Exit(130)
