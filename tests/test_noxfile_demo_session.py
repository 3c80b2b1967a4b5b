"""``nox -s demo``: its installed-check (a second run skips pip) and the demo's ``--help``."""

from __future__ import annotations

import functools
import importlib.util
import json
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parent.parent


@functools.cache
def _load_noxfile() -> ModuleType:
    """Loaded once: nox keeps one registry of sessions per process, and loading again re-registers them."""
    spec = importlib.util.spec_from_file_location("project_noxfile", REPO / "noxfile.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _noxfile() -> ModuleType:
    pytest.importorskip("nox")
    return _load_noxfile()


def _installed_agents_core() -> tuple[str, str]:
    """(url, version) of this environment's agents-core when it is an editable install, else skip."""
    try:
        dist = metadata.distribution("agents-core")
    except metadata.PackageNotFoundError:
        pytest.skip("agents-core is not installed in this environment")
    url = json.loads(dist.read_text("direct_url.json") or "{}")
    if not url.get("dir_info", {}).get("editable"):
        pytest.skip("agents-core is not an editable install here")
    return str(url["url"]).rstrip("/"), dist.version


def _check(tmp_path: Path, wanted: list[str], root: str, version: str) -> tuple[int, str]:
    script = tmp_path / "check.py"
    script.write_text(_noxfile()._SATISFIED_CHECK)
    data = tmp_path / "check.json"
    data.write_text(json.dumps([wanted, root, version]))
    done = subprocess.run([sys.executable, str(script), str(data)], capture_output=True, text=True, timeout=60,
                          check=False)
    return done.returncode, done.stdout.strip()


def test_satisfied_when_everything_is_there(tmp_path: Path) -> None:
    root, version = _installed_agents_core()
    code, out = _check(tmp_path, ["attrs>=1", "numpy", "tomli>=2; python_version < '3.0'"], root, version)
    assert (code, out) == (0, "satisfied")


def test_missing_or_too_old_or_another_checkout_is_not_satisfied(tmp_path: Path) -> None:
    root, version = _installed_agents_core()
    code, out = _check(tmp_path, ["surely-not-installed-pkg", "attrs>=999"], root, version)
    assert code == 1
    assert "surely-not-installed-pkg" in out and "attrs>=999 (have " in out
    code, out = _check(tmp_path, ["attrs"], "file:///somewhere/else", version)
    assert (code, out) == (1, "missing: agents-core (editable, this checkout)")
    code, out = _check(tmp_path, ["attrs"], root, "0.0.0.dev0")
    assert code == 1


def test_requirements_come_from_pyproject() -> None:
    wanted = _noxfile()._requirements("zenoh,local")
    assert any(r.startswith("eclipse-zenoh") for r in wanted)
    assert any(r.startswith("llama-cpp-python") for r in wanted)
    assert any(r.startswith("attrs") for r in wanted)


def test_demo_help_lists_the_vision_and_voice_demos() -> None:
    done = subprocess.run([sys.executable, "-m", "agents_core.demo", "--help"], capture_output=True, text=True,
                          timeout=60, check=True)
    assert "vision --model detector.onnx --images DIR" in done.stdout
    assert "voice --wav FILE" in done.stdout


def test_the_voice_demo_session_installs_its_default_vad() -> None:
    source = (REPO / "noxfile.py").read_text(encoding="utf-8")
    assert 'session.install("--no-deps", "silero-vad")' in source
