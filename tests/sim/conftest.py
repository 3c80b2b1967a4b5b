"""The sim tests need the ``sim`` extra (Gymnasium, MuJoCo, gym-pusht): skipped, saying so, without it."""

from __future__ import annotations

import importlib.util

import pytest

_MISSING = [m for m in ("gymnasium", "mujoco") if importlib.util.find_spec(m) is None]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if not _MISSING:
        return
    skip = pytest.mark.skip(reason=f"{', '.join(_MISSING)} not installed: pip install 'agents-core[sim]'")
    for item in items:
        if "tests/sim/" in str(item.fspath).replace("\\", "/"):
            item.add_marker(skip)
