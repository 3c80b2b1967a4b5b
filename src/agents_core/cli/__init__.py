"""``agentsctl``: run recipes and inspect a live graph (topics, components, actions) on Zenoh and ROS 2.

Installed as the ``agentsctl`` console script (the ``cli`` extra brings Typer and Rich); also
``python -m agents_core.cli``. See ``docs/cli.md``. Nothing here imports a middleware: the CLI
speaks through the same :class:`~agents_core.transport.contract.Transport` as recipes do.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__, own=("main",))


def main() -> None:
    """The console script's entry point."""
    from .app import app  # noqa: PLC0415 - Typer is imported only when the CLI runs
    from .output import install_safe_logging  # noqa: PLC0415 - Rich is imported only when the CLI runs

    install_safe_logging()
    app()
