"""The UI attached to a recipe running elsewhere (another process or machine), on Zenoh or ROS 2.

``python -m agents_core.ui.attach --transport zenoh --connect tcp/127.0.0.1:7447 [--port 5001]``
opens its own transport session, finds the recipe's components (``transport.discover()``, or
``--component NAME`` repeated), asks each one's ``<name>/describe`` service for its inputs,
outputs and actions, and serves the UI until Ctrl+C. :func:`main` is meant to become the CLI's
``agentsctl ui`` subcommand. A token, when binding off loopback, comes from ``AGENTS_UI_TOKEN``
(never from the command line).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..topics import Topic
from .recipe_view import RemoteRecipe
from .settings import UISettings

if TYPE_CHECKING:
    from ..transport.contract import Transport
    from .server import UIServer

__all__ = ["attach", "main", "session_options"]


def attach(transport: Transport, *, components: Sequence[str] | None = None,
           inputs: Sequence[Topic] | None = None, outputs: Sequence[Topic] | None = None,
           settings: UISettings | None = None, timeout: float = 2.0) -> UIServer:
    """Start a UI for the components that ``transport`` reaches (all it discovers, or ``components``).

    ``inputs`` / ``outputs`` default to what the components describe (see
    :func:`~.recipe_view.default_topics`). The caller keeps and closes ``transport``; stop the
    returned server first.
    """
    from .server import UIServer  # noqa: PLC0415  (Starlette and uvicorn, only when a UI starts)

    view = RemoteRecipe(transport, components, timeout=timeout)
    return UIServer(view, transport, inputs=inputs, outputs=outputs, settings=settings).start()


def session_options(connect: Sequence[str], mode: str = "peer") -> dict[str, Any]:
    """The UI's Zenoh options: with ``connect``, a ``mode`` session of those endpoints; without, what every other
    ``agentsctl`` command opens (the host's recipes: the loopback rendezvous or ``AGENTS_ZENOH_*``), never an
    isolated session."""
    if connect:
        return {"mode": mode, "connect": list(connect), "listen": []}
    return {"zenoh_options": {"scouting/delay": 100}}  # as agents_core.cli.connection.zenoh_options(None)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="agentsctl ui", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", default=None,
                        help="zenoh or ros2 (default: AGENTS_TRANSPORT, else zenoh, as every agentsctl command)")
    parser.add_argument("--connect", action="append", default=[],
                        help="Zenoh endpoint to connect to (repeat); none: the recipes on this host (the loopback "
                             "rendezvous, or AGENTS_ZENOH_CONNECT), as every agentsctl command")
    parser.add_argument("--mode", default="peer", help="Zenoh session mode with --connect (peer or client)")
    parser.add_argument("--component", action="append", default=None, help="show only these components (repeat)")
    parser.add_argument("--host", default="127.0.0.1", help="bind address (off loopback needs AGENTS_UI_TOKEN)")
    parser.add_argument("--port", type=int, default=5001)
    parser.add_argument("--tls-certfile", default=None, help="PEM certificate: serve HTTPS (with --tls-keyfile)")
    parser.add_argument("--tls-keyfile", default=None, help="the certificate's PEM private key")
    parser.add_argument("--seconds", type=float, default=0.0, help="stop after this long (0: until Ctrl+C)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the attached UI until SIGINT / SIGTERM (or ``--seconds``)."""
    args = _parser().parse_args(argv)
    from ..transport.registry import TRANSPORT_ENV_VAR, resolve_transport  # noqa: PLC0415

    name = (args.transport or os.environ.get(TRANSPORT_ENV_VAR, "").strip() or "zenoh").strip().lower()
    options: dict[str, Any] = {}
    if name == "zenoh":
        options = session_options(args.connect, args.mode)
    transport = resolve_transport(name, **options)
    try:
        settings = UISettings(host=args.host, port=args.port, tls_certfile=args.tls_certfile,
                              tls_keyfile=args.tls_keyfile)
        server = attach(transport, components=args.component, settings=settings)
        stop = threading.Event()
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda *_: stop.set())
        print(f"UI for {server.state.hub.components} over {transport.name}: {server.url}", flush=True)
        try:
            stop.wait(args.seconds if args.seconds > 0 else None)
        finally:
            server.stop()
    finally:
        transport.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
