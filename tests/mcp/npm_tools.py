"""MCP programs from npm that no one here wrote (the Inspector, the reference "everything" server), installed
once into a cache folder (``AGENTS_TEST_NPM_CACHE``, default ``~/.cache/agents-core-tests/npm``).

A test that needs one skips, saying why, where npm or the registry is missing.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

INSPECTOR = ("@modelcontextprotocol/inspector@2", "mcp-inspector")
EVERYTHING = ("@modelcontextprotocol/server-everything", "mcp-server-everything")


def npm_binary(package: tuple[str, str]) -> Path:
    """The installed binary of ``package`` ((npm spec, binary name)); installs it first if needed."""
    spec, name = package
    npm = shutil.which("npm")
    if npm is None:
        pytest.skip(f"npm is not installed: this test needs {spec}")
    cache = Path(os.environ.get("AGENTS_TEST_NPM_CACHE", Path.home() / ".cache" / "agents-core-tests" / "npm"))
    binary = cache / "node_modules" / ".bin" / name
    if not binary.exists():
        cache.mkdir(parents=True, exist_ok=True)
        done = subprocess.run([npm, "install", "--silent", "--prefix", str(cache), spec], capture_output=True,
                              text=True, timeout=600, check=False)
        if done.returncode != 0 or not binary.exists():
            pytest.skip(f"npm could not install {spec}: {done.stderr.strip()[-300:]}")
    return binary
