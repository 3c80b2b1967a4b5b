"""Which device a local model runs on: ``device_local_model`` ("auto", "cuda" or "cpu") resolved.

The developer docs show ``device_local_model`` defaulting to ``"cuda"``; a recipe written that way
must use the GPU of a robot that has one, and still run on one that has none. So:

- ``"auto"`` (the default here): the GPU when the backend installed can use one, else the CPU;
- ``"cuda"``: the GPU when the backend can use one, else the CPU with a WARNING saying why and
  what to install (never silently);
- ``"cpu"``: the CPU.

What "can use a GPU" means per backend: llama.cpp built with GPU offload
(``llama_cpp.llama_supports_gpu_offload()``), onnxruntime with its ``CUDAExecutionProvider``,
sherpa-onnx built for CUDA (a ``+cuda`` version).
"""

from __future__ import annotations

import logging
from typing import Any, Literal

from ..errors import ConfigError

__all__ = ["DEVICES", "gpu_available", "resolve_device"]

#: The values ``device_local_model`` takes.
DEVICES = ("auto", "cuda", "cpu")

Backend = Literal["llama_cpp", "onnxruntime", "sherpa_onnx"]

_logger = logging.getLogger("agents_core.engines")

_INSTALL = {
    "llama_cpp": "a CUDA build of llama-cpp-python (CMAKE_ARGS=-DGGML_CUDA=on pip install llama-cpp-python)",
    "onnxruntime": "onnxruntime-gpu",
    "sherpa_onnx": "a CUDA build of sherpa-onnx (its +cuda wheels)",
}


def gpu_available(backend: Backend, module: Any) -> bool:
    """Whether ``module`` (the imported backend) can run a model on a GPU."""
    try:
        if backend == "llama_cpp":
            probe = getattr(module, "llama_supports_gpu_offload", None)
            return bool(probe()) if callable(probe) else False
        if backend == "onnxruntime":
            return "CUDAExecutionProvider" in module.get_available_providers()
        return "cuda" in str(getattr(module, "__version__", "")).lower()
    except Exception as exc:  # a broken build: the CPU is the safe answer
        _logger.debug("cannot tell whether %s can use a GPU: %s", backend, exc)
        return False


def resolve_device(requested: str, backend: Backend, module: Any, what: str) -> str:
    """``"cuda"`` or ``"cpu"`` for ``requested`` (see the module docstring); ``what`` names the model in logs."""
    if requested not in DEVICES:
        raise ConfigError(f"{what}: device must be one of {list(DEVICES)}, got {requested!r}")
    if requested == "cpu":
        return "cpu"
    if gpu_available(backend, module):
        if requested == "auto":
            _logger.info("%s: a GPU is usable through %s: running on cuda", what, backend)
        return "cuda"
    if requested == "cuda":
        _logger.warning("%s: device 'cuda' was asked, but this %s cannot use a GPU: RUNNING ON THE CPU (slower). "
                        "Install %s, or set device_local_model='cpu' to silence this", what, backend,
                        _INSTALL[backend])
    return "cpu"
