"""Topics: named, typed channels between components, with their QoS.

``Topic(name, msg_type)`` takes a :class:`~agents_core.supported_types.SupportedType` or its
registered name. Names are checked at construction against the rules every transport can
carry (ROS 2 topic names and Zenoh key expressions both accept them), so a bad name fails in
the recipe, not at launch on one middleware only.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

from attrs import define, field

from . import base_validators
from .errors import ConfigError, TopicNameError, TypeValidationError
from .support.checked_attrs import CheckedFieldsMeta
from .types.base import SupportedType, get_type

if TYPE_CHECKING:
    from .conditions import FieldRef

__all__ = ["FixedInput", "QoSConfig", "Topic", "validate_topic_name"]

# Tokens of letters, digits and underscores, not starting with a digit, joined by single
# slashes, optionally absolute. This is the intersection of the ROS 2 topic name rules and
# what a Zenoh key expression chunk may contain without wildcards (*, $*, **) or specials.
_NAME_RE = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
_MAX_NAME_LENGTH = 255


def validate_topic_name(name: Any, what: str = "topic") -> str:
    """Return ``name`` if every transport can carry it, else raise :class:`TopicNameError`."""
    if not isinstance(name, str) or not name:
        raise TopicNameError(f"{what} name must be a non-empty str, got {name!r}")
    if len(name) > _MAX_NAME_LENGTH:
        raise TopicNameError(f"{what} name {name[:40]!r}... is longer than {_MAX_NAME_LENGTH} characters")
    if not _NAME_RE.match(name):
        raise TopicNameError(
            f"invalid {what} name {name!r}: use letters, digits and '_' in '/'-separated tokens that do "
            "not start with a digit (no spaces, '-', '.', wildcards, or empty/trailing '/')" + _name_fix(name)
        )
    return name


def _name_fix(name: str) -> str:
    """Why, and the name to use instead, when one is near (``my-talker`` -> ``my_talker``)."""
    fixed = re.sub(r"[^A-Za-z0-9_/]", "_", name.strip()).strip("/")
    fixed = re.sub(r"/+", "/", fixed)
    fixed = "/".join(f"_{part}" if part[:1].isdigit() else part for part in fixed.split("/"))
    why = (": ROS 2 names (nodes, topics, services) allow no '-' or '.', and every transport must carry the "
           "same name" if any(c in name for c in "-.") else "")
    return f"{why}; use {fixed!r}" if fixed and _NAME_RE.match(fixed) else why



@define(kw_only=True, frozen=True)
class QoSConfig(metaclass=CheckedFieldsMeta):
    """Quality of service of a topic.

    - ``reliability``: ``"reliable"`` (retransmit / block) or ``"best_effort"`` (may drop).
    - ``history`` / ``depth``: ``"keep_last"`` keeps the newest ``depth`` values in each
      subscriber's queue (older ones are dropped and counted); ``"keep_all"`` is bounded by
      ``depth`` too on the memory transport (no transport queue is truly unbounded).
    - ``durability``: ``"volatile"`` (only values published after subscribing) or
      ``"transient_local"`` (a late subscriber first receives the last ``depth`` values).
    """

    reliability: Literal["reliable", "best_effort"] = field(
        default="reliable", validator=base_validators.in_(("reliable", "best_effort"))
    )
    history: Literal["keep_last", "keep_all"] = field(
        default="keep_last", validator=base_validators.in_(("keep_last", "keep_all"))
    )
    depth: int = field(default=10)
    durability: Literal["volatile", "transient_local"] = field(
        default="volatile", validator=base_validators.in_(("volatile", "transient_local"))
    )

    @depth.validator
    def _check_depth(self, _: Any, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 100_000:
            raise ConfigError(f"QoSConfig.depth must be an int in [1, 100000], got {value!r}")


def _resolve_type(value: Any) -> type[SupportedType]:
    return get_type(value)


@define(kw_only=False, frozen=True)
class Topic:
    """A named, typed channel.

    :param name: topic name (see :func:`validate_topic_name`).
    :param msg_type: a SupportedType subclass or its registered name (e.g. ``"String"``).
    :param qos_profile: the topic's :class:`QoSConfig` (default: reliable, keep last 10).
    """

    name: str = field(validator=lambda _s, _a, v: validate_topic_name(v))
    msg_type: type[SupportedType] = field(converter=_resolve_type)
    qos_profile: QoSConfig = field(factory=QoSConfig, kw_only=True)

    @qos_profile.validator
    def _check_qos(self, _: Any, value: Any) -> None:
        if not isinstance(value, QoSConfig):
            raise ConfigError(f"topic {self.name!r}: qos_profile must be a QoSConfig, got {type(value).__name__}")

    @property
    def type_name(self) -> str:
        """The registered name of :attr:`msg_type`."""
        return self.msg_type.type_name()

    @property
    def msg(self) -> FieldRef:
        """A reference to this topic's message for event conditions, e.g. ``topic.msg.data > 5``."""
        from .conditions import FieldRef  # noqa: PLC0415  # conditions imports topics: break the cycle

        return FieldRef(self, ())

    def validator(self) -> Callable[[Any], Any]:
        """``msg_type.validate`` whose TypeValidationError names this topic (what publishers run on each value):
        ``topic 'count' (Int32): Int32 expects int, got str``."""
        validate = self.msg_type.validate
        where = f"topic {self.name!r} ({self.type_name})"

        def checked(value: Any) -> Any:
            try:
                return validate(value)
            except TypeValidationError as exc:
                raise TypeValidationError(f"{where}: {exc}") from exc

        return checked

    def __repr__(self) -> str:
        return f"Topic(name={self.name!r}, msg_type={self.type_name})"


@define(kw_only=False, frozen=True)
class FixedInput(Topic):
    """An input whose value never changes (e.g. a fixed prompt); it needs no publisher.

    ``fixed`` is validated against ``msg_type`` at construction.
    """

    fixed: Any = field(default=None)

    def __attrs_post_init__(self) -> None:
        try:
            value = self.msg_type.validate(self.fixed)
        except TypeValidationError as exc:
            raise TypeValidationError(f"FixedInput {self.name!r}: {exc}") from exc
        object.__setattr__(self, "fixed", value)

    def __repr__(self) -> str:
        return f"FixedInput(name={self.name!r}, msg_type={self.type_name}, fixed={self.fixed!r})"
