"""What a transport can do, said by the transport itself: :class:`TransportDescriptor`.

The CLI, the web UI's attach mode, the launch report, the launcher and the recipe test harness
need to know a few things about a transport *before* (or besides) opening it: whether it lives in
one process, how another process reaches it, whether it takes endpoints, what it can carry. They
ask the transport's descriptor (:func:`agents_core.transport.registry.describe_transport_kind`),
never its name. A transport's package defines its descriptor, next to its driver, in a module that
does not import the middleware (``agents_zenoh.descriptor``, ``agents_ros2.descriptor``), and
registers it once: an ``agents_core.transports`` entry point that loads the descriptor (or a
factory with a ``descriptor`` attribute), or :func:`~agents_core.transport.registry.register_transport`.

What it can carry is a set of words from :data:`CARRIES`:

- ``"values"``, ``"requests"``: topics and services (every transport);
- ``"goals"``: long-running goals with feedback;
- ``"discovery"``: another observer can list the graph;
- ``"cross-process"``: components may live in different processes (``multiprocessing=True``);
- ``"attach"``: a process started later (``agentsctl topics``, ``agentsctl ui``) can reach a
  running recipe.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Sequence
from typing import Any

from attrs import define, field

__all__ = ["CARRIES", "MEMORY", "TransportDescriptor"]

#: The words :attr:`TransportDescriptor.carries` may hold (see the module docstring).
CARRIES = frozenset({"values", "requests", "goals", "discovery", "cross-process", "attach"})

#: ``observer_options(connect, mode)``: transport options for a process that reaches a running graph.
ObserverOptions = Callable[[Sequence[str] | None, str | None], dict[str, Any]]


def _carries(value: Any) -> frozenset[str]:
    words = frozenset(value)
    unknown = sorted(words - CARRIES)
    if unknown:
        raise ValueError(f"TransportDescriptor.carries: unknown word(s) {unknown} (known: {sorted(CARRIES)})")
    return words


@define(frozen=True, kw_only=True)
class TransportDescriptor:
    """One transport, as data: how it is built and what it can do (see the module docstring).

    :param name: the name it is resolved by (``Launcher(transport=name)``, ``--transport name``).
    :param factory: ``"module:attribute"`` of what builds it (called with the transport options).
    :param title: how a sentence names it ("Zenoh", "ROS 2").
    :param extra: the pip extra that installs its dependencies (None: none needed).
    :param requires: modules whose absence means that extra is not installed.
    :param in_process: it lives inside one process (nothing outside can reach it).
    :param needs_router: processes meet only through a router (``agentsctl router``) that must run first.
    :param router: a module that runs such a router for a test: ``python -m MODULE ENDPOINT`` listens on
        ``ENDPOINT``, prints ``READY`` once it does and stops on SIGINT (:mod:`agents_core.testing.recipes`
        starts one per test); None: none.
    :param router_environment: the environment variables that make a process of this transport (a recipe
        run unchanged) reach the router at ``endpoint``, on this host only; None: none needed.
    :param rendezvous: where processes meet when nothing else is said (an endpoint), or None.
    :param endpoints: it is reached at endpoints (``--connect`` / ``--listen`` mean something to it).
    :param carries: words of :data:`CARRIES`.
    :param observer_options: options for a process that reaches a running graph (the CLI, the UI's
        attach mode, a test's asker), given endpoints to connect to (None: the rendezvous) and a mode.
    :param listener_options: options for a process other processes reach at ``endpoint``, on this host only.
    :param isolate: set up a private, this-host-only space for a test (ROS 2: a domain of the test's
        own, in ``os.environ``) and return the options both sides then open with; None: nothing needed.
    :param pair: ``"module:function"`` of its conformance pair factory (a context manager yielding two
        transports that reach each other, :mod:`agents_core.testing.pairs`); None: the default.
    :param describe: ``describe(transport) -> str``: where an open transport reaches, for the launch
        report (endpoints, domain); None: nothing beyond the name.
    """

    name: str
    factory: str
    title: str = ""
    extra: str | None = None
    requires: tuple[str, ...] = ()
    in_process: bool = False
    needs_router: bool = False
    router: str | None = None
    router_environment: Callable[[str], dict[str, str]] | None = field(default=None, eq=False)
    rendezvous: str | None = None
    endpoints: bool = False
    carries: frozenset[str] = field(default=frozenset({"values", "requests"}), converter=_carries)
    observer_options: ObserverOptions | None = field(default=None, eq=False)
    listener_options: Callable[[str], dict[str, Any]] | None = field(default=None, eq=False)
    isolate: Callable[[], dict[str, Any]] | None = field(default=None, eq=False)
    describe: Callable[[Any], str] | None = field(default=None, eq=False)
    pair: str | None = None

    @property
    def cross_process(self) -> bool:
        """Components may live in different processes on it."""
        return "cross-process" in self.carries and not self.in_process

    @property
    def attachable(self) -> bool:
        """A process started later can reach a recipe running on it (the CLI, ``agentsctl ui``)."""
        return "attach" in self.carries and not self.in_process

    @property
    def shown_name(self) -> str:
        """:attr:`title`, else :attr:`name`."""
        return self.title or self.name

    def factory_module(self) -> str:
        """The module :attr:`factory` names (what a component process imports to open it)."""
        return self.factory.partition(":")[0].strip()

    def load_factory(self) -> Any:
        """The object :attr:`factory` names (imports its module)."""
        module_name, _, attribute = self.factory.partition(":")
        obj: Any = importlib.import_module(module_name.strip())
        for part in attribute.strip().split("."):
            obj = getattr(obj, part)
        return obj

    def missing_module(self) -> str | None:
        """The first module of :attr:`requires` that is not installed, or None."""
        for module in self.requires:
            if importlib.util.find_spec(module) is None:
                return module
        return None

    def reach(self, connect: Sequence[str] | None = None, mode: str | None = None) -> dict[str, Any]:
        """Options for a process that reaches a running graph on this transport (see :attr:`observer_options`)."""
        if self.observer_options is None:
            return {}
        return dict(self.observer_options(list(connect) if connect else None, mode))

    def listen(self, endpoint: str) -> dict[str, Any]:
        """Options for a process the others reach at ``endpoint`` (see :attr:`listener_options`)."""
        if self.listener_options is None:
            return {}
        return dict(self.listener_options(endpoint))

    def summary(self, transport: Any) -> str:
        """``name`` and, when the descriptor can say it, where ``transport`` reaches: ``"zenoh (peer; ...)"``."""
        detail = self.describe(transport) if self.describe is not None else ""
        return f"{self.name} ({detail})" if detail else self.name

    def to_dict(self) -> dict[str, Any]:
        """The descriptor's data (JSON-like; the functions as whether they are given)."""
        return {"name": self.name, "title": self.shown_name, "factory": self.factory, "extra": self.extra,
                "requires": list(self.requires), "in_process": self.in_process, "needs_router": self.needs_router,
                "rendezvous": self.rendezvous, "endpoints": self.endpoints, "carries": sorted(self.carries),
                "cross_process": self.cross_process, "attachable": self.attachable}


#: The memory transport: one process, every primitive.
MEMORY = TransportDescriptor(
    name="memory", factory="agents_core.transport.memory:MemoryTransport", title="memory", in_process=True,
    carries=frozenset({"values", "requests", "goals", "discovery"}),
    describe=lambda transport: "in this process only")
