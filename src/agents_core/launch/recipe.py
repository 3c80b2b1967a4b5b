"""A recipe as data: :class:`Recipe`, what ``Launcher.add_pkg`` (and the launcher's other setters) fill.

A recipe is the components (each one's class, constructor arguments, topics, trigger, setup
calls, attributes assigned after construction, fallbacks), the event -> action wiring, the
settings (transport, multiprocessing, process start, config file, ``on_fail``, respawns) and the
run's attachments (web UI, Foxglove, recording). It holds the live components the recipe built;
what each one *is* is read from what it recorded (``Component.__new__`` keeps its constructor's
arguments, :mod:`agents_core.declarations.setup_calls` the calls and assignments made since), never by building
it again: :meth:`Recipe.entries` gives one :class:`ComponentEntry` per component, and
:meth:`Recipe.to_dict` the whole recipe as JSON-like data (what ``agentsctl recipe show`` prints,
secrets redacted). Two recipes compare equal when that data does.

:func:`capture_recipe` runs a recipe file up to the point where it would start its launcher and
returns that launcher's recipe (``agentsctl recipe show recipe.py``).
"""

from __future__ import annotations

import inspect
import json
import runpy
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs

from ..actions import Action
from ..declarations.setup_calls import SetupCall, recorded_assignments, recorded_setup_calls
from ..errors import ConfigError, WiringError
from ..events import Event
from ..topics import Topic
from ..transport.process_values import TAG, encode_value

if TYPE_CHECKING:
    from ..components.component_base import Component

__all__ = ["FORMAT", "ComponentEntry", "Recipe", "RecipeSettings", "RecipeShown", "capture_recipe",
           "stop_if_capturing"]

#: The ``format`` field of :meth:`Recipe.to_dict`.
FORMAT = "agents_core.recipe/1"
#: Attributes never carried as assigned ones (the config is bound as an argument; the rest is the runtime's).
NOT_CARRIED = frozenset({"config", "trigger", "runtime"})
_SECRET_WORDS = ("api_key", "apikey", "token", "password", "secret")


def constructor_parameters(component: Component) -> set[str]:
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


def bind_config(component: Component, args: tuple[Any, ...],
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


@attrs.frozen(eq=False)
class ComponentEntry:
    """One component of a recipe, as data read from what it recorded (see the module docstring).

    ``kwargs`` holds the constructor's keyword arguments with the config as it is now, and the
    attributes assigned after construction that the constructor takes (``additional_model_clients``);
    ``attributes`` the other ones (set again after construction in a component process).
    """

    name: str
    component_class: type
    args: tuple[Any, ...]
    kwargs: Mapping[str, Any]
    attributes: Mapping[str, Any]
    setup_calls: tuple[SetupCall, ...]
    inputs: tuple[Topic, ...]
    outputs: tuple[Topic, ...]
    trigger: Any
    run_type: str
    fallbacks: Mapping[str, Any]
    giveup: tuple[Action, ...]
    giveup_retries: int
    component: Component = attrs.field(repr=False)

    @classmethod
    def of(cls, component: Component) -> ComponentEntry:
        """The entry of ``component``, from its records (nothing is built)."""
        args, kwargs = getattr(component, "_init_arguments", ((), {}))
        positional, keywords = bind_config(component, args, kwargs)
        parameters = constructor_parameters(component)
        attributes: dict[str, Any] = {}
        for name in recorded_assignments(component):
            if name in NOT_CARRIED or not hasattr(component, name):
                continue
            if name in parameters:  # the constructor checks it as it checks its own arguments
                keywords[name] = getattr(component, name)
            else:
                attributes[name] = getattr(component, name)
        health = component.runtime.health
        return cls(name=component.component_name, component_class=type(component), args=tuple(positional),
                   kwargs=keywords, attributes=attributes, setup_calls=tuple(recorded_setup_calls(component)),
                   inputs=tuple(component.inputs), outputs=tuple(component.outputs), trigger=component.trigger,
                   run_type=str(getattr(component.run_type, "value", component.run_type)),
                   fallbacks=dict(health.fallbacks), giveup=tuple(health.giveup_actions),
                   giveup_retries=health.giveup_retries, component=component)

    def to_dict(self) -> dict[str, Any]:
        """JSON-like data (values as :func:`~agents_core.transport.process_values.encode_value` writes them)."""
        where = f"component {self.name!r}"
        return {
            "name": self.name,
            "class": _class_name(self.component_class),
            "args": [show_value(a, f"{where}: argument {i}") for i, a in enumerate(self.args)],
            "kwargs": {k: show_value(v, f"{where}: argument {k!r}") for k, v in self.kwargs.items()},
            "attributes": {k: show_value(v, f"{where}: attribute {k!r}") for k, v in self.attributes.items()},
            "setup_calls": [{"method": c.method, "args": show_value(list(c.args), where),
                             "kwargs": show_value(dict(c.kwargs), where)} for c in self.setup_calls],
            "inputs": [_topic(t) for t in self.inputs],
            "outputs": [_topic(t) for t in self.outputs],
            "trigger": show_value(self.trigger, f"{where}: trigger"),
            "run_type": self.run_type,
            "fallbacks": {kind: {"actions": [_action(a) for a in fallback.actions],
                                 "max_retries": fallback.max_retries} for kind, fallback in self.fallbacks.items()},
            "giveup": {"actions": [_action(a) for a in self.giveup], "max_retries": self.giveup_retries},
        }


@attrs.define(kw_only=True)
class RecipeSettings:
    """How a recipe runs: what the Launcher's constructor and setters were given."""

    #: A transport name, None (``AGENTS_TRANSPORT``, else memory), or a ready transport object.
    transport: Any = None
    transport_options: dict[str, Any] = attrs.field(factory=dict)
    config_file: str | None = None
    #: A component process each (``add_pkg(multiprocessing=True)``).
    multiprocessing: bool = False
    process_start: str = "fork"
    #: ``Launcher.on_fail(action_name, max_retries)``.
    fail_action: tuple[str, int | None] | None = None
    fallback_rate: float | None = None
    #: ``Launcher.on_process_fail(max_retries)`` (None: a crashed process is not respawned) and its give-up.
    process_fail_retries: int | None = None
    process_giveup: Action | None = None
    #: ``Launcher(namespace=...)`` (else ``AGENTS_NAMESPACE``): component and relative topic names go under it
    #: on the wire (:mod:`agents_core.transport.namespace`); ``""``: none.
    namespace: str = ""

    def set_namespace(self, namespace: str | None) -> None:
        """``Launcher(namespace=...)``: checked (ConfigError naming the field), then kept; None: the environment's."""
        from ..transport.namespace import namespace_from_env, validate_namespace  # noqa: PLC0415

        self.namespace = namespace_from_env() if namespace is None else validate_namespace(
            namespace, "Launcher(namespace=...)")

    def open_transport(self) -> tuple[Any, bool]:
        """The transport the run uses and whether the launcher closes it: the named one opened (owned), or the
        object given; seen through the namespace (:func:`~agents_core.transport.namespace.namespaced`) if any."""
        from ..transport.namespace import namespaced  # noqa: PLC0415
        from ..transport.registry import resolve_transport  # noqa: PLC0415

        owned = isinstance(self.transport, str) or self.transport is None
        transport = resolve_transport(self.transport, **self.transport_options)
        if not self.namespace:
            return transport, owned
        return namespaced(transport, self.namespace, owns_inner=owned), True

    def set_process_fail(self, max_retries: int, on_giveup: Action | None) -> None:
        """``Launcher.on_process_fail``: checked, then kept."""
        if isinstance(max_retries, bool) or not isinstance(max_retries, int) or max_retries < 0:
            raise ConfigError(f"on_process_fail: max_retries must be an int >= 0, got {max_retries!r}")
        self.process_fail_retries = max_retries
        if on_giveup is not None:
            self.set_giveup(on_giveup)

    def set_giveup(self, action: Action) -> None:
        """``Launcher.on_giveup``: checked, then kept."""
        if not isinstance(action, Action):
            raise WiringError(f"on_giveup takes an Action, got {type(action).__name__}")
        self.process_giveup = action

    def set_fail_action(self, action_name: str, max_retries: int | None) -> None:
        """``Launcher.on_fail``: checked, then kept (applied at start)."""
        if not isinstance(action_name, str) or not action_name.isidentifier():
            raise ConfigError(f"on_fail: action_name must be a method name such as 'restart', got {action_name!r}")
        if max_retries is not None and (isinstance(max_retries, bool) or not isinstance(max_retries, int)
                                        or max_retries < 0):
            raise ConfigError(f"on_fail: max_retries must be an int >= 0 or None, got {max_retries!r}")
        self.fail_action = (action_name, max_retries)

    def set_fallback_rate(self, rate: float | None) -> None:
        """``Launcher.fallback_rate = rate``: checked, then kept."""
        if rate is not None and (isinstance(rate, bool) or not isinstance(rate, int | float) or not rate > 0):
            raise ConfigError(f"fallback_rate must be a rate in Hz > 0, got {rate!r}")
        self.fallback_rate = None if rate is None else float(rate)

    def to_dict(self) -> dict[str, Any]:
        """JSON-like data (a transport object as its name)."""
        transport = self.transport if self.transport is None or isinstance(self.transport, str) else {
            "object": type(self.transport).__name__, "name": str(getattr(self.transport, "name", "?"))}
        return {"transport": transport, "transport_options": show_value(self.transport_options, "transport options"),
                "config_file": self.config_file, "multiprocessing": self.multiprocessing,
                "process_start": self.process_start,
                "on_fail": None if self.fail_action is None else {"action_name": self.fail_action[0],
                                                                  "max_retries": self.fail_action[1]},
                "fallback_rate": self.fallback_rate, "process_fail_retries": self.process_fail_retries,
                "process_giveup": None if self.process_giveup is None else _action(self.process_giveup),
                "namespace": self.namespace}


@attrs.define(eq=False)
class Recipe:
    """What a launcher runs (see the module docstring): filled by ``add_pkg`` and the launcher's setters."""

    components: list[Component] = attrs.field(factory=list)
    events_actions: dict[Event, list[Action]] = attrs.field(factory=dict)
    settings: RecipeSettings = attrs.field(factory=RecipeSettings)
    #: The run's attachments by name (``"ui"``, ``"foxglove"``, ``"record"``): their options.
    attachments: dict[str, Mapping[str, Any]] = attrs.field(factory=dict)

    def add(self, components: Sequence[Component], events_actions: Mapping[Event, Action | Sequence[Action]] | None,
            multiprocessing: bool) -> None:
        """Add components and event -> action wiring (``add_pkg``); WiringError naming what is wrong."""
        from ..components.component_base import Component  # noqa: PLC0415  (the components load the runtime)

        self.settings.multiprocessing = self.settings.multiprocessing or bool(multiprocessing)
        for c in components:
            if not isinstance(c, Component):
                raise WiringError(f"add_pkg() takes components, got {type(c).__name__}")
            if any(c.component_name == other.component_name for other in self.components):
                raise WiringError(f"two components are named {c.component_name!r}; names must be unique")
            self.components.append(c)
        names = [c.component_name for c in self.components]
        for c in self.components:  # a Cortex offers the actions of its own recipe's components by default
            getattr(c, "set_recipe_components", lambda _names: None)(names)
        for event, actions in (events_actions or {}).items():
            if not isinstance(event, Event):
                raise WiringError(f"events_actions keys must be Event objects, got {type(event).__name__}")
            action_list = [actions] if isinstance(actions, Action) else list(actions)
            for a in action_list:
                if not isinstance(a, Action):
                    raise WiringError(f"event {event.name!r}: {a!r} is not an Action")
            self.events_actions.setdefault(event, []).extend(action_list)

    def entries(self) -> list[ComponentEntry]:
        """One :class:`ComponentEntry` per component, in the order they were added."""
        return [ComponentEntry.of(c) for c in self.components]

    def component(self, name: str) -> Component:
        """The component named ``name``; ConfigError listing the names otherwise."""
        for c in self.components:
            if c.component_name == name:
                return c
        names = [c.component_name for c in self.components]
        raise ConfigError(f"no component {name!r} in the recipe (components: {names})")

    def watched_events(self) -> set[Event]:
        """Every event the launcher evaluates: those of ``events_actions`` and the components' trigger events."""
        events = set(self.events_actions)
        events.update(c.trigger for c in self.components if isinstance(c.trigger, Event))
        return events

    def to_dict(self) -> dict[str, Any]:
        """The whole recipe as JSON-like data (secrets redacted): what ``agentsctl recipe show`` prints."""
        return {
            "format": FORMAT,
            "components": [entry.to_dict() for entry in self.entries()],
            "events_actions": [{"event": _event(event), "actions": [_action(a) for a in actions]}
                               for event, actions in self.events_actions.items()],
            "settings": self.settings.to_dict(),
            "attachments": {name: show_value(dict(options), f"attachment {name!r}")
                            for name, options in sorted(self.attachments.items())},
        }

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON text."""
        return json.dumps(self.to_dict(), indent=indent, sort_keys=False)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Recipe) and self.to_dict() == other.to_dict()

    def __hash__(self) -> int:  # a mutable value: hashed by identity, as a list is not hashable at all
        return id(self)


# -- values for people ------------------------------------------------------------------------


def show_value(value: Any, where: str = "value") -> Any:
    """``value`` as JSON-like data: as it crosses to a component process where it can, else its type; secrets hidden."""
    if isinstance(value, Event):
        return _event(value)
    if isinstance(value, Action):
        return _action(value)
    if isinstance(value, list | tuple) and any(isinstance(v, Event | Action) for v in value):
        return [show_value(v, f"{where}[{i}]") for i, v in enumerate(value)]
    try:
        data = encode_value(value, where)
    except (ConfigError, TypeError, ValueError, RecursionError):
        data = {TAG: "local only", "v": _class_name(type(value))}
    return _redacted(data)


def _redacted(data: Any) -> Any:
    if isinstance(data, list):
        return [_redacted(v) for v in data]
    if isinstance(data, dict):
        return {k: ("<redacted>" if isinstance(v, str) and v and _secret(k) else _redacted(v)) for k, v in data.items()}
    return data


def _secret(key: str) -> bool:
    lowered = key.lower()
    return any(word in lowered for word in _SECRET_WORDS)


def _class_name(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _topic(topic: Topic) -> dict[str, Any]:
    return {"name": topic.name, "type": topic.type_name}


def _event(event: Event) -> dict[str, Any]:
    return {"name": event.name, "topics": sorted(t.name for t in event.topics.values())}


def _action(action: Action) -> dict[str, Any]:
    owner = action.owner
    return {"name": action.name, "owner": getattr(owner, "component_name", None) if owner is not None else None,
            "args": show_value(list(action.args), f"action {action.name!r}"),
            "kwargs": show_value(dict(action.kwargs), f"action {action.name!r}"), "description": action.description}


# -- capturing a recipe file's recipe ---------------------------------------------------------

_capturing: list[Recipe] | None = None


class RecipeShown(BaseException):  # a control-flow signal, like SystemExit
    """Raised by ``Launcher.start()`` while :func:`capture_recipe` runs a recipe file: the recipe is complete."""


def stop_if_capturing(recipe: Recipe) -> None:
    """Called by ``Launcher.start()``: while :func:`capture_recipe` runs, keep ``recipe`` and stop there."""
    if _capturing is not None:
        _capturing.append(recipe)
        raise RecipeShown


def capture_recipe(path: str | Path, argv: Sequence[str] = ()) -> Recipe:
    """Run the recipe file ``path`` as ``__main__`` (with ``argv``) until its launcher would start; its recipe.

    ConfigError if the file never starts a launcher. The components are built (their constructors
    run) but never bound, configured or started.
    """
    global _capturing  # noqa: PLW0603  # one capture at a time, in the CLI's process
    file = Path(path)
    if not file.is_file():
        raise ConfigError(f"recipe {str(path)!r} is not a file")
    found: list[Recipe] = []
    saved_argv, saved_path = list(sys.argv), list(sys.path)
    sys.argv = [str(file.resolve()), *argv]
    sys.path.insert(0, str(file.resolve().parent))
    _capturing = found
    try:
        runpy.run_path(str(file.resolve()), run_name="__main__")
    except RecipeShown:
        pass
    except SystemExit as exc:
        if not found:
            raise ConfigError(f"recipe {str(path)!r} exited ({exc.code}) before starting a launcher") from None
    finally:
        _capturing = None
        sys.argv, sys.path[:] = saved_argv, saved_path
    if not found:
        raise ConfigError(f"recipe {str(path)!r} never starts a launcher (Launcher.bringup() or start())")
    return found[0]

