"""ROS 2 message types without rclpy: definitions, RIHS01 type hashes and CDR, from ``rosbags``.

This is the message-class provider of the ``rmw_zenoh`` transport. The framework's conversions
(:mod:`agents_ros2.conversions`, the one set the ``ros2`` transport uses) build and read message
objects by field name; here any object with the right field names (an rclpy message, a ``rosbags``
dataclass, a plain object) is written as CDR (XCDR1, little-endian) and CDR is read back as
``rosbags`` dataclasses, which the same conversions read.

Definitions come from ``rosbags``' ROS 2 Jazzy store, and for other packages (the framework's
``agents_interfaces``, a user's ``_ros_type`` package) from the ``share/<pkg>/msg|srv`` files of
the installed ROS packages (``AMENT_PREFIX_PATH``, else this Python's prefix). Type hashes are
computed from the definitions as rosidl computes them (REP 2016, ``RIHS01_<sha256>``); a service's
hash covers its request, response and event messages, as rosidl's does.
"""

from __future__ import annotations

import array
import os
import re
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

from agents_core.errors import TypeValidationError

__all__ = ["RosTypes", "ros_type_name", "ros_types"]

#: The generated types of an action ``pkg/action/<Name>``: ``<Name>`` followed by one of these (or nothing).
_ACTION_PART = re.compile(r"(.+?)(_SendGoal(?:_Request|_Response|_Event)?|_GetResult(?:_Request|_Response|_Event)?"
                          r"|_FeedbackMessage|_Goal|_Result|_Feedback)?")
_UUID = "unique_identifier_msgs/msg/UUID"
_TIME = "builtin_interfaces/msg/Time"

_DTYPES: dict[str, Any] = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
    "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
    "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64,
}

#: From this size on, a publisher's CDR buffer is reused (:meth:`RosTypes.serialize_into`).
REUSE_MIN_BYTES = 64 * 1024


def ros_type_name(cls: type[Any]) -> str:
    """``pkg/msg/Type`` of a message class: a rosbags dataclass' ``__msgtype__``, or an rclpy class' module."""
    name = getattr(cls, "__msgtype__", None)
    if isinstance(name, str):
        return name
    module = cls.__module__.split(".")
    if len(module) >= 2 and module[1] in ("msg", "srv", "action"):
        return f"{module[0]}/{module[1]}/{cls.__name__}"
    raise TypeValidationError(f"cannot tell the ROS type of class {cls.__module__}.{cls.__qualname__}")


def _share_dirs() -> list[Path]:
    roots = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    roots.append(sys.prefix)
    return [Path(r) / "share" for r in dict.fromkeys(roots)]


class RosTypes:
    """Definitions, hashes and CDR of ROS 2 types (one per process: :func:`ros_types`)."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415  # ~0.2 s: only when used

        self._store = get_typestore(Stores.ROS2_JAZZY)
        for typename in list(self._store.fielddefs):
            self._store.fielddefs[typename] = _char_as_uint8(self._store.fielddefs[typename])
        self._lock = threading.RLock()
        self._hashes: dict[str, str] = {}
        #: Type name -> whether it has no field that needs adapting (numeric arrays, bytes, chars).
        self._plain: dict[str, bool] = {}

    # -- definitions ------------------------------------------------------------------------

    def _find(self, pkg: str, kind: str, name: str) -> Path | None:
        for share in _share_dirs():
            path = share / pkg / kind / f"{name}.{kind}"
            if path.is_file():
                return path
        return None

    def ensure(self, typename: str) -> None:
        """Load ``pkg/msg/Type`` or ``pkg/srv/Type`` (and what it uses) if the store lacks it."""
        # ``types`` is filled after ``fielddefs`` when rosbags registers a type: a reader that finds it
        # there outside the lock sees the type complete.
        if typename in self._store.types:
            return
        with self._lock:
            if typename in self._store.types:
                return
            pkg, kind, name = typename.split("/")
            if kind == "srv":
                for suffix in ("_Request", "_Response", "_Event"):
                    name = name.removesuffix(suffix)
                self._ensure_service(pkg, name)
                return
            if kind == "action":
                match = _ACTION_PART.fullmatch(name)
                self._ensure_action(pkg, match.group(1) if match else name)
                return
            path = self._find(pkg, kind, name)
            if path is None:
                raise TypeValidationError(f"ROS type {typename} is unknown: no rosbags definition and no "
                                          f"share/{pkg}/{kind}/{name}.{kind} under {_share_dirs()}")
            self._register_text(path.read_text(), typename)

    def _register_text(self, text: str, typename: str) -> None:
        from rosbags.typesys import get_types_from_msg  # noqa: PLC0415

        pkg, _kind, name = typename.split("/")
        # rosbags resolves relative field types against the name's first part only as pkg/msg/...
        parsed = get_types_from_msg(text, f"{pkg}/msg/{name}")
        types = {typename if key == f"{pkg}/msg/{name}" else key: _char_as_uint8(value)
                 for key, value in parsed.items()}
        for _consts, fields in types.values():
            for _field, desc in fields:
                for ref in _references(desc):
                    if ref not in types:
                        self.ensure(ref)
        self._store.register(types)

    def _ensure_service(self, pkg: str, name: str) -> None:
        path = self._find(pkg, "srv", name)
        if path is None:
            raise TypeValidationError(f"ROS service type {pkg}/srv/{name} is unknown: no share/{pkg}/srv/{name}.srv")
        lines = path.read_text().splitlines()
        cut = next((i for i, line in enumerate(lines) if line.strip() == "---"), None)
        if cut is None:
            raise TypeValidationError(f"{path} has no '---' between request and response")
        base = f"{pkg}/srv/{name}"
        self._register_text("\n".join(lines[:cut]) + "\n", f"{base}_Request")
        self._register_text("\n".join(lines[cut + 1:]) + "\n", f"{base}_Response")
        self._register_service(base)

    def _ensure_action(self, pkg: str, name: str) -> None:
        """Register the types rosidl generates for ``share/<pkg>/action/<name>.action``."""
        path = self._find(pkg, "action", name)
        if path is None:
            raise TypeValidationError(f"ROS action type {pkg}/action/{name} is unknown: no "
                                      f"share/{pkg}/action/{name}.action under {_share_dirs()}")
        parts: list[list[str]] = [[]]
        for line in path.read_text().splitlines():
            if line.strip() == "---":
                parts.append([])
            else:
                parts[-1].append(line)
        if len(parts) != 3:
            raise TypeValidationError(f"{path} must have goal, result and feedback separated by two '---' lines")
        base = f"{pkg}/action/{name}"
        for part, lines in zip(("_Goal", "_Result", "_Feedback"), parts, strict=True):
            self._register_text("\n".join(lines) + "\n", base + part)
        self.ensure(_UUID)
        self.ensure(_TIME)

        def ref(typename: str) -> tuple[Any, str]:
            return (Nodetype.NAME, typename)

        made: dict[str, Any] = {
            f"{base}_SendGoal_Request": ([], [("goal_id", ref(_UUID)), ("goal", ref(f"{base}_Goal"))]),
            f"{base}_SendGoal_Response": ([], [("accepted", (Nodetype.BASE, ("bool", 0))), ("stamp", ref(_TIME))]),
            f"{base}_GetResult_Request": ([], [("goal_id", ref(_UUID))]),
            f"{base}_GetResult_Response": ([], [("status", (Nodetype.BASE, ("int8", 0))),
                                                ("result", ref(f"{base}_Result"))]),
            f"{base}_FeedbackMessage": ([], [("goal_id", ref(_UUID)), ("feedback", ref(f"{base}_Feedback"))]),
        }
        self._store.register(made)
        self._register_service(f"{base}_SendGoal")
        self._register_service(f"{base}_GetResult")
        whole = [("goal", ref(f"{base}_Goal")), ("result", ref(f"{base}_Result")),
                 ("feedback", ref(f"{base}_Feedback")), ("send_goal_service", ref(f"{base}_SendGoal")),
                 ("get_result_service", ref(f"{base}_GetResult")),
                 ("feedback_message", ref(f"{base}_FeedbackMessage"))]
        self._store.register({base: ([], whole)})  # type: ignore[dict-item]

    def _register_service(self, base: str) -> None:
        """The event message and the service itself (its hash covers request, response and event)."""
        event = [("info", (Nodetype.NAME, "service_msgs/msg/ServiceEventInfo")),
                 ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{base}_Request"), 1))),
                 ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{base}_Response"), 1)))]
        self._store.register({f"{base}_Event": ([], event)})  # type: ignore[dict-item]
        whole = [("request_message", (Nodetype.NAME, f"{base}_Request")),
                 ("response_message", (Nodetype.NAME, f"{base}_Response")),
                 ("event_message", (Nodetype.NAME, f"{base}_Event"))]
        self._store.register({base: ([], whole)})  # type: ignore[dict-item]

    def type_hash(self, typename: str) -> str:
        """The type's REP-2016 hash, ``RIHS01_<hex>``, computed from its definition."""
        found = self._hashes.get(typename)
        if found is None:
            self.ensure(typename)
            with self._lock:
                found = self._hashes[typename] = self._store.hash_rihs01(typename)
        return found

    def message_class(self, typename: str) -> type[Any]:
        """The rosbags dataclass of ``typename`` (all fields are required keywords)."""
        self.ensure(typename)
        cls: type[Any] = self._store.types[typename]
        return cls

    # -- CDR ----------------------------------------------------------------------------------

    def serialize(self, message: Any, typename: str) -> bytes:
        """``message`` (any object with the type's field names) as CDR bytes."""
        self.ensure(typename)
        data = self._store.serialize_cdr(self.adapt(message, typename), typename)
        return data.tobytes()  # one copy of the buffer (bytes(array) would walk it item by item)

    def serialize_into(self, message: Any, typename: str, buffer: bytearray | None) -> bytearray:
        """``message`` as CDR (little-endian) written into ``buffer`` when it has the size and at least
        :data:`REUSE_MIN_BYTES` (zeroed first, so the padding is as in a fresh one), else into a new bytearray;
        returns the one written.

        A publisher keeps its buffer from one message to the next: a large message (an image) then costs no
        fresh pages per message (Zenoh copies the bytes on ``put``)."""
        self.ensure(typename)
        adapted = self.adapt(message, typename)
        msgdef = self._store.get_msgdef(typename)
        size = 4 + msgdef.getsize_cdr(0, adapted, self._store)
        if buffer is None or len(buffer) != size or size < REUSE_MIN_BYTES:
            buffer = bytearray(size)  # small ones come from the allocator's free lists: cheaper than zeroing
        else:
            np.frombuffer(buffer, np.uint8).fill(0)
        with memoryview(buffer) as view, view[4:] as body:
            view[:4] = b"\x00\x01\x00\x00"
            end = msgdef.serialize_cdr_le(body, 0, adapted, self._store)
        if end + 4 != size:
            raise TypeValidationError(f"{typename}: wrote {end + 4} bytes of CDR, expected {size}")
        return buffer

    def deserialize(self, data: bytes | bytearray | memoryview, typename: str) -> Any:
        """CDR bytes as the rosbags dataclass of ``typename`` (TypeValidationError for malformed bytes)."""
        self.ensure(typename)
        raw = bytes(data)
        if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
            raise TypeValidationError(f"{typename}: {len(raw)} bytes are not a CDR payload (bad header)")
        try:
            return self._store.deserialize_cdr(raw, typename)
        except Exception as exc:
            raise TypeValidationError(f"{typename}: malformed CDR ({type(exc).__name__}: {exc})") from exc

    def adapt(self, message: Any, typename: str) -> Any:
        """``message`` as the rosbags dataclass of ``typename``, field by field (numeric sequences as numpy).

        A type without numeric arrays, bytes or chars anywhere is written from ``message`` as it is (rosbags
        reads fields by name).
        """
        cls = self._store.types[typename]
        if type(message) is cls:
            return message
        plain = self._plain.get(typename)
        if plain is None:
            plain = self._plain[typename] = self._is_plain(typename)
        if plain:
            return message
        _consts, fields = self._store.fielddefs[typename]
        return cls(**{name: self._field(getattr(message, name), desc) for name, desc in fields})

    def _is_plain(self, typename: str) -> bool:
        fields: list[tuple[str, Any]] = list(self._store.fielddefs[typename][1])
        for _name, (kind, rest) in fields:
            if kind == Nodetype.NAME and not self._is_plain(rest):
                return False
            if kind == Nodetype.BASE and rest[0] in ("byte", "char"):
                return False
            if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                (item_kind, item_rest), _count = rest
                if item_kind == Nodetype.NAME:
                    if not self._is_plain(item_rest):
                        return False
                elif item_rest[0] != "string":
                    return False
        return True

    def _field(self, value: Any, desc: Any) -> Any:
        kind, rest = desc
        if kind == Nodetype.NAME:
            return self.adapt(value, rest)
        if kind == Nodetype.BASE:
            if rest[0] in ("byte", "char") and isinstance(value, bytes | bytearray):
                return value[0] if value else 0
            return value
        (item_kind, item_rest), _count = rest
        if item_kind == Nodetype.NAME:
            return [self.adapt(v, item_rest) for v in value]
        dtype = _DTYPES.get(item_rest[0])
        if dtype is None:  # strings
            return list(value)
        if isinstance(value, np.ndarray):
            return value.astype(dtype, copy=False)
        itemsize = np.dtype(dtype).itemsize
        if isinstance(value, bytes | bytearray) and itemsize == 1:
            return np.frombuffer(value, dtype=np.uint8).view(dtype)
        if isinstance(value, array.array) and value.itemsize == itemsize:
            return np.frombuffer(value, dtype=dtype)  # a view: rclpy-style sequences are not copied
        return np.asarray(value, dtype=dtype)


def _char_as_uint8(definition: Any) -> Any:
    """A definition with ``char`` fields as ``uint8``: what rosidl makes of ``char`` (the same CDR byte, and the
    type id its hash uses; rosbags hashes it as a char)."""
    consts, fields = definition

    def fix(desc: Any) -> Any:
        kind, rest = desc
        if isinstance(rest, tuple) and len(rest) == 2 and rest[0] == "char":
            return (kind, ("uint8", rest[1]))
        if isinstance(rest, tuple) and len(rest) == 2 and isinstance(rest[0], tuple):
            return (kind, (fix(rest[0]), rest[1]))
        return desc

    return (consts, [(name, fix(desc)) for name, desc in fields])


def _references(desc: Any) -> list[str]:
    kind, rest = desc
    if kind == Nodetype.NAME:
        return [rest]
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return _references(rest[0])
    return []


_instance: RosTypes | None = None
_instance_lock = threading.Lock()


def ros_types() -> RosTypes:
    """The process' :class:`RosTypes` (created on first use)."""
    global _instance  # noqa: PLW0603
    with _instance_lock:
        if _instance is None:
            _instance = RosTypes()
        return _instance
