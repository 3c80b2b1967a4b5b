"""``python -m agents_core.cli``: the same as the ``agentsctl`` console script."""

from __future__ import annotations

from . import main

main()
