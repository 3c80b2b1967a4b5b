"""``agentsctl recipe show RECIPE.py [ARGS...]``: a recipe file's recipe as JSON, without running it.

The file runs as ``__main__`` (with ``ARGS`` as its arguments) until its launcher would start;
its components are built, never bound or started (:func:`agents_core.launch.recipe.capture_recipe`).
What the file prints meanwhile goes to stderr, so stdout holds the JSON document alone.
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path
from typing import Annotated

import typer

from .connection import one_line_errors

__all__ = ["app", "show"]

app = typer.Typer(help="Look at a recipe file as data.", no_args_is_help=True)


@app.command("show", context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
@one_line_errors
def show(ctx: typer.Context,
         recipe: Annotated[Path, typer.Argument(help="the recipe file (run as __main__ until it would start)")],
         compact: Annotated[bool, typer.Option("--compact", help="one line of JSON")] = False) -> None:
    """Print the recipe (components, topics, triggers, events and actions, settings) as JSON; secrets redacted."""
    from ..launch.recipe import capture_recipe  # noqa: PLC0415  (loads the launcher: only for this command)

    with contextlib.redirect_stdout(sys.stderr):
        captured = capture_recipe(recipe, list(ctx.args))
        text = captured.to_json(indent=None if compact else 2)
    sys.stdout.write(text + "\n")
    sys.stdout.flush()
