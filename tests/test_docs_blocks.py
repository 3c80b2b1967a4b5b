"""Every ``python`` block of README.md and docs/ either runs or is marked as a fragment (docs/writing-docs.md).

A block runs alone, in a fresh interpreter started in an empty directory, on the memory transport,
with a time limit, as an imported module (a ``__main__`` part does not run); the ``test_*``
functions it defines are then called. ``<!-- continues -->`` on the line before the fence runs it
after the page's previous block that runs, in the same process; ``<!-- fragment -->`` only compiles it.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PAGES = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
FRAGMENT, CONTINUES = "<!-- fragment -->", "<!-- continues -->"
#: Seconds one block (with the blocks it continues) may take.
BLOCK_TIMEOUT = 90.0
#: Optional packages: a block that imports one is skipped, naming it, where it is not installed.
OPTIONAL_MODULES = ("zenoh", "rclpy", "agents_interfaces", "emem", "llama_cpp", "sherpa_onnx", "onnxruntime",
                    "gymnasium")

_FENCE_OPEN = re.compile(r"^(?P<indent>[ \t]*)```(?P<info>[^`\n]*)$")

#: Run in the child: the file of blocks as a module, then the named test functions of the last block.
_RUNNER = """
import runpy, sys
namespace = runpy.run_path(sys.argv[1], run_name="docs_block")
for name in sys.argv[2:]:
    namespace[name]()
"""


@dataclass(frozen=True)
class Block:
    """One fenced ``python`` block: where it is, its code (dedented) and its marker."""

    page: Path
    line: int  # of the opening fence, 1-based
    code: str
    marker: str | None  # FRAGMENT, CONTINUES or None

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def _fences(page: Path) -> list[tuple[int, str, str, list[str]]]:
    """Every fenced block of ``page``: (line of the opening fence, its info string, the line before, body lines)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found, index = [], 0
    while index < len(lines):
        opening = _FENCE_OPEN.match(lines[index])
        if not opening:
            index += 1
            continue
        indent, end = opening.group("indent"), index + 1
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        before = lines[index - 1].strip() if index else ""
        body = [text[len(indent):] if text.startswith(indent) else text for text in lines[index + 1:end]]
        found.append((index + 1, opening.group("info").strip(), before, body))
        index = end + 1
    return found


def python_blocks() -> list[Block]:
    """The ``python`` blocks of README.md and docs/, in page order."""
    blocks = []
    for page in PAGES:
        for line, info, before, body in _fences(page):
            if info == "python":
                marker = before if before in (FRAGMENT, CONTINUES) else None
                blocks.append(Block(page, line, textwrap.dedent("\n".join(body)) + "\n", marker))
    return blocks


def _chain(block: Block, blocks: list[Block]) -> list[Block]:
    """``block`` preceded by the blocks it continues: each ``<!-- continues -->`` reaches back to the
    page's previous block that runs (fragments are skipped)."""
    runs_here = [b for b in blocks if b.page == block.page and b.marker != FRAGMENT]
    chain = [block]
    while chain[0].marker == CONTINUES:
        position = runs_here.index(chain[0])
        assert position > 0, f"{chain[0].where}: {CONTINUES} with no block that runs before it on the page"
        chain.insert(0, runs_here[position - 1])
    return chain


ALL = python_blocks()
RUN = [b for b in ALL if b.marker != FRAGMENT]
FRAGMENTS = [b for b in ALL if b.marker == FRAGMENT]


def test_the_docs_have_blocks_of_both_kinds() -> None:
    """The scan finds the README's and docs' blocks (a parser that found none would pass everything)."""
    assert len(RUN) >= 10 and len(FRAGMENTS) >= 5, (len(RUN), len(FRAGMENTS))
    assert {b.page.name for b in ALL} >= {"README.md", "porting.md", "zenoh-wire-format.md"}


def _tutorial_file(page: Path, info: str) -> bool:
    """A tutorial page's file (```python title="name.py"): tests/newcomer writes and runs it, with its commands."""
    in_tutorial = page.is_relative_to(REPO / "docs" / "tutorial")
    return in_tutorial and re.fullmatch(r'python title="[\w.-]+\.py"', info) is not None


def test_no_python_block_escapes_the_check() -> None:
    """Python fenced another way (``py``, ``python3``, ``pycon``) would not be checked: spell it ``python``."""
    odd = [f"{page.relative_to(REPO)}:{line} ```{info}" for page in PAGES for line, info, _, _ in _fences(page)
           if (info.split(" ")[0] in ("py", "python3", "pycon", "Python") or (info.startswith("python") and
                                                                               info != "python"))
           and not _tutorial_file(page, info)]
    assert not odd, f"python blocks with another info string: {odd}"


def test_every_marker_stands_before_a_python_block() -> None:
    """A marker that no python fence follows (a typo, a moved block) would silently mark nothing."""
    stray = []
    for page in PAGES:
        lines = page.read_text(encoding="utf-8").splitlines()
        for number, text in enumerate(lines, start=1):
            if text.strip() in (FRAGMENT, CONTINUES):
                after = lines[number] if number < len(lines) else ""
                if after.strip() != "```python":
                    stray.append(f"{page.relative_to(REPO)}:{number}")
    assert not stray, f"markers not on the line right before a ```python fence: {stray}"


def test_the_rule_is_documented() -> None:
    rule = (REPO / "docs" / "writing-docs.md").read_text(encoding="utf-8")
    assert FRAGMENT in rule and CONTINUES in rule and "tests/test_docs_blocks.py" in rule


@pytest.mark.parametrize("block", FRAGMENTS, ids=[b.where for b in FRAGMENTS])
def test_fragment_is_valid_python(block: Block) -> None:
    compile(block.code, block.where, "exec")


@pytest.mark.parametrize("block", RUN, ids=[b.where for b in RUN])
def test_block_runs(block: Block, tmp_path: Path) -> None:
    chain = _chain(block, ALL)
    script = tmp_path / "docs_block.py"
    script.write_text("".join(b.code for b in chain), encoding="utf-8")
    tests = [node.name for node in ast.parse(block.code).body
             if isinstance(node, ast.FunctionDef) and node.name.startswith("test_")]
    env = dict(os.environ)
    env.update(AGENTS_TRANSPORT="memory", AGENTS_QUIET="1", HF_HUB_OFFLINE="1",
               PYTHONPATH=os.pathsep.join([str(REPO / "src"), *filter(None, [env.get("PYTHONPATH")])]))
    work = tmp_path / "cwd"
    work.mkdir()
    done = subprocess.run([sys.executable, "-c", _RUNNER, str(script), *tests], cwd=work, env=env,
                          capture_output=True, text=True, timeout=BLOCK_TIMEOUT, check=False)
    if done.returncode != 0:
        missing = re.search(r"ModuleNotFoundError: No module named '([\w.]+)'", done.stderr)
        if missing and missing.group(1).split(".")[0] in OPTIONAL_MODULES:
            pytest.skip(f"{block.where} needs {missing.group(1)}, which is not installed")
    where = " after ".join(b.where for b in reversed(chain))
    assert done.returncode == 0, f"{where} failed ({done.returncode}):\n{done.stdout[-2000:]}\n{done.stderr[-4000:]}"
