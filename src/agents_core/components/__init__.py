"""Components: the processing units of a recipe."""

from __future__ import annotations

from .component_base import Component, ComponentPublisher
from .model_component import ModelComponent
from .run_type import ComponentRunType

__all__ = ["Component", "ComponentPublisher", "ComponentRunType", "ModelComponent"]
