"""``SemanticRouterConfig``: the settings of ``SemanticRouter`` (:mod:`.semantic_router`), beside it.

Public as ``agents_core.config.SemanticRouterConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from attrs import define, field

from .. import base_validators
from ..config import AT_CONFIGURE, ModelComponentConfig

__all__ = ["SemanticRouterConfig"]


@define(kw_only=True)
class SemanticRouterConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.semantic_router.SemanticRouter`.

    :param router_name: names the collection of route samples in the vector database.
    :param distance_func: the database's distance, ``"l2"``, ``"cosine"`` or ``"ip"``.
    :param maximum_distance: in vector mode, a query farther than this from every route's samples
        goes to the default route.
    :param enable_local_model: in LLM mode, choose routes with the built-in local LLM.
    """

    router_name: str = field(default="semantic_router", validator=base_validators.non_empty_str, metadata=AT_CONFIGURE)
    distance_func: str = field(default="l2", validator=base_validators.in_(["l2", "cosine", "ip"]),
                               metadata=AT_CONFIGURE)
    maximum_distance: float = field(default=0.4, validator=base_validators.gt(0.0))

