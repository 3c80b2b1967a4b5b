"""Built-in local models and the helpers that find their files.

``LocalLLM`` / ``LocalVLM`` need the ``local`` extra (llama-cpp-python); importing this package
imports neither it nor the local model module until a name is used (PEP 562), and creating a model
is what imports llama-cpp-python.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

#: module -> the names re-exported from it, imported on first access.
_EXPORTS: dict[str, tuple[str, ...]] = {
    ".local_llm": ("LocalLLM", "LocalVLM"),
    ".model_files": ("default_llm_path", "resolve_model_file"),
}

if TYPE_CHECKING:
    from .local_llm import LocalLLM, LocalVLM
    from .model_files import default_llm_path, resolve_model_file
else:
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = ["LocalLLM", "LocalVLM", "default_llm_path", "resolve_model_file"]
