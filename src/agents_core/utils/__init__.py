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

from ..support.lazy import lazy_facade

if TYPE_CHECKING:
    from ..components.vision.tracking import ObjectTracker as ObjectTracker
    from ..components.vision.tracking import TrackedObject as TrackedObject
    from ..engines.audio import StreamResampler as StreamResampler
    from ..engines.audio import to_mono_float as to_mono_float
    from ..engines.local_llm import LocalLLM as LocalLLM
    from ..engines.local_llm import LocalVLM as LocalVLM
    from ..engines.local_stt import LocalSTT as LocalSTT
    from ..engines.local_tts import LocalTTS as LocalTTS
    from ..engines.local_vision import LocalVisionModel as LocalVisionModel
    from ..engines.model_files import default_llm_path as default_llm_path
    from ..engines.model_files import resolve_model_file as resolve_model_file
else:
    __getattr__, __dir__ = lazy_facade(__name__)
