"""Components: the processing units of a recipe.

Each name is imported from its module on first use (PEP 562): ``from agents_core.components import
Component`` loads the component runtime only, not the model components and their clients.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_facade

if TYPE_CHECKING:
    from ..runtime.run_type import ComponentRunType
    from .component_base import Component
    from .cortex.component import Cortex
    from .llm import LLM
    from .map_encoding import MapEncoding, MapLayer
    from .memory import MemLayer, Memory
    from .mllm import MLLM, VLM
    from .model_component import ModelComponent
    from .publisher import ComponentPublisher
    from .semantic_router import Route, SemanticRouter
    from .speech_to_text import SpeechToText
    from .text_to_speech import TextToSpeech
    from .video_maker import VideoMessageMaker
    from .vision.component import Vision
    from .vla.component import VLA
else:
    __getattr__, __dir__ = lazy_facade(__name__)

__all__ = [
    "LLM",
    "MLLM",
    "VLA",
    "VLM",
    "Component",
    "ComponentPublisher",
    "ComponentRunType",
    "Cortex",
    "MapEncoding",
    "MapLayer",
    "MemLayer",
    "Memory",
    "ModelComponent",
    "Route",
    "SemanticRouter",
    "SpeechToText",
    "TextToSpeech",
    "VideoMessageMaker",
    "Vision",
]
