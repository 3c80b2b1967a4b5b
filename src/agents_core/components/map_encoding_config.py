"""``MapConfig``: the settings of ``MapEncoding`` (:mod:`agents_core.components.map_encoding`), beside it.

Public as ``agents_core.config.MapConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from typing import Any

from attrs import define, field

from .. import base_validators
from ..config import AT_CONFIGURE, BaseComponentConfig

__all__ = ["MapConfig"]


@define(kw_only=True)
class MapConfig(BaseComponentConfig):
    """Settings of the :class:`~agents_core.components.map_encoding.MapEncoding` component.

    :param map_name: the vector database collection the map is written to.
    :param distance_func: the collection's distance, ``"l2"``, ``"cosine"`` or ``"ip"`` (for a new one).
    :param position_timeout: a layer value is only placed on the map when the robot's position arrived at
        most this many seconds before it; older (or no) position: the value is dropped and counted.
    :param map_wait_timeout: how long (s) configure waits for the first grid map (default 0: do not wait,
        as upstream, which reads the map at each step).
    :param require_map: without a map after that wait, configure fails (True) or the component starts
        and drops values (counted as ``no_map``) until a map arrives (False, the default).
    :param buffer_size: the most values kept while the database cannot be written to; when it is full
        the oldest value is dropped (counted).
    """

    map_name: str = field(default="map", validator=base_validators.non_empty_str, metadata=AT_CONFIGURE)
    distance_func: str = field(default="cosine", validator=base_validators.in_(["l2", "cosine", "ip"]),
                               metadata=AT_CONFIGURE)
    position_timeout: float = field(default=2.0, validator=base_validators.gt(0.0))
    map_wait_timeout: float = field(default=0.0, validator=base_validators.in_range(0.0, 3600.0))
    require_map: bool = field(default=False)
    buffer_size: int = field(default=1000, validator=base_validators.in_range(1, 10_000_000))

    def _get_inference_params(self) -> dict[str, Any]:
        """None: this component calls no model (every config class has the hook, architecture.md)."""
        return {}

