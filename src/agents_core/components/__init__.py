"""Components: the processing units of a recipe."""

from __future__ import annotations

from .component_base import Component, ComponentPublisher
from .llm import LLM
from .mllm import MLLM, VLM
from .model_component import ModelComponent
from .run_type import ComponentRunType
from .semantic_router import Route, SemanticRouter

__all__ = [
    "LLM",
    "MLLM",
    "VLM",
    "Component",
    "ComponentPublisher",
    "ComponentRunType",
    "ModelComponent",
    "Route",
    "SemanticRouter",
]
