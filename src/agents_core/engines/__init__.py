"""The built-in local model engines, run in the component's own process, and their helpers.

``LocalLLM`` / ``LocalVLM`` (:mod:`.local_llm`) need the ``local`` extra (llama-cpp-python),
``LocalVisionModel`` (:mod:`.local_vision`) onnxruntime, ``LocalSTT`` / ``LocalTTS``
(:mod:`.local_stt`, :mod:`.local_tts`) sherpa-onnx (the same extra). :mod:`.model_files` finds
their files (a path, a hub id, the default cache); :mod:`.audio` holds the sample-rate, down-mix
and WAV helpers of the speech engines and components. Importing this package imports none of
them until a name is used (PEP 562), and creating a model is what imports its runtime.
``agents_core.utils`` re-exports the same names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade

if TYPE_CHECKING:
    from .audio import StreamResampler as StreamResampler
    from .audio import to_mono_float as to_mono_float
    from .local_llm import LocalLLM as LocalLLM
    from .local_llm import LocalVLM as LocalVLM
    from .local_stt import LocalSTT as LocalSTT
    from .local_tts import LocalTTS as LocalTTS
    from .local_vision import LocalVisionModel as LocalVisionModel
    from .model_files import default_llm_path as default_llm_path
    from .model_files import resolve_model_file as resolve_model_file
else:
    __getattr__, __dir__ = lazy_facade(__name__)
