"""Built-in local models and the helpers that find their files.

``LocalLLM`` / ``LocalVLM`` need the ``local`` extra (llama-cpp-python); importing this package
does not import it until a model is created.
"""

from __future__ import annotations

from .local_llm import LocalLLM, LocalVLM
from .model_files import default_llm_path, resolve_model_file

__all__ = ["LocalLLM", "LocalVLM", "default_llm_path", "resolve_model_file"]
