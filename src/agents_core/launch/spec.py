"""``ComponentSpec``: everything a child process needs to rebuild one component, as JSON-like data.

A component records the arguments it was constructed with (``Component.__new__``); the spec
holds its class (``module:qualname``), those arguments encoded through the value-codec registry
of :mod:`agents_core.transport.process_values` (topics, configs, models and other attrs data,
model and database clients through their own ``serialize()``, enums, paths, plain JSON values;
re-exported here), the component's config as it is at launch
(a config file may have changed it), its fallbacks and give-up actions (the component's own
methods, with JSON-like arguments), and how to reach the transport. A class defined in the
recipe itself (the ``__main__`` module) is named ``RECIPE_MODULE:qualname``; the child imports
the recipe file by path under that module name, so its ``if __name__ == "__main__":`` block
does not run. The launcher's ``sys.path`` travels too, so a recipe's sibling modules import
the same in the child whatever directory the recipe was started from.

The spec is the encoding of one entry of the recipe (:class:`~agents_core.launch.recipe.ComponentEntry`,
read from what the component recorded: nothing is built to learn what it is). What the recipe
did to the component after building it travels as well: the calls of its setup methods
(:mod:`agents_core.declarations.setup_calls`: ``register_tool``, ``set_topic_prompt``, processors, ...),
replayed in order, and public attributes it assigned (an attribute named as a constructor
parameter, such as ``additional_model_clients``, becomes that argument; another one is set again
after construction). A function crosses by its qualified name (a module-level
``def``); a lambda or a nested function cannot, and is refused at ``add_pkg`` naming the
component, the call and the function. :func:`check_rebuild` refuses, naming it, state added past
the component's methods (a pre-processor given to a publisher directly), which the child would lack.

A component triggered by an :class:`~agents_core.events.Event` gets a stand-in event of the same
name (:class:`LauncherEvent`): the launcher watches the event's topics and evaluates its
condition, as it does for every event, and sends each firing down the child's command pipe.

A spec may hold secrets (a client's API key): it travels over a pipe, never in argv, the
environment or a file. ``SPEC_VERSION`` is checked by the child, so a launcher and a child
from different releases fail with a clear error instead of building something else.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs

from ..declarations.setup_calls import SETUP_MARK, SetupCall, expected_state
from ..errors import ConfigError
from ..events import Event
from ..topics import Topic
from ..transport.process_values import (  # re-exported: the codecs moved below the launcher
    RECIPE_MODULE,
    TAG,
    LauncherEvent,
    ValueCodec,
    class_path,
    decode_value,
    encode_value,
    import_class,
    register_value_codec,
)
from .recipe import ComponentEntry

if TYPE_CHECKING:
    from ..components.component_base import Component

__all__ = [
    "RECIPE_MODULE",
    "SPEC_VERSION",
    "TAG",
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

SPEC_VERSION = 3


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
    #: The launcher's telemetry settings (:class:`~agents_core.telemetry.TelemetrySettings` fields), None: off there.
    telemetry: dict[str, Any] | None = None
    #: The recipe's namespace: the child sees its transport through it (:mod:`agents_core.transport.namespace`).
    namespace: str = ""
    #: A forked process's: the launcher's environment changes since its fork server started (None: removed);
    #: None for a spawned one, which inherits the launcher's (:mod:`agents_core.launch.fork_server`).
    environment: dict[str, str | None] | None = None
    version: int = SPEC_VERSION

    @classmethod
    def from_component(cls, component: Component, transport: str, transport_options: Mapping[str, Any],
                       parent_pid: int) -> ComponentSpec:
        """The spec of ``component``; ConfigError naming the component for what cannot cross processes."""
        return cls.from_entry(ComponentEntry.of(component), transport, transport_options, parent_pid)

    @classmethod
    def from_entry(cls, entry: ComponentEntry, transport: str, transport_options: Mapping[str, Any],
                   parent_pid: int) -> ComponentSpec:
        """The spec of one recipe entry (:class:`~agents_core.launch.recipe.ComponentEntry`), encoded."""
        name = entry.name
        where = f"component {name!r}"
        positional, keywords = entry.args, dict(entry.kwargs)
        trigger = entry.trigger
        if isinstance(trigger, Event):
            # The launcher evaluates the event and forwards its firings (see LauncherEvent).
            stand_in = LauncherEvent(trigger.name)
            positional = tuple(stand_in if a is trigger else a for a in positional)
            keywords = {k: stand_in if v is trigger else v for k, v in keywords.items()}
        component = entry.component
        spec = cls(component_name=name, component_class=class_path(entry.component_class),
                   args=[encode_value(a, f"{where}: argument {i}") for i, a in enumerate(positional)],
                   kwargs={k: encode_value(v, f"{where}: argument {k!r}") for k, v in keywords.items()},
                   transport=transport,
                   transport_options={k: encode_value(v, f"transport option {k!r}")
                                      for k, v in transport_options.items()},
                   parent_pid=parent_pid,
                   fallbacks={kind: {"actions": [_encode_own_action(component, a) for a in fallback.actions],
                                     "max_retries": fallback.max_retries}
                              for kind, fallback in entry.fallbacks.items()},
                   giveup=[_encode_own_action(component, a) for a in entry.giveup],
                   giveup_retries=entry.giveup_retries,
                   setup_calls=[_encode_setup_call(where, call) for call in entry.setup_calls],
                   attributes={k: encode_value(v, f"{where}: attribute {k!r} (set after construction)")
                               for k, v in entry.attributes.items()},
                   sys_path=_import_path(), telemetry=_telemetry_fields())
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

    def apply_environment(self) -> None:
        """Set and unset in this process what :attr:`environment` says (first thing, before anything reads it)."""
        if self.environment is None:
            return
        if not isinstance(self.environment, Mapping):
            raise ConfigError("component spec: environment must be a mapping")
        for name, value in self.environment.items():
            if not isinstance(name, str) or not (value is None or isinstance(value, str)):
                raise ConfigError(f"component spec: environment variable {name!r} must be a string (or None)")
            try:
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value
            except ValueError as exc:  # a name with "=" or a NUL: not the launcher's
                raise ConfigError(f"component spec: environment variable {name!r}: {exc}") from exc

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


def check_rebuild(component: Component, spec: ComponentSpec) -> None:
    """Refuse, naming it, state the child would lack: added past the component's methods since its construction.

    Nothing is rebuilt: the component's record (:func:`~agents_core.declarations.setup_calls.expected_state`)
    says what its constructor and its recorded setup calls made; the attributes assigned after
    construction are in ``spec`` already (:meth:`ComponentSpec.from_component`).
    """
    from ..components.component_base import carried_state  # noqa: PLC0415

    where = f"component {component.component_name!r}"
    expected = expected_state(component)
    if expected is None:
        return
    for what, count in carried_state(component).items():
        if count != expected.get(what, 0):
            raise ConfigError(f"{where}: {what} added after construction are not carried to a component process "
                              "(set other than through the component's methods); add them in the component's "
                              "__init__, or run it with multiprocessing=False")
    if spec.attributes or spec.kwargs:
        spec.find_recipe(where)


def _telemetry_fields() -> dict[str, Any] | None:
    from ..telemetry import active_settings  # noqa: PLC0415  (light: nothing of OpenTelemetry)

    settings = active_settings()
    return None if settings is None else settings.to_dict()
