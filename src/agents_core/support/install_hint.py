"""The pip command that installs an extra, worded for how this copy of the package was installed.

The package is used from a checkout (``pip install -e .`` or ``PYTHONPATH=src``) as often as from a
registry, and ``pip install 'agents-core[zenoh]'`` fails in a checkout until a release exists. An
error message that names a missing extra asks :func:`install_hint` for the command, which gives the
checkout form (with the checkout's path) when the package runs from one, else the registry form.
"""

from __future__ import annotations

from pathlib import Path

from .version import DISTRIBUTION, _source_tree_version

__all__ = ["install_hint"]

_PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"


def install_hint(extra: str, pyproject: Path = _PYPROJECT) -> str:
    """``pip install -e '<checkout>[extra]'`` from a checkout, ``pip install 'agents-core[extra]'`` otherwise."""
    if _source_tree_version(pyproject) is not None:
        return f"pip install -e '{pyproject.parent}[{extra}]'"
    return f"pip install '{DISTRIBUTION}[{extra}]'"
