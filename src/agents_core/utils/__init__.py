"""Built-in local models and the helpers that find their files.

``LocalLLM`` / ``LocalVLM`` need the ``local`` extra (llama-cpp-python), ``LocalVisionModel``
onnxruntime and ``LocalSTT`` / ``LocalTTS`` sherpa-onnx (the same extra); importing this package
imports neither it nor the local model module until a name is used (PEP 562), and creating a model
is what imports llama-cpp-python.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

#: module -> the names re-exported from it, imported on first access.
_EXPORTS: dict[str, tuple[str, ...]] = {
    ".audio": ("StreamResampler", "to_mono_float"),
    ".local_llm": ("LocalLLM", "LocalVLM"),
    ".local_stt": ("LocalSTT",),
    ".local_tts": ("LocalTTS",),
    ".local_vision": ("LocalVisionModel",),
    ".model_files": ("default_llm_path", "resolve_model_file"),
    ".tracking": ("ObjectTracker", "TrackedObject"),
}

if TYPE_CHECKING:
    from .audio import StreamResampler, to_mono_float
    from .local_llm import LocalLLM, LocalVLM
    from .local_stt import LocalSTT
    from .local_tts import LocalTTS
    from .local_vision import LocalVisionModel
    from .model_files import default_llm_path, resolve_model_file
    from .tracking import ObjectTracker, TrackedObject
else:
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = ["LocalLLM", "LocalSTT", "LocalTTS", "LocalVLM", "LocalVisionModel", "ObjectTracker", "StreamResampler",
           "TrackedObject", "default_llm_path", "resolve_model_file", "to_mono_float"]
