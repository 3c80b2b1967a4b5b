"""Built-in local models and the helpers that find their files.

``LocalLLM`` / ``LocalVLM`` need the ``local`` extra (llama-cpp-python), ``LocalVisionModel``
onnxruntime (the same extra); importing this package
imports neither it nor the local model module until a name is used (PEP 562), and creating a model
is what imports llama-cpp-python.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

#: module -> the names re-exported from it, imported on first access.
_EXPORTS: dict[str, tuple[str, ...]] = {
    ".local_llm": ("LocalLLM", "LocalVLM"),
    ".local_vision": ("LocalVisionModel",),
    ".model_files": ("default_llm_path", "resolve_model_file"),
    ".tracking": ("ObjectTracker", "TrackedObject"),
}

if TYPE_CHECKING:
    from .local_llm import LocalLLM, LocalVLM
    from .local_vision import LocalVisionModel
    from .model_files import default_llm_path, resolve_model_file
    from .tracking import ObjectTracker, TrackedObject
else:
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = ["LocalLLM", "LocalVLM", "LocalVisionModel", "ObjectTracker", "TrackedObject", "default_llm_path",
           "resolve_model_file"]
