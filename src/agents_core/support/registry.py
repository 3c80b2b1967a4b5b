"""One registry rule for every name-keyed table of the framework.

Message types, Zenoh codecs, ROS 2 conversions, model classes, vector database classes and
clients are each looked up by name. :class:`Registry` is the one implementation they share, so
they all behave alike:

- **thread-safe**: every read and write holds the registry's lock;
- **one error type per failure**: a name that is not registered raises :class:`NotRegisteredError`
  (a :class:`~agents_core.errors.UnknownTypeError`, so a ``ConfigError`` and a ``LookupError``),
  with close matches ("did you mean ...?") and the registry's own hint on how to register; a name
  taken by a different entry raises :class:`DuplicateNameError` (a ``ConfigError``). A registry may
  name a subclass of either to raise instead (the Zenoh codecs raise one that is also a
  ``CodecError``), never an unrelated type;
- **one subclass rule**: :meth:`Registry.for_class` walks ``cls.__mro__`` and returns the entry of
  the nearest class that has one, skipping the classes that ``inherits(cls, base)`` refuses
  (message types refuse a base whose value class differs: its wire form would not fit);
- **re-registration**: registering the same entry again is a no-op; a class re-created under the
  same module and qualified name (attrs does this for slotted classes) replaces the old one;
  ``replace=True`` overrides deliberately.
"""

from __future__ import annotations

import difflib
import threading
from collections.abc import Callable, Iterator
from typing import Any, Generic, TypeVar

from ..errors import ConfigError, UnknownTypeError

__all__ = ["DuplicateNameError", "NotRegisteredError", "Registry"]

T = TypeVar("T")


class NotRegisteredError(UnknownTypeError):
    """A name (or a class and all its bases) has no entry in a registry."""


class DuplicateNameError(ConfigError):
    """A name is already registered with a different entry."""


def _same_definition(a: Any, b: Any) -> bool:
    """True when ``b`` is ``a`` re-created (same module and qualified name), as attrs does for slotted classes."""
    return (isinstance(a, type) and isinstance(b, type) and a.__module__ == b.__module__
            and a.__qualname__ == b.__qualname__)


class Registry(Generic[T]):
    """A thread-safe name -> entry table with close-match errors and one MRO fallback rule.

    :param kind: what the entries are, for messages (``"message type"``, ``"Zenoh codec"``).
    :param hint: how to register a missing entry; ``{name}`` is replaced by the name looked up.
    :param missing_error: raised for a missing name (a :class:`NotRegisteredError` subclass).
    :param duplicate_error: raised for a taken name (a :class:`DuplicateNameError` subclass).
    :param class_name: the registry name of a class, for :meth:`for_class` (default ``__name__``).
    :param missing_text: the start of the missing-name message; ``{kind}`` and ``{name}`` are filled in.
    """

    def __init__(self, kind: str, *, hint: str = "", missing_error: type[NotRegisteredError] = NotRegisteredError,
                 duplicate_error: type[DuplicateNameError] = DuplicateNameError,
                 class_name: Callable[[type], str] | None = None,
                 missing_text: str = "unknown {kind} {name}") -> None:
        self.kind = kind
        self.missing_text = missing_text
        self.hint = hint
        self._missing = missing_error
        self._duplicate = duplicate_error
        self._class_name: Callable[[type], str] = class_name or (lambda cls: cls.__name__)
        self._entries: dict[str, T] = {}
        self._lock = threading.RLock()

    # -- writing ------------------------------------------------------------------------------

    def register(self, name: str, entry: T, *, replace: bool = False) -> T:
        """Register ``entry`` under ``name``; returns it (so it can decorate a class)."""
        if not isinstance(name, str) or not name:
            raise ConfigError(f"a {self.kind} name must be a non-empty str, got {name!r}")
        with self._lock:
            existing = self._entries.get(name)
            if (existing is not None and existing is not entry and not replace
                    and not _same_definition(existing, entry)):
                where = getattr(existing, "__module__", None)
                by = f" by {where}" if isinstance(where, str) else ""
                raise self._duplicate(f"{self.kind} name {name!r} is already registered{by}; pass another name "
                                      "(or replace=True to override it on purpose)")
            self._entries[name] = entry
        return entry

    def unregister(self, name: str) -> T | None:
        """Remove ``name`` (tests and plugins undoing their registrations); returns what was there."""
        with self._lock:
            return self._entries.pop(name, None)

    # -- reading ------------------------------------------------------------------------------

    def find(self, name: str) -> T | None:
        """The entry for ``name``, or None."""
        with self._lock:
            return self._entries.get(name)

    def get(self, name: str) -> T:
        """The entry for ``name``; :class:`NotRegisteredError` with close matches when there is none."""
        found = self.find(name)
        if found is None:
            raise self.missing(name)
        return found

    def for_class(self, cls: type, inherits: Callable[[type, type], bool] | None = None) -> T:
        """The entry of ``cls``, else of its nearest base (in MRO order) that ``inherits(cls, base)`` accepts."""
        found = self.find_for_class(cls, inherits)
        if found is None:
            raise self.missing(self._class_name(cls))
        return found

    def find_for_class(self, cls: type, inherits: Callable[[type, type], bool] | None = None) -> T | None:
        """As :meth:`for_class`, None instead of the error."""
        with self._lock:
            for base in cls.__mro__:
                if base is not cls and inherits is not None and not inherits(cls, base):
                    continue
                try:
                    name = self._class_name(base)
                except (AttributeError, TypeError):  # a mixin or ``object``: not a registrable class
                    continue
                entry = self._entries.get(name)
                if entry is not None:
                    return entry
        return None

    def missing(self, name: str) -> NotRegisteredError:
        """The error for a missing ``name``: close matches first, then how to register it."""
        with self._lock:
            names = list(self._entries)
        hints: list[str] = []
        if isinstance(name, str):
            lowered = [n for n in names if n.lower() == name.lower()]
            hints = list(dict.fromkeys(lowered + difflib.get_close_matches(name, names, n=3, cutoff=0.5)))
        text = self.missing_text.format(kind=self.kind, name=repr(name))
        if hints:
            text += f"; did you mean {', '.join(repr(h) for h in hints)}?"
        if self.hint:
            text += f" ({self.hint.replace('{name}', repr(name))})"
        return self._missing(text)

    def snapshot(self) -> dict[str, T]:
        """A copy of the table: name -> entry."""
        with self._lock:
            return dict(self._entries)

    def __contains__(self, name: object) -> bool:
        with self._lock:
            return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.snapshot())

    def __len__(self) -> int:
        with self._lock:
            return len(self._entries)
