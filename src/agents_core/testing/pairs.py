"""Transport pairs for the conformance suite: how each installed transport is opened twice.

A *pair factory* is a callable with no arguments that returns a context manager yielding
``(a, b)``: two transports that reach each other (``a`` publishes, serves and declares; ``b``
subscribes, requests and observes). Leaving the context closes both.

Where a transport's pair factory comes from, first match wins:

1. the built-in transports: :func:`memory_pair`, :func:`zenoh_pair`, :func:`ros2_pair`;
2. the one the transport's descriptor names (:attr:`~agents_core.transport.descriptor.TransportDescriptor.pair`);
3. an entry point of the :data:`PAIR_ENTRY_POINT_GROUP` group with the transport's name::

       [project.entry-points."agents_core.conformance_pairs"]
       mqtt = "my_package.testing:mqtt_pair"

4. otherwise :func:`shared_instance_pair`: **one** instance, made with
   ``resolve_transport(name)``, used as both ``a`` and ``b`` (as the memory transport is). Any
   transport reaches itself, so the default never fails for want of discovery; a transport that
   spans sessions or processes should register a pair factory of its own so that the suite also
   checks two independent instances.

Everything networked stays on this host: Zenoh peers listen and connect on explicit
``tcp/127.0.0.1`` ports with multicast scouting off; ROS 2 discovery is limited to
``LOCALHOST`` in a domain derived from the process id. Middleware is imported inside the
factories, so importing this module needs neither zenoh nor rclpy.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import os
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from functools import partial
from importlib.metadata import entry_points
from typing import TYPE_CHECKING

from ..errors import TransportNotAvailableError
from ..transport.memory import MemoryTransport
from ..transport.registry import available_transports, describe_transport_kind, resolve_transport
from .helpers import free_tcp_port

if TYPE_CHECKING:
    from ..transport.contract import Transport

__all__ = [
    "BUILTIN_PAIRS",
    "PAIR_ENTRY_POINT_GROUP",
    "PairFactory",
    "conformance_transports",
    "memory_pair",
    "missing_requirement",
    "pair_factory",
    "private_ros_environment",
    "ros2_pair",
    "shared_instance_pair",
    "skip_unless_installed",
    "zenoh_pair",
]

#: Entry-point group: transport name -> "module:function" returning a context manager yielding ``(a, b)``.
PAIR_ENTRY_POINT_GROUP = "agents_core.conformance_pairs"

PairFactory = Callable[[], AbstractContextManager[tuple["Transport", "Transport"]]]

# Zenoh's open() waits up to scouting/delay (500 ms by default) for its connections; on
# loopback they take a few ms, so a short delay saves half a second per test.
_FAST_OPEN = {"scouting/delay": 50}

@contextlib.contextmanager
def memory_pair() -> Iterator[tuple[Transport, Transport]]:
    """Yield ``(t, t)``: one memory transport used from both sides; closed on exit."""
    transport = MemoryTransport()
    try:
        yield transport, transport
    finally:
        transport.close()


@contextlib.contextmanager
def zenoh_pair() -> Iterator[tuple[Transport, Transport]]:
    """Yield ``(a, b)``: two Zenoh peers on loopback, ``b`` connected to ``a``; both closed on exit."""
    from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415 - needs the zenoh extra

    port_a = free_tcp_port()
    with _opened_pair(
        lambda: ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port_a}"], connect=[],
                               multicast_scouting=False, zenoh_options=_FAST_OPEN),
        lambda: ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{free_tcp_port()}"],
                               connect=[f"tcp/127.0.0.1:{port_a}"], multicast_scouting=False,
                               zenoh_options=_FAST_OPEN),
    ) as pair:
        yield pair


@contextlib.contextmanager
def _opened_pair(open_a: Callable[[], Transport], open_b: Callable[[], Transport]) -> Iterator[tuple[Transport,
                                                                                                    Transport]]:
    """Open ``a`` then ``b``; whatever was opened is closed on exit (or when ``b`` fails to open)."""
    a = open_a()
    try:
        b = open_b()
    except BaseException:
        a.close()
        raise
    try:
        yield a, b
    finally:
        b.close()
        a.close()


def private_ros_environment() -> int:
    """Keep ROS 2 discovery on this host, in a domain of this process's own; returns the domain id.

    Must run before the first ROS context of the process is initialised (rcl reads both there).
    """
    domain_id = 1 + os.getpid() % 100
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(domain_id)
    return domain_id


@contextlib.contextmanager
def ros2_pair() -> Iterator[tuple[Transport, Transport]]:
    """Yield ``(a, b)``: two ROS 2 transports with a DDS participant each; both closed on exit.

    Each has a ROS context of its own, so ``a`` and ``b`` discover each other as two processes would.
    """
    from agents_ros2.transport import Ros2Transport  # noqa: PLC0415 - needs the ros2 extra

    domain_id = private_ros_environment()
    with _opened_pair(lambda: Ros2Transport(domain_id=domain_id), lambda: Ros2Transport(domain_id=domain_id)) as pair:
        yield pair


@contextlib.contextmanager
def shared_instance_pair(name: str) -> Iterator[tuple[Transport, Transport]]:
    """Yield ``(t, t)``: one ``resolve_transport(name)`` used from both sides; closed on exit.

    The default for a third-party transport that registers no pair factory.
    """
    transport = resolve_transport(name)
    try:
        yield transport, transport
    finally:
        transport.close()


#: The built-in transports' pair factories, by transport name.
BUILTIN_PAIRS: dict[str, PairFactory] = {"memory": memory_pair, "zenoh": zenoh_pair, "ros2": ros2_pair}


def _pair_entry_points() -> dict[str, str]:
    """Pair factories installed through :data:`PAIR_ENTRY_POINT_GROUP`: name -> "module:function"."""
    return {ep.name: ep.value for ep in entry_points(group=PAIR_ENTRY_POINT_GROUP)}


def conformance_transports() -> list[str]:
    """Every transport the suite runs on: built-in, ``agents_core.transports`` and pair entry points."""
    return sorted(set(available_transports()) | set(BUILTIN_PAIRS) | set(_pair_entry_points()))


def missing_requirement(name: str) -> str | None:
    """Why a built-in transport cannot run here (its extra is not installed), or None.

    Only a missing module counts: a broken installation must fail the suite, not skip it.
    """
    try:
        descriptor = describe_transport_kind(name)
    except TransportNotAvailableError:
        return None  # resolving it says what is wrong
    module = descriptor.missing_module()
    if module is None:
        return None
    extra = descriptor.extra
    return (f"{name} transport not available here: the '{extra}' extra is not installed "
            f"(no module {module!r}); pip install 'agents-core[{extra}]'")


def skip_unless_installed(transport: str, *modules: str, reason: str | None = None) -> None:
    """Skip the calling test when ``transport``'s extra, or one of ``modules``, is not installed.

    ``transport`` is a built-in transport's name (``"zenoh"``, ``"ros2"``), or ``""`` to check
    ``modules`` only. The skip's reason names what is missing (``reason``, if given, says it
    instead: how to install it, say); a module that is installed but broken is left to fail the test.
    """
    import pytest  # noqa: PLC0415 - importing this module must not need pytest

    why = missing_requirement(transport) if transport else None
    absent = [m for m in modules if importlib.util.find_spec(m) is None]
    if why is None and absent:
        why = f"{transport or 'this test'} needs {', '.join(absent)}, which is not installed"
    if why is not None:
        pytest.skip(reason or why)


def pair_factory(name: str) -> PairFactory:
    """The pair factory for transport ``name`` (see the module docstring for the order)."""
    if name in BUILTIN_PAIRS:
        return BUILTIN_PAIRS[name]
    with contextlib.suppress(TransportNotAvailableError):
        named = describe_transport_kind(name).pair
        if named:
            module, _, attribute = named.partition(":")
            return getattr(importlib.import_module(module), attribute)  # type: ignore[no-any-return]
    for ep in entry_points(group=PAIR_ENTRY_POINT_GROUP):
        if ep.name == name:
            factory = ep.load()
            if not callable(factory):
                raise TypeError(f"pair entry point {name!r} ({ep.value}) is not callable")
            return factory  # type: ignore[no-any-return]
    return partial(shared_instance_pair, name)
