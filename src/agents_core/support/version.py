"""The package version, from one place: ``version`` in pyproject.toml.

An installed package (wheel, sdist or ``pip install -e .``) reads it from its metadata; a source
tree used without installing (``PYTHONPATH=src``) reads it from the pyproject.toml beside ``src/``.
``agents_core.__version__`` calls this on first access only: importlib.metadata costs tens of
milliseconds that ``import agents_core`` should not pay.
"""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["DISTRIBUTION", "UNKNOWN_VERSION", "package_version"]

#: The distribution name on PyPI (``pip install agents-core``).
DISTRIBUTION = "agents-core"

#: What ``__version__`` says when neither the metadata nor a pyproject.toml can be read.
UNKNOWN_VERSION = "0+unknown"

_PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"


def _source_tree_version(pyproject: Path) -> str | None:
    """``[project] version`` of a checkout's pyproject.toml, None when there is none (or another project's)."""
    try:
        text = pyproject.read_text(encoding="utf-8")
    except OSError:
        return None
    # A regex, not tomllib: Python 3.10 has no tomllib, and tomli is only a dependency there.
    project = re.search(r"^\[project\]\s*$(.*?)(?=^\[|\Z)", text, flags=re.M | re.S)
    if project is None or not re.search(rf'^name\s*=\s*"{DISTRIBUTION}"', project.group(1), flags=re.M):
        return None
    found = re.search(r'^version\s*=\s*"([^"]+)"', project.group(1), flags=re.M)
    return found.group(1) if found else None


def package_version(pyproject: Path = _PYPROJECT) -> str:
    """The checkout's pyproject.toml version, else the installed distribution's, else ``0+unknown``.

    The pyproject.toml looked at is the one two levels above this package (``src/..``): it exists
    in a checkout (used from ``src`` or installed editable) and never inside a wheel's install, so
    a checkout on ``PYTHONPATH`` reports its own version, not an older installed copy's.
    """
    from_source = _source_tree_version(pyproject)
    if from_source is not None:
        return from_source
    from importlib.metadata import PackageNotFoundError, version  # noqa: PLC0415  (costly; first use only)

    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return UNKNOWN_VERSION
