"""The few lines every example shares: its command line and a bounded run (copy it along with an example).

Every example takes::

    --transport memory|zenoh|ros2|rmw_zenoh   (default: AGENTS_TRANSPORT, else memory)
    --listen / --connect ENDPOINT    (Zenoh / rmw_zenoh endpoints; default: the transport's rendezvous)
    --namespace NAME                 (run under a robot's namespace, e.g. robot1; default: AGENTS_NAMESPACE)
    --seconds N                      (stop after N seconds)
    --once                           (stop after the example's first complete result)

and otherwise runs until Ctrl-C. It prints ``READY`` on stdout once every component is active
(the tests wait for it) and its results on stdout; the launcher's status lines go to stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

from agents_core import Launcher
from agents_core.transport import describe_transport_kind
from agents_core.transport.registry import known_transports

__all__ = ["SHARED", "make_launcher", "parser", "run", "servers"]

#: The shared model files, photos and audio (``../shared`` beside the checkout, or AGENTS_SHARED).
SHARED = Path(os.environ.get("AGENTS_SHARED", str(Path(__file__).resolve().parents[1].parent / "shared")))


def parser(doc: str | None) -> argparse.ArgumentParser:
    """An argument parser with the options every example takes."""
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--transport", choices=known_transports(), default=None,
                   help="default: AGENTS_TRANSPORT, else memory")
    p.add_argument("--listen", action="append", default=None, metavar="ENDPOINT", help="zenoh: listen here")
    p.add_argument("--connect", action="append", default=None, metavar="ENDPOINT", help="zenoh: connect here")
    p.add_argument("--namespace", default=None, metavar="NAME",
                   help="run under this namespace, e.g. robot1 (default: AGENTS_NAMESPACE, else none)")
    p.add_argument("--seconds", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--once", action="store_true", help="stop after the first complete result")
    return p


def make_launcher(args: argparse.Namespace) -> Launcher:
    """A launcher on the chosen transport (one reached at endpoints, Zenoh or rmw_zenoh: on the given ones, if any)."""
    options: dict[str, object] = {}
    name = args.transport or os.environ.get("AGENTS_TRANSPORT") or "memory"
    if (args.listen or args.connect) and describe_transport_kind(name).endpoints:
        options = {"listen": args.listen or [], "connect": args.connect or []}
    return Launcher(transport=args.transport, transport_options=options, namespace=getattr(args, "namespace", None))


def run(launcher: Launcher, args: argparse.Namespace, *, on_ready: Callable[[Launcher], None] | None = None,
        done: threading.Event | None = None) -> None:
    """``launcher.bringup()`` until Ctrl-C, ``--seconds``, or (with ``--once``) until ``done`` is set.

    ``on_ready(launcher)`` runs on a thread of its own once every component is active (to feed
    the example's inputs, say).
    """
    def watch() -> None:
        start = time.monotonic()
        while not launcher.all_active():
            if args.seconds is not None and time.monotonic() - start > args.seconds:
                launcher.request_stop()
                return
            time.sleep(0.05)
        print("READY", flush=True)
        if on_ready is not None:
            threading.Thread(target=on_ready, args=(launcher,), daemon=True).start()
        while True:
            if args.once and done is not None and done.is_set():
                break
            if args.seconds is not None and time.monotonic() - start >= args.seconds:
                break
            time.sleep(0.05)
        launcher.request_stop()

    threading.Thread(target=watch, daemon=True).start()
    launcher.bringup()


def servers(args: argparse.Namespace, db_path: str) -> contextlib.AbstractContextManager[object]:
    """The Chroma and embedding servers of the vector-database examples: those not answering on
    ``--chroma-port`` / ``--embeddings-port`` are started (and stopped at the end), unless
    ``--no-start-servers`` (see :mod:`agents_core.example_servers`)."""
    if getattr(args, "no_start_servers", False):
        return contextlib.nullcontext()
    from agents_core.example_servers import example_servers  # noqa: PLC0415

    return example_servers(args.chroma_port, args.embeddings_port, db_path=db_path, alias=args.embeddings_model)
