"""The Zenoh transport (work in progress: see the project's issue on the Zenoh adapter)."""

from __future__ import annotations

import zenoh  # noqa: F401  # the dependency check: a missing extra fails here, with the extra named by the registry

__all__: list[str] = []
