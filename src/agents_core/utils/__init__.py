"""Built-in local models and the helpers that find their files (a façade: the code lives elsewhere).

The engines are in :mod:`agents_core.engines`, the object tracker next to its one user,
:mod:`agents_core.components.vision.tracking`; the names stay importable from here.
``LocalLLM`` / ``LocalVLM`` need the ``local`` extra (llama-cpp-python), ``LocalVisionModel``
onnxruntime and ``LocalSTT`` / ``LocalTTS`` sherpa-onnx (the same extra); importing this package
imports neither it nor the local model module until a name is used (PEP 562), and creating a model
is what imports llama-cpp-python.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_facade

if TYPE_CHECKING:
    from ..components.vision.tracking import ObjectTracker, TrackedObject
    from ..engines.audio import StreamResampler, to_mono_float
    from ..engines.local_llm import LocalLLM, LocalVLM
    from ..engines.local_stt import LocalSTT
    from ..engines.local_tts import LocalTTS
    from ..engines.local_vision import LocalVisionModel
    from ..engines.model_files import default_llm_path, resolve_model_file
else:
    __getattr__, __dir__ = lazy_facade(__name__)

__all__ = ["LocalLLM", "LocalSTT", "LocalTTS", "LocalVLM", "LocalVisionModel", "ObjectTracker", "StreamResampler",
           "TrackedObject", "default_llm_path", "resolve_model_file", "to_mono_float"]
