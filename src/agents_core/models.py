"""Model descriptions: what a model client should load on its serving platform.

A model is attrs data (``@define(kw_only=True)``) holding a name, a checkpoint and the
platform-specific options; :meth:`Model._get_init_params` is the dict sent to the platform when
the client initializes. Model classes register themselves by class name, so a serialized
client can say which kind of model it serves.
"""

from __future__ import annotations

from typing import Any, ClassVar

from attrs import define, field

from . import base_validators
from .config import BaseAttrs
from .errors import ConfigError

__all__ = ["Model", "model_types"]

_model_types: dict[str, type[Model]] = {}


def model_types() -> dict[str, type[Model]]:
    """Every model class defined so far, by class name."""
    return dict(_model_types)


def _non_empty_str(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a non-empty str, got {value!r}")


@define(kw_only=True)
class Model(BaseAttrs):
    """Base of model descriptions.

    :param name: an identifier chosen by the user (logs, client keys).
    :param checkpoint: the model's identifier on the serving platform (Ollama tag, hub repo, ...).
    :param init_timeout: seconds the platform may take to load the model (None: its default).
    """

    #: Set by subclasses that only some components can use (informational).
    model_family: ClassVar[str] = "generic"

    name: str = field(validator=_non_empty_str)
    checkpoint: str = field(validator=_non_empty_str)
    init_timeout: int | None = field(default=None, validator=base_validators.gt(0))

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # attrs re-creates slotted classes; the last registration is the final class.
        _model_types[cls.__name__] = cls

    def _get_init_params(self) -> dict[str, Any]:
        """The parameters the serving platform needs to load this model."""
        return {"checkpoint": self.checkpoint}


_model_types["Model"] = Model
