"""The UI attached to a recipe running elsewhere (another process or machine), on Zenoh or ROS 2.

``python -m agents_core.ui.attach --transport zenoh --connect tcp/127.0.0.1:7447 [--port 5001]``
opens its own transport session, finds the recipe's components (``transport.discover()``, or
``--component NAME`` repeated), asks each one's ``<name>/describe`` service for its inputs,
outputs and actions, and serves the UI until Ctrl+C. Any transport whose descriptor says
``attach`` works; the options come from the descriptor (``reach``). :func:`main` is meant to become the CLI's
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

from ..errors import ConfigError
from ..topics import Topic
from .recipe_view import RemoteRecipe
from .settings import UISettings

if TYPE_CHECKING:
    from ..transport.contract import Transport
    from .server import UIServer

__all__ = ["attach", "main"]


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


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="agentsctl ui", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", default=None,
                        help="a cross-process transport: zenoh, ros2 or an installed one (default: zenoh)")
    parser.add_argument("--connect", action="append", default=[],
                        help="endpoint to connect to, for a transport reached at endpoints such as Zenoh (repeat)")
    parser.add_argument("--mode", default="peer", help="session mode, where the transport has one (Zenoh: peer "
                                                       "or client)")
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
    from ..transport.registry import (  # noqa: PLC0415
        DEFAULT_CROSS_PROCESS,
        TRANSPORT_ENV_VAR,
        describe_transport_kind,
        resolve_transport,
    )

    name = args.transport or os.environ.get(TRANSPORT_ENV_VAR, "").strip() or DEFAULT_CROSS_PROCESS
    descriptor = describe_transport_kind(name)
    if not descriptor.attachable:
        raise ConfigError(f"the UI cannot attach over the {descriptor.name} transport: it lives inside one "
                          "process (the recipe enables its UI itself: launcher.enable_ui())")
    if args.connect and not descriptor.endpoints:
        raise ConfigError(f"--connect: the {descriptor.name} transport is not reached at endpoints")
    options: dict[str, Any] = descriptor.reach(args.connect, args.mode) if descriptor.endpoints else descriptor.reach()
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
