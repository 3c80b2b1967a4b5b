"""``ComponentSpec``: everything a child process needs to rebuild one component, as JSON-like data.

A component records the arguments it was constructed with (``Component.__new__``); the spec
holds its class (``module:qualname``), those arguments encoded through a **value-codec registry**
(topics, configs, models and other attrs data, model and database clients through their own
``serialize()``, enums, paths, plain JSON values), the component's config as it is at launch
(a config file may have changed it), its fallbacks and give-up actions (the component's own
methods, with JSON-like arguments), and how to reach the transport. A class defined in the
recipe itself (the ``__main__`` module) is named ``RECIPE_MODULE:qualname``; the child imports
the recipe file by path under that module name, so its ``if __name__ == "__main__":`` block
does not run. The launcher's ``sys.path`` travels too, so a recipe's sibling modules import
the same in the child whatever directory the recipe was started from.

What the recipe did to the component after building it travels as well: the calls of its
setup methods (:mod:`agents_core.setup_calls`: ``register_tool``, ``set_topic_prompt``,
processors, ...), replayed in order, and public attributes it assigned (an attribute named as a
constructor parameter, such as ``additional_model_clients``, becomes that argument; another one
is set again after construction). A function crosses by its qualified name (a module-level
``def``); a lambda or a nested function cannot, and is refused at ``add_pkg`` naming the
component, the call and the function. :func:`check_rebuild` rebuilds the component in the
launcher and refuses, naming the attribute, any difference that would remain.

A component triggered by an :class:`~agents_core.events.Event` gets a stand-in event of the same
name (:class:`LauncherEvent`): the launcher watches the event's topics and evaluates its
condition, as it does for every event, and sends each firing down the child's command pipe.

A spec may hold secrets (a client's API key): it travels over a pipe, never in argv, the
environment or a file. ``SPEC_VERSION`` is checked by the child, so a launcher and a child
from different releases fail with a clear error instead of building something else.
"""

from __future__ import annotations

import enum
import importlib
import inspect
import os
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs

from ..actions import ACTION_MARK
from ..component_method import ComponentMethod
from ..config import BaseAttrs
from ..errors import ConfigError
from ..event_transfer import decode_event, encode_event
from ..events import Event
from ..registry import Registry
from ..setup_calls import SETUP_MARK, SetupCall, recorded_setup_calls
from ..topics import FixedInput, QoSConfig, Topic

if TYPE_CHECKING:
    from ..components.component_base import Component

__all__ = [
    "RECIPE_MODULE",
    "SPEC_VERSION",
    "ComponentSpec",
    "LauncherEvent",
    "ValueCodec",
    "check_rebuild",
    "class_path",
    "decode_value",
    "encode_value",
    "import_class",
    "register_value_codec",
]

SPEC_VERSION = 2
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
    codec = _by_class.find_for_class(type(value)) or _client_codec_for(value)
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


# -- the spec ---------------------------------------------------------------------------------


@attrs.define(kw_only=True)
class ComponentSpec:
    """One component, as a child process rebuilds it (see the module docstring)."""

    component_name: str
    component_class: str
    args: list[Any]
    kwargs: dict[str, Any]
    transport: str
    transport_options: dict[str, Any]
    recipe_path: str | None = None
    parent_pid: int = 0
    #: Fallbacks and give-up actions the recipe set on the component: its own methods only.
    fallbacks: dict[str, Any] = attrs.field(factory=dict)
    giveup: list[Any] = attrs.field(factory=list)
    giveup_retries: int = 1
    #: Setup calls made after construction (``{"method", "args", "kwargs"}``), replayed in order.
    setup_calls: list[Any] = attrs.field(factory=list)
    #: Public attributes the recipe assigned after construction, set again after it.
    attributes: dict[str, Any] = attrs.field(factory=dict)
    #: The launcher's import path, put in front of the child's (a recipe's sibling modules).
    sys_path: list[str] = attrs.field(factory=list)
    version: int = SPEC_VERSION

    @classmethod
    def from_component(cls, component: Component, transport: str, transport_options: Mapping[str, Any],
                       parent_pid: int) -> ComponentSpec:
        """The spec of ``component``; ConfigError naming the component for what cannot cross processes."""
        name = component.component_name
        where = f"component {name!r}"
        args, kwargs = getattr(component, "_init_arguments", ((), {}))
        positional, keywords = _bind_config(component, args, kwargs)
        trigger = component.trigger
        if isinstance(trigger, Event):
            # The launcher evaluates the event and forwards its firings (see LauncherEvent).
            stand_in = LauncherEvent(trigger.name)
            positional = tuple(stand_in if a is trigger else a for a in positional)
            keywords = {k: stand_in if v is trigger else v for k, v in keywords.items()}
        spec = cls(component_name=name, component_class=class_path(type(component)),
                   args=[encode_value(a, f"{where}: argument {i}") for i, a in enumerate(positional)],
                   kwargs={k: encode_value(v, f"{where}: argument {k!r}") for k, v in keywords.items()},
                   transport=transport,
                   transport_options={k: encode_value(v, f"transport option {k!r}")
                                      for k, v in transport_options.items()},
                   parent_pid=parent_pid,
                   fallbacks={kind: {"actions": [_encode_own_action(component, a) for a in fallback.actions],
                                     "max_retries": fallback.max_retries}
                              for kind, fallback in component.runtime.health.fallbacks.items()},
                   giveup=[_encode_own_action(component, a) for a in component.runtime.health.giveup_actions],
                   giveup_retries=component.runtime.health.giveup_retries,
                   setup_calls=[_encode_setup_call(where, call) for call in recorded_setup_calls(component)],
                   sys_path=_import_path())
        spec.find_recipe(where)
        return spec

    def find_recipe(self, where: str) -> None:
        """Set :attr:`recipe_path` when the spec names something defined in the running recipe."""
        if self.recipe_path is None and _mentions_recipe(self):
            main_file = getattr(sys.modules.get("__main__"), "__file__", None)
            if main_file is None:
                raise ConfigError(f"{where} uses a class or function defined in an interactive session; "
                                  "multiprocessing needs it in a module or a recipe file")
            self.recipe_path = str(Path(main_file).resolve())

    def extend_import_path(self) -> None:
        """Put the launcher's import path in front of this process's (before importing anything it names)."""
        for entry in reversed(self.sys_path):
            if entry not in sys.path:
                sys.path.insert(0, entry)

    def to_dict(self) -> dict[str, Any]:
        """JSON-like form (what goes down the pipe)."""
        return attrs.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ComponentSpec:
        """Check the version and the fields; ConfigError on anything unexpected."""
        if not isinstance(data, Mapping):
            raise ConfigError("a component spec must be a mapping")
        if data.get("version") != SPEC_VERSION:
            raise ConfigError(f"component spec version {data.get('version')!r} is not the supported "
                              f"{SPEC_VERSION}: the launcher and the child come from different releases")
        names = {a.name for a in attrs.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(f"component spec: unknown field(s) {unknown}")
        try:
            return cls(**data)
        except TypeError as exc:
            raise ConfigError(f"component spec: {exc}") from exc

    def build(self) -> Component:
        """Construct the component from the decoded arguments, then set what the recipe set after that:
        its public attributes, its setup calls (in order), its fallbacks."""
        from ..components.component_base import Component  # noqa: PLC0415

        component_class = import_class(self.component_class)
        if not (isinstance(component_class, type) and issubclass(component_class, Component)):
            raise ConfigError(f"{self.component_class!r} is not a Component class")
        component: Component = component_class(*decode_value(self.args), **decode_value(self.kwargs))
        for name, value in self.attributes.items():
            setattr(component, name, decode_value(value))
        for call in self.setup_calls:
            method = getattr(component, str(call["method"]), None)
            if not getattr(method, SETUP_MARK, False):  # only what setup_calls records, nothing else
                raise ConfigError(f"component {self.component_name!r}: {call['method']!r} is not a setup method")
            assert method is not None
            method(*decode_value(call["args"]), **decode_value(call["kwargs"]))
        self._restore_fallbacks(component)
        return component

    def _restore_fallbacks(self, component: Component) -> None:
        from ..actions import Action, Fallback  # noqa: PLC0415

        health = component.runtime.health

        def action(data: dict[str, Any]) -> Action:
            return Action(getattr(component, data["method"]), args=decode_value(data["args"]),
                          kwargs=decode_value(data["kwargs"]), description=data.get("description"))

        # Replaced, not added to: what the constructor set is part of what the parent had.
        for kind, data in self.fallbacks.items():
            health.set_fallback(kind, Fallback([action(a) for a in data["actions"]], data["max_retries"]))
        if self.giveup:
            health.set_giveup([action(a) for a in self.giveup], self.giveup_retries)

    def __repr__(self) -> str:
        # Never the arguments: a client's spec may hold an API key.
        return f"ComponentSpec({self.component_name!r}, {self.component_class!r}, transport={self.transport!r})"


def _mentions_recipe(spec: ComponentSpec) -> bool:
    return f'"{RECIPE_MODULE}:' in repr(spec.to_dict()).replace("'", '"')


def _bind_config(component: Component, args: tuple[Any, ...],
                 kwargs: dict[str, Any]) -> tuple[tuple[Any, ...], dict[str, Any]]:
    """The constructor arguments with ``config`` replaced by the component's config as it is now.

    A launcher's config file (or code run after construction) may have changed the config; the
    child must start from what the parent would have run. The arguments are normalised to
    keywords where the signature allows it.
    """
    try:
        signature = inspect.signature(type(component).__init__)
        bound = signature.bind(None, *args, **kwargs)
    except TypeError:
        return args, kwargs
    arguments = dict(bound.arguments)
    arguments.pop(next(iter(signature.parameters)), None)  # self
    has_config = "config" in signature.parameters or any(
        p.kind is inspect.Parameter.VAR_KEYWORD for p in signature.parameters.values())
    positional: list[Any] = []
    keywords: dict[str, Any] = {}
    for name, value in arguments.items():
        param = signature.parameters[name]
        if param.kind is inspect.Parameter.VAR_POSITIONAL:
            positional.extend(value)
        elif param.kind is inspect.Parameter.VAR_KEYWORD:
            keywords.update(value)
        elif param.kind is inspect.Parameter.POSITIONAL_ONLY:
            positional.append(value)
        else:
            keywords[name] = value
    if has_config and "config_file" not in keywords:
        keywords["config"] = component.config
    return tuple(positional), keywords


def _encode_own_action(component: Component, action: Any) -> dict[str, Any]:
    """A fallback action as data: a method of the component itself, with JSON-like arguments."""
    where = f"component {component.component_name!r}: fallback action {action.name!r}"
    if action.owner is not component:
        raise ConfigError(f"{where} is not a method of the component; in a component process a fallback can "
                          "only run the component's own methods")
    return {"method": action.name, "args": encode_value(list(action.args), where),
            "kwargs": encode_value(dict(action.kwargs), where), "description": action.description}


def _encode_setup_call(where: str, call: SetupCall) -> dict[str, Any]:
    first = call.args[0] if call.args else None
    about = first.name if isinstance(first, Topic) else first if isinstance(first, str) and len(first) < 80 else None
    here = f"{where}: {call.method}(" + (f"{about!r}, ...)" if about is not None else "...)")
    return {"method": call.method, "args": [encode_value(a, here) for a in call.args],
            "kwargs": {k: encode_value(v, f"{here} {k}=") for k, v in call.kwargs.items()}}


def _import_path() -> list[str]:
    """This process's ``sys.path`` as absolute directories (``""`` is the current directory)."""
    return [os.path.abspath(entry or os.curdir) for entry in sys.path if isinstance(entry, str)]


def _extra_state(component: Component) -> dict[str, int]:
    """What a component holds beyond its constructor's doing that no attribute shows."""
    health = component.runtime.health
    return {"fallbacks": len(health.fallbacks) + len(health.giveup_actions),
            "publisher pre-processors": sum(len(p._preprocessors) for p in component.publishers_dict.values()),
            "callback post-processors": sum(len(cb._postprocessors) for cb in
                                            (*component.callbacks.values(), *component.trig_callbacks.values()))}


#: Attributes compared by other means (the config is bound as an argument, the trigger is a stand-in).
_NOT_COMPARED = frozenset({"config", "trigger", "runtime"})
_OPAQUE = object()


def _public_state(component: Component) -> dict[str, Any]:
    """The component's public attributes, encoded (``_OPAQUE`` for a value no codec knows)."""
    state: dict[str, Any] = {}
    for name, value in vars(component).items():
        if name.startswith("_") or name in _NOT_COMPARED:
            continue
        try:
            state[name] = encode_value(value, name)
        except ConfigError:
            state[name] = _OPAQUE
    return state


def _constructor_parameters(component: Component) -> set[str]:
    """Parameter names the component's constructor takes (through ``**kwargs`` too, up its classes)."""
    names: set[str] = set()
    for klass in type(component).__mro__:
        init = klass.__dict__.get("__init__")
        if init is None or klass is object:
            continue
        params = inspect.signature(init).parameters.values()
        names.update(p.name for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD))
        if not any(p.kind is p.VAR_KEYWORD for p in params):
            break  # this constructor passes nothing more up
    return names


def _carry_attributes(component: Component, spec: ComponentSpec, rebuilt: Component) -> bool:
    """Put in ``spec`` the public attributes of ``component`` that ``rebuilt`` lacks or has otherwise;
    whether there were any. ConfigError naming an attribute that cannot cross."""
    where = f"component {component.component_name!r}"
    now, then = _public_state(component), _public_state(rebuilt)
    parameters = _constructor_parameters(component)
    changed = False
    for name, value in now.items():
        if name in then and (value is _OPAQUE or value == then[name]):
            continue  # the same, or two values of a kind no codec knows (a queue, a lock): built alike
        if value is _OPAQUE:
            encode_value(getattr(component, name), f"{where}: attribute {name!r} (set after construction)")
        if name in parameters:  # the constructor checks it as it checks its own arguments
            spec.kwargs[name] = value
        else:
            spec.attributes[name] = value
        changed = True
    return changed


def check_rebuild(component: Component, spec: ComponentSpec) -> None:
    """Rebuild ``component`` from ``spec`` here; carry the attributes assigned after construction into
    ``spec``, and refuse, naming it, whatever the child would still lack.
    """
    where = f"component {component.component_name!r}"
    if spec.recipe_path is not None and RECIPE_MODULE not in sys.modules:
        # In the launcher's process the recipe is __main__: the same module under the child's name.
        sys.modules[RECIPE_MODULE] = sys.modules["__main__"]
    rebuilt = spec.build()
    if _carry_attributes(component, spec, rebuilt):
        spec.find_recipe(where)
        if spec.recipe_path is not None and RECIPE_MODULE not in sys.modules:
            sys.modules[RECIPE_MODULE] = sys.modules["__main__"]
        rebuilt = spec.build()
    now, then = _public_state(component), _public_state(rebuilt)
    for name, value in now.items():
        if value is not _OPAQUE and then.get(name, _OPAQUE) != value:
            raise ConfigError(f"{where}: attribute {name!r} set after construction does not come out the same in a "
                              "component process; set it through the constructor, or run it with "
                              "multiprocessing=False")
    before, after = _extra_state(component), _extra_state(rebuilt)
    for what, count in before.items():
        if count != after[what]:
            raise ConfigError(f"{where}: {what} added after construction are not carried to a component process "
                              "(set other than through the component's methods); add them in the component's "
                              "__init__, or run it with multiprocessing=False")
