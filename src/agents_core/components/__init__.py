"""Components: the processing units of a recipe.

Each name is imported from its module on first use (PEP 562): ``from agents_core.components import
Component`` loads the component runtime only, not the model components and their clients.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade

if TYPE_CHECKING:
    from ..runtime.run_type import ComponentRunType as ComponentRunType
    from .component_base import Component as Component
    from .cortex.component import Cortex as Cortex
    from .llm import LLM as LLM
    from .map_encoding import MapEncoding as MapEncoding
    from .map_encoding import MapLayer as MapLayer
    from .memory import MemLayer as MemLayer
    from .memory import Memory as Memory
    from .mllm import MLLM as MLLM
    from .mllm import VLM as VLM
    from .model_component import ModelComponent as ModelComponent
    from .publisher import ComponentPublisher as ComponentPublisher
    from .semantic_router import Route as Route
    from .semantic_router import SemanticRouter as SemanticRouter
    from .speech_to_text import SpeechToText as SpeechToText
    from .text_to_speech import TextToSpeech as TextToSpeech
    from .video_maker import VideoMessageMaker as VideoMessageMaker
    from .vision.component import Vision as Vision
    from .vla.component import VLA as VLA
else:
    __getattr__, __dir__ = lazy_facade(__name__)
