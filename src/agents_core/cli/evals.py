"""``agentsctl eval ...``: the evaluation commands' sub-app (``run`` is in :mod:`.eval_run`).

A stand-in on the s7-sim branch: s7-evalreport's module of the same name (with ``report`` and
``compare``) replaces it at merge.
"""

from __future__ import annotations

import typer

__all__ = ["eval_app"]

eval_app = typer.Typer(name="eval", no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                       help="Score agents over seeded episodes in a simulated world.")
