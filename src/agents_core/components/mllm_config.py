"""``MLLMConfig``: the settings of ``MLLM`` (:mod:`agents_core.components.mllm`), beside it.

Public as ``agents_core.config.MLLMConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from attrs import define, field

from .. import base_validators
from ..config import AT_CONFIGURE
from .llm_config import LLMConfig

__all__ = ["MLLMConfig", "VLMConfig"]


@define(kw_only=True)
class MLLMConfig(LLMConfig):
    """Settings of the :class:`~agents_core.components.mllm.MLLM` (VLM) component.

    :param task: ``"general"`` (text answers), or a structured task whose answer is parsed into a
        typed output: ``"grounding"`` (boxes → Detections), ``"pointing"`` (points →
        PointsOfInterest), ``"affordance"`` (boxes of where to act → Detections), ``"trajectory"``
        (an ordered path of points → PointsOfInterest).
    :param local_mmproj_path: the local VLM's projector file, when it is not beside the model.
    """

    task: str = field(default="general", validator=base_validators.in_(
        ["general", "grounding", "pointing", "affordance", "trajectory"]))
    local_mmproj_path: str | None = field(default=None, validator=base_validators.optional_str, metadata=AT_CONFIGURE)


#: The upstream name of the same configuration.
VLMConfig = MLLMConfig

