"""``MemLayer``: one input stream of a :class:`~agents_core.components.memory.Memory`, and its text form.

A perception layer takes String, StreamingString (stored once its stream is done), Detections or
Trackings (their labels). An internal-state layer (``is_internal_state=True``: battery, temperature,
joint health) takes any type whose values have a text form (see :func:`text_form`).
"""

from __future__ import annotations

from typing import Any

import attrs
from attrs import define, field

from ...errors import ComponentError, ConfigError, WiringError
from ...messages import DetectionsMsg, TrackingsMsg
from ...supported_types import Detections, String, Trackings
from ...topics import Topic
from ..layer_points import convert_points, pre_defined_validator

__all__ = ["PERCEPTION_TYPES", "MemLayer", "text_form"]

#: What a perception layer may subscribe to (subclasses too: StreamingString is a String).
PERCEPTION_TYPES = (String, Detections, Trackings)


def _scalar_text(value: Any) -> str | None:
    if isinstance(value, bool | int | float | str):
        return str(value).strip()
    return None


def text_form(value: Any) -> str | None:
    """The text stored for ``value``, None when there is nothing to store.

    A str is itself; Detections / Trackings are their labels (``"cup, chair"``; none: nothing);
    a number or bool is written out; a message with a scalar ``data`` field is that field; any
    other attrs message is its scalar fields, ``name=value`` (an array of up to 8 numbers counts).
    """
    if isinstance(value, DetectionsMsg | TrackingsMsg):
        return ", ".join(value.labels) or None
    scalar = _scalar_text(value)
    if scalar is not None:
        return scalar or None
    data = getattr(value, "data", None)
    scalar = _scalar_text(data)
    if scalar is not None:
        return scalar or None
    if attrs.has(type(value)):
        parts = []
        for attribute in attrs.fields(type(value)):
            item = getattr(value, attribute.name)
            text = _scalar_text(item)
            if text is None and hasattr(item, "tolist") and getattr(item, "size", 9) <= 8:
                text = str([round(float(v), 4) for v in item.tolist()])
            if text:
                parts.append(f"{attribute.name}={text}")
        return ", ".join(parts) or None
    raise ComponentError(f"a {type(value).__name__} has no text form")


def _check_topic(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, Topic):
        raise ConfigError(f"MemLayer.subscribes_to must be a Topic, got {value!r}")


def _check_multiple(instance: Any, attribute: Any, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value <= 100:
        raise ConfigError(f"MemLayer.resolution_multiple must be a number in (0, 100], got {value!r}")


@define(frozen=True)
class Fix:
    """The robot's position (m, world frame) and when it arrived (``time.monotonic()``)."""

    x: float
    y: float
    z: float
    received: float


def _points(value: Any) -> list[tuple[Any, str]]:
    return convert_points("MemLayer", value)


@define(kw_only=True)
class MemLayer:
    """One layer of a :class:`~agents_core.components.memory.Memory`.

    :param subscribes_to: the topic whose values are remembered; the layer's name is the topic's name
        (the ``layer`` filter of the retrieval tools).
    :param temporal_change: store every new value with its time (things that change: detections);
        False: a value equal to the layer's last stored one, in the same cell, is not stored again
        (things that stay: a room's name).
    :param resolution_multiple: the layer's cell is ``MemoryConfig.cell_size`` times this (coarser or finer
        "same place" for the rule above).
    :param pre_defined: ``(position, text)`` points written once into a new database (e.g. room names).
    :param is_internal_state: the robot's own state (battery, temperature): stored as body state,
        answered by ``body_status`` rather than the perception tools; any type with a text form.
    :param template: a Jinja2 template making the stored text from ``text`` (e.g. ``"I saw {{ text }}"``).
    """

    subscribes_to: Topic = field(validator=_check_topic)
    temporal_change: bool = field(default=False)
    resolution_multiple: float = field(default=1, validator=_check_multiple)
    pre_defined: list[tuple[Any, str]] = field(factory=list, converter=_points,
                                               validator=pre_defined_validator("MemLayer"))
    is_internal_state: bool = field(default=False)
    template: str | None = field(default=None)
    _compiled: Any = field(default=None, init=False, repr=False, eq=False)

    def __attrs_post_init__(self) -> None:
        if not self.is_internal_state and not issubclass(self.subscribes_to.msg_type, PERCEPTION_TYPES):
            raise WiringError(f"MemLayer {self.name!r}: a perception layer takes String, StreamingString, "
                              f"Detections or Trackings, not {self.subscribes_to.type_name} (set "
                              "is_internal_state=True for the robot's own state)")
        if self.template is not None:
            import jinja2  # noqa: PLC0415  (only layers with a template need it)

            try:
                self._compiled = jinja2.Environment(undefined=jinja2.StrictUndefined,
                                                    autoescape=False).from_string(self.template)
            except jinja2.TemplateSyntaxError as exc:
                raise ConfigError(f"MemLayer {self.name!r}: template is not valid Jinja2: {exc}") from exc

    @property
    def name(self) -> str:
        """The layer's name: its topic's name."""
        return self.subscribes_to.name

    def text_of(self, value: Any) -> str | None:
        """The text stored for ``value`` (None: nothing to store)."""
        text = text_form(value)
        if text and self._compiled is not None:
            text = str(self._compiled.render(text=text)).strip()
        return text or None
