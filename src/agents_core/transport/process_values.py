"""Values that cross to another process: a **value-codec registry** (JSON-like data and back).

What a component process is built from (:class:`~agents_core.launch.spec.ComponentSpec`) is its
constructor's arguments, encoded here: topics, configs, models and other attrs data, model and
database clients through their own ``serialize()``, enums, paths, tuples, plain JSON values,
functions by their ``module:qualname``, another component's ``@component_action`` as a
:class:`~agents_core.declarations.component_method.ComponentMethod`, and what a package registers with
:func:`register_value_codec` (Cortex's actions: :mod:`agents_core.components.cortex.transfer`).
A class defined in the recipe itself (the ``__main__`` module) is named ``RECIPE_MODULE:qualname``;
the child imports the recipe file under that module name.

It sits below the components and the launcher (it needs only the vocabulary: topics, configs,
events, actions), so a component package registers its own codecs without importing the launcher.
"""

from __future__ import annotations

import enum
import importlib
import inspect
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import attrs

from ..actions import ACTION_MARK
from ..config import BaseAttrs
from ..declarations.component_method import ComponentMethod
from ..declarations.event_transfer import decode_event, encode_event
from ..errors import ConfigError
from ..events import Event
from ..support.registry import Registry
from ..topics import FixedInput, QoSConfig, Topic

__all__ = [
    "RECIPE_MODULE",
    "TAG",
    "LauncherEvent",
    "ValueCodec",
    "class_path",
    "decode_value",
    "encode_value",
    "import_class",
    "register_value_codec",
]

#: The module name a child imports the recipe file under.
RECIPE_MODULE = "agents_recipe"
#: Marks an encoded (non-JSON) value: ``{TAG: codec name, "v": data}``.
TAG = "__agents_value__"


def class_path(cls: type) -> str:
    """``module:qualname`` of ``cls``; classes of the running recipe (``__main__``) get RECIPE_MODULE."""
    if "<locals>" in cls.__qualname__:
        raise ConfigError(f"class {cls.__qualname__!r} is defined inside a function: another process cannot "
                          "import it; define it at the top level of a module or of the recipe")
    module = RECIPE_MODULE if cls.__module__ == "__main__" else cls.__module__
    return f"{module}:{cls.__qualname__}"


def import_class(path: str) -> Any:
    """The object named by ``module:qualname`` (the recipe module must be imported first)."""
    module_name, sep, qualname = path.partition(":")
    if not sep or not module_name or not qualname:
        raise ConfigError(f"{path!r} is not a 'module:qualname' class path")
    try:
        obj: Any = importlib.import_module(module_name)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"cannot import {path!r}: {exc}") from exc
    return obj


# -- the value codecs -------------------------------------------------------------------------


@attrs.define(frozen=True)
class ValueCodec:
    """How one kind of value crosses to another process: ``encode(value) -> JSON-like`` and back."""

    name: str
    kind: type
    encode: Callable[[Any], Any]
    decode: Callable[[Any], Any]


_codecs: Registry[ValueCodec] = Registry("process value codec", hint="register it with register_value_codec()")
_by_class: Registry[ValueCodec] = Registry("process value codec")


def register_value_codec(codec: ValueCodec) -> ValueCodec:
    """Make values of ``codec.kind`` (and its subclasses) transferable to component processes."""
    _codecs.register(codec.name, codec, replace=True)
    _by_class.register(codec.kind.__name__, codec, replace=True)
    return codec


def encode_value(value: Any, where: str = "value") -> Any:
    """``value`` as JSON-like data a child process can decode; ConfigError naming ``where`` if it cannot."""
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, list):
        return [encode_value(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value) and TAG not in value:
        return {k: encode_value(v, f"{where}[{k!r}]") for k, v in value.items()}
    codec = _by_class.find_for_class(type(value))
    if codec is not None and not isinstance(value, codec.kind):
        codec = None  # the registry matches class names: threading.Event is not our Event
    codec = codec or _client_codec_for(value)
    if codec is None and attrs.has(type(value)):
        # Any attrs class (SemanticRouter's Route, a recipe's own data class), not only configs:
        # rebuilt from its init fields, as a BaseAttrs is.
        codec = _codecs.get("attrs")
    if codec is None and _is_component_action(value):
        # Another component's action (an LLM's tool): the child reaches it through that component's services.
        return {TAG: "component method", "v": [value.__self__.component_name, value.__name__]}
    if codec is None and inspect.isroutine(value):
        return {TAG: "function", "v": _encode_function(value, where)}
    if codec is None and isinstance(value, Event):
        raise ConfigError(f"{where}: event {value.name!r} is evaluated in the launcher; a component process gets "
                          "only its trigger event (the launcher forwards its firings). Use the event as the "
                          "component's trigger or in add_pkg(events_actions=...), or run it with "
                          "multiprocessing=False")
    if codec is None:
        raise ConfigError(f"{where}: a {type(value).__name__} cannot be sent to a component process (known: "
                          f"JSON values, {', '.join(sorted(_codecs))}); build it in the component instead")
    return {TAG: codec.name, "v": codec.encode(value)}


def decode_value(data: Any) -> Any:
    """The value :func:`encode_value` encoded."""
    if isinstance(data, list):
        return [decode_value(v) for v in data]
    if isinstance(data, dict):
        if TAG in data:
            return _codecs.get(str(data[TAG])).decode(data.get("v"))
        return {k: decode_value(v) for k, v in data.items()}
    return data


def _encode_topic(topic: Topic) -> dict[str, Any]:
    out: dict[str, Any] = {"name": topic.name, "msg_type": topic.type_name,
                           "qos": attrs.asdict(topic.qos_profile)}
    if isinstance(topic, FixedInput):
        out["fixed"] = encode_value(topic.fixed, f"FixedInput {topic.name!r}")
    return out


def _decode_topic(data: dict[str, Any]) -> Topic:
    qos = QoSConfig(**data["qos"])
    if "fixed" in data:
        return FixedInput(data["name"], data["msg_type"], fixed=decode_value(data["fixed"]), qos_profile=qos)
    return Topic(data["name"], data["msg_type"], qos_profile=qos)


def _encode_attrs(value: BaseAttrs) -> dict[str, Any]:
    fields = {a.alias: encode_value(getattr(value, a.name), f"{type(value).__name__}.{a.name}")
              for a in attrs.fields(type(value)) if a.init}
    return {"class": class_path(type(value)), "fields": fields}


def _decode_attrs(data: dict[str, Any]) -> Any:
    cls = import_class(data["class"])
    return cls(**{k: decode_value(v) for k, v in data["fields"].items()})


def _encode_client(client: Any) -> dict[str, Any]:
    return {"class": class_path(type(client)), "spec": client.serialize()}


def _decode_client(data: dict[str, Any]) -> Any:
    from ..clients.client_base import client_from_spec  # noqa: PLC0415  # clients load httpx: only when used

    import_class(data["class"])  # registers a client class defined in the recipe or a user module
    return client_from_spec(dict(data["spec"]))


def _encode_enum(value: enum.Enum) -> dict[str, Any]:
    return {"class": class_path(type(value)), "name": value.name}


def _encode_function(func: Any, where: str) -> str:
    """A function as ``module:qualname``, when importing that name gives this very function back."""
    owner = getattr(func, "__self__", None)
    module = getattr(func, "__module__", None) or getattr(getattr(func, "__objclass__", None), "__module__", None)
    qualname = getattr(func, "__qualname__", "") or ""
    shown = f"{module}.{qualname}" if module else repr(func)
    fix = ("define it with `def` at the top level of a module or of the recipe and pass that, or run the "
           "component with multiprocessing=False")
    if owner is not None and not inspect.ismodule(owner):
        raise ConfigError(f"{where}: {shown} is a method bound to a {type(owner).__name__}, which a component "
                          f"process cannot rebuild; {fix}")
    if not module or not qualname or "<" in qualname:
        what = "a lambda" if "<lambda>" in qualname else "a function defined inside another function"
        raise ConfigError(f"{where}: {shown} is {what}: a component process cannot import it; {fix}")
    found: Any = sys.modules.get(module)
    for part in qualname.split("."):
        found = getattr(found, part, None)
    if found is not func:
        raise ConfigError(f"{where}: {shown} is not reachable under that name in its module; {fix}")
    return f"{RECIPE_MODULE if module == '__main__' else module}:{qualname}"


def _is_component_action(value: Any) -> bool:
    """Whether ``value`` is a ``@component_action`` bound to a component."""
    return (inspect.ismethod(value) and getattr(value.__func__, ACTION_MARK, None) is not None
            and isinstance(getattr(value.__self__, "component_name", None), str))


def _decode_function(path: str) -> Any:
    func = import_class(path)
    if not callable(func):
        raise ConfigError(f"{path!r} is not callable")
    return func


class LauncherEvent(Event):
    """The trigger event of a component in its own process: fired by the launcher, which evaluates the
    recipe's event of the same name and forwards each firing down the process's command pipe."""


def _client_codec_for(value: Any) -> ValueCodec | None:
    """The client codec for a model or database client. Looked up by module, not imported here: the
    clients load httpx, which a component process without clients should not pay for at start."""
    module = sys.modules.get("agents_core.clients.client_base")
    if module is None or not isinstance(value, module.BaseClient):
        return None
    return _codecs.get("client")


def _register_builtin_codecs() -> None:
    register_value_codec(ValueCodec("topic", Topic, _encode_topic, _decode_topic))
    register_value_codec(ValueCodec("attrs", BaseAttrs, _encode_attrs, _decode_attrs))
    # Decoding by name only; encoding finds clients through _client_codec_for.
    _codecs.register("client", ValueCodec("client", object, _encode_client, _decode_client))
    register_value_codec(ValueCodec("enum", enum.Enum, _encode_enum,
                                    lambda d: getattr(import_class(d["class"]), d["name"])))
    register_value_codec(ValueCodec("path", Path, str, Path))
    register_value_codec(ValueCodec("tuple", tuple, lambda t: [encode_value(v) for v in t],
                                    lambda d: tuple(decode_value(v) for v in d)))
    # Encoding through encode_value (which knows where the function is used); decoding by name.
    _codecs.register("function", ValueCodec("function", object, str, _decode_function))
    _codecs.register("component method", ValueCodec("component method", object, list,
                                                    lambda d: ComponentMethod(str(d[0]), str(d[1]))))
    register_value_codec(ValueCodec("launcher event", LauncherEvent, lambda e: e.name, LauncherEvent))
    # Any other event crosses as its topic condition (the VLA's termination event); see event_transfer.
    register_value_codec(ValueCodec("event", Event, encode_event, decode_event))


_register_builtin_codecs()
