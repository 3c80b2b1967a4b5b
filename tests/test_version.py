"""``agents_core.__version__`` is pyproject.toml's version, read on first access (the one place it is written)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import agents_core
from agents_core.support import version as _version

REPO = Path(__file__).resolve().parent.parent


def test_version_is_pyprojects() -> None:
    found = re.search(r'^version = "([^"]+)"', (REPO / "pyproject.toml").read_text(encoding="utf-8"), flags=re.M)
    assert found is not None
    assert agents_core.__version__ == found.group(1)
    assert "__version__" in agents_core.__all__


def test_reading_the_version_is_lazy() -> None:
    code = ("import sys, agents_core; before = 'importlib.metadata' in sys.modules; "
            "v = agents_core.__version__; print(before, v)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    before, version = out.stdout.split()
    assert before == "False"
    assert version == agents_core.__version__


def test_fallbacks(tmp_path: Path) -> None:
    other = tmp_path / "pyproject.toml"
    other.write_text('[project]\nname = "something-else"\nversion = "9.9"\n')
    # Another project's pyproject.toml is not ours: the installed metadata (or 0+unknown) answers.
    assert _version.package_version(other) != "9.9"
    ours = tmp_path / "ours.toml"
    ours.write_text('[build-system]\nrequires = []\n\n[project]\nname = "agents-core"\nversion = "1.2.3"\n\n'
                    '[tool.x]\nversion = "0"\n')
    assert _version.package_version(ours) == "1.2.3"
    assert _version.package_version(tmp_path / "missing.toml") in (agents_core.__version__, _version.UNKNOWN_VERSION)
