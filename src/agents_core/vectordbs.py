"""Vector database descriptions, the ``DB`` counterpart of :class:`~agents_core.models.Model`."""

from __future__ import annotations

from typing import Any

from attrs import define, field

from .config import BaseAttrs
from .errors import ConfigError

__all__ = ["DB", "db_types"]

_db_types: dict[str, type[DB]] = {}


def db_types() -> dict[str, type[DB]]:
    """Every DB class defined so far, by class name."""
    return dict(_db_types)


def _non_empty_str(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a non-empty str, got {value!r}")


@define(kw_only=True)
class DB(BaseAttrs):
    """Base of vector database descriptions.

    :param name: an identifier chosen by the user.
    :param db_location: where the database keeps its data (a path or a server-side location).
    """

    name: str = field(validator=_non_empty_str)
    db_location: str = field(default="./data")

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _db_types[cls.__name__] = cls

    def _get_init_params(self) -> dict[str, Any]:
        """The parameters the database server needs to open this database."""
        return {"db_location": self.db_location}


_db_types["DB"] = DB
