"""The ``python`` blocks of the spec (../shared/spec/upstream-dev-docs.md), read from the file itself.

:func:`spec_blocks` numbers them 1.. in the order they appear; :func:`adapted` rewrites a block's
imports the one way the spec allows (``agents`` -> ``agents_core``; ``ros_sugar``'s modules -> their
homes here; ``automatika_embodied_agents`` -> ``agents_interfaces``, this project's interface
package). A test names the block it runs with :func:`covers`; ``test_spec_coverage.py`` checks that
every block is covered by some test, and that the first line each test expects is still the block's.
"""

from __future__ import annotations

import os
import re
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

REPO = Path(__file__).resolve().parents[2]
#: The spec: ``AGENTS_SPEC_FILE`` overrides where the shared folder is not beside the checkout.
SPEC = Path(os.environ.get("AGENTS_SPEC_FILE", REPO.parent / "shared" / "spec" / "upstream-dev-docs.md"))
if not SPEC.is_file() and "AGENTS_SPEC_FILE" not in os.environ:  # a worktree: the shared folder two levels up
    SPEC = REPO.parents[1] / "shared" / "spec" / "upstream-dev-docs.md"

#: The import rewrites: the spec's module -> this project's (docs/porting.md, "The one change").
RENAMES = [
    (re.compile(r"\bros_sugar\.supported_types\b"), "agents_core.supported_types"),
    (re.compile(r"\bros_sugar\.io\.callbacks\b"), "agents_core.callbacks"),
    (re.compile(r"\bautomatika_embodied_agents\.msg\b"), "agents_interfaces.msg"),
    (re.compile(r"\bfrom agents\b"), "from agents_core"),
    (re.compile(r"\bimport agents\b"), "import agents_core"),
]

F = TypeVar("F", bound=Callable[..., Any])

#: block number -> (the test's name, the block's first line as that test expects it).
COVERED: dict[int, tuple[str, str]] = {}


@dataclass(frozen=True)
class SpecBlock:
    """One ```python block of the spec: its number, the line of its fence, its code."""

    number: int
    line: int
    code: str

    @property
    def first_line(self) -> str:
        return next(line.strip() for line in self.code.splitlines() if line.strip())


def spec_text() -> str:
    """The spec's text, or a skip naming where it was looked for (it is not part of this repository)."""
    if not SPEC.is_file():
        import pytest  # noqa: PLC0415

        pytest.skip(f"the upstream developer docs are not at {SPEC} (set AGENTS_SPEC_FILE)")
    return SPEC.read_text(encoding="utf-8")


def spec_blocks() -> list[SpecBlock]:
    """Every ```python block of the spec, numbered from 1."""
    lines = spec_text().splitlines()
    found: list[SpecBlock] = []
    index = 0
    while index < len(lines):
        if lines[index].strip() == "```python":
            start = index
            body: list[str] = []
            index += 1
            while index < len(lines) and lines[index].strip() != "```":
                body.append(lines[index])
                index += 1
            found.append(SpecBlock(len(found) + 1, start + 1, textwrap.dedent("\n".join(body)) + "\n"))
        index += 1
    return found


def block(number: int) -> SpecBlock:
    """Block ``number`` of the spec."""
    return spec_blocks()[number - 1]


def adapted(number: int, *replacements: tuple[str, str]) -> str:
    """Block ``number`` with the import rewrites, then each ``(old, new)`` completion (each must match)."""
    code = block(number).code
    for pattern, new in RENAMES:
        code = pattern.sub(new, code)
    for old, new in replacements:
        if old not in code:
            raise AssertionError(f"spec block {number}: the completion expects {old!r} in it")
        code = code.replace(old, new)
    return code


def run_block(number: int, namespace: dict[str, Any] | None = None, *replacements: tuple[str, str]) -> dict[str, Any]:
    """Execute block ``number`` (adapted and completed) in ``namespace``; returns the namespace."""
    namespace = {"__name__": f"spec_block_{number}"} if namespace is None else namespace
    namespace.setdefault("__name__", f"spec_block_{number}")
    exec(compile(adapted(number, *replacements), f"{SPEC.name}:block{number}", "exec"), namespace)
    return namespace


def covers(*numbers_and_first_lines: tuple[int, str]) -> Callable[[F], F]:
    """Mark a test as running the given blocks, each with the first line it expects."""
    def mark(func: F) -> F:
        for number, first in numbers_and_first_lines:
            if number in COVERED:
                raise AssertionError(f"spec block {number} is covered twice ({COVERED[number][0]}, {func.__name__})")
            COVERED[number] = (func.__name__, first)
        return func

    return mark
