"""The ``agentsctl`` command tree: ``run``, ``recipe``, ``topics``, ``components``, ``call``, ``ui``, ``router``,
``record``, ``play``, ``episodes``, ``eval``, ``foxglove``."""

from __future__ import annotations

import os
import runpy
import sys
from pathlib import Path
from typing import Annotated

import typer

from ..errors import AgentsError, ConfigError
from ..support.console import QUIET_ENV_VAR
from ..support.install_hint import install_hint
from ..transport.registry import TRANSPORT_ENV_VAR, available_transports
from . import components, episodes, eval_run, recipe, recording, top, topics  # noqa: F401 - eval_run registers `eval run`
from . import mcp as mcp_cli
from .connection import attachable_transports, fail, one_line_errors
from .evals import eval_app
from .foxglove import foxglove
from .output import print_json, say

__all__ = ["app"]

#: Read by ``ZenohTransport`` for options a recipe does not give (see agents_zenoh.transport).
ZENOH_CONNECT_ENV_VAR = "AGENTS_ZENOH_CONNECT"
ZENOH_MODE_ENV_VAR = "AGENTS_ZENOH_MODE"

app = typer.Typer(name="agentsctl", no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                  help="Run agents_core recipes and inspect a live graph on Zenoh or ROS 2.")
app.add_typer(topics.app, name="topics")
app.add_typer(components.app, name="components")
app.add_typer(recipe.app, name="recipe")
app.add_typer(eval_app, name="eval")
app.add_typer(episodes.app, name="episodes")
app.command("call")(components.call)
app.command("record")(recording.record)
app.command("play")(recording.play)
app.command("foxglove")(foxglove)
app.command("mcp")(mcp_cli.mcp)
app.command("approve")(mcp_cli.approve)
app.command("deny")(mcp_cli.deny)
app.command("top")(top.top)


@app.command("run", context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
def run(ctx: typer.Context,
        recipe: Annotated[Path, typer.Argument(help="the recipe file, run as __main__")],
        transport: Annotated[str | None, typer.Option(
            "--transport", "-t", help="memory, zenoh, ros2 or an installed one (sets AGENTS_TRANSPORT for "
                                      "Launcher())")] = None,
        connect: Annotated[list[str] | None, typer.Option(
            "--connect", "-c", help="Zenoh endpoint(s) to connect to, e.g. a router; makes the recipe a client "
                                    "unless --mode says otherwise")] = None,
        mode: Annotated[str | None, typer.Option("--mode", help="Zenoh session mode: peer, client or router")] = None,
        namespace: Annotated[str | None, typer.Option(
            "--namespace", "-N", help="run the recipe under this namespace, e.g. robot1 (sets AGENTS_NAMESPACE "
                                      "for Launcher())")] = None,
        quiet: Annotated[bool, typer.Option(
            "--quiet", "-q", help="no status lines on stderr (sets AGENTS_QUIET=1)")] = False,
        debug: Annotated[bool, typer.Option(
            "--debug", help="the full traceback when the recipe fails to start (sets AGENTS_DEBUG=1)")] = False,
        ) -> None:
    """Run a recipe file as __main__ (extra arguments go to the recipe's sys.argv).

    The recipe's launcher prints its transport, components, UI address and how to stop on stderr.
    """
    if not recipe.is_file():
        raise fail(f"recipe {str(recipe)!r} is not a file")
    if transport is not None:
        if transport.strip().lower() not in available_transports():
            raise fail(f"unknown transport {transport!r}; use {', '.join(available_transports())}")
        os.environ[TRANSPORT_ENV_VAR] = transport.strip().lower()
    if connect:
        os.environ[ZENOH_CONNECT_ENV_VAR] = ",".join(connect)
    if mode is not None:
        if mode not in ("peer", "client", "router"):
            raise fail(f"unknown Zenoh mode {mode!r}; use peer, client or router")
        os.environ[ZENOH_MODE_ENV_VAR] = mode
    if namespace is not None:
        from ..transport.namespace import NAMESPACE_ENV_VAR, validate_namespace  # noqa: PLC0415

        try:
            os.environ[NAMESPACE_ENV_VAR] = validate_namespace(namespace, "--namespace")
        except ConfigError as exc:
            raise fail(str(exc)) from None
    if quiet:
        os.environ[QUIET_ENV_VAR] = "1"
    if debug:
        os.environ["AGENTS_DEBUG"] = "1"  # agents_core.launch.short_errors
    path = str(recipe.resolve())
    sys.argv = [path, *ctx.args]
    # The recipe's own imports (a module beside it) work as with `python recipe.py`.
    sys.path.insert(0, str(recipe.resolve().parent))
    runpy.run_path(path, run_name="__main__")


@app.command("ui", context_settings={"allow_extra_args": True, "ignore_unknown_options": True,
                                     "help_option_names": []})
def ui(ctx: typer.Context) -> None:
    """Serve the web UI for a recipe running elsewhere (Zenoh or ROS 2); 'agentsctl ui --help' lists options."""
    args = list(ctx.args)
    if "--transport" in args and args.index("--transport") + 1 < len(args):
        name = args[args.index("--transport") + 1].strip().lower()
        if name not in attachable_transports():
            raise fail(f"the UI attaches over {' or '.join(attachable_transports())}, not {name!r} (a recipe on an "
                       "in-process transport enables its UI itself: launcher.enable_ui())")
    try:
        from ..ui.attach import main as attach_main  # noqa: PLC0415 - needs the ui extra
    except ImportError as exc:
        raise fail(f"the web UI needs the 'ui' extra ({exc}); {install_hint('ui')}") from None
    try:
        code = attach_main(args)
    except (AgentsError, OSError) as exc:
        raise fail(str(exc) or type(exc).__name__) from None
    raise typer.Exit(code)


@app.command("router")
@one_line_errors
def router(listen: Annotated[list[str], typer.Option("--listen", "-l", help="endpoint to listen on, e.g. "
                                                     "tcp/0.0.0.0:7447 (repeatable)")],
           connect: Annotated[list[str] | None,
                              typer.Option("--connect", "-c", help="another router to join, forming a mesh, e.g. "
                                                                   "tcp/10.0.0.2:7447 (repeatable)")] = None,
           json_out: Annotated[bool, typer.Option("--json", help="print the ready and peers lines as JSON")] = False,
           ) -> None:
    """Run a Zenoh router (for recipes on several machines) until Ctrl-C or SIGTERM.

    With --connect it joins other routers (a mesh: clients of any router reach the others'); it prints
    what it is linked to (routers, peers, clients) each time that changes.
    """
    try:
        from agents_zenoh.router import serve_router  # noqa: PLC0415 - needs the zenoh extra
    except ImportError as exc:
        raise ConfigError(f"the router needs the 'zenoh' extra ({exc}); {install_hint('zenoh')}") from None

    def ready(session: object) -> None:
        zid = str(session.info.zid())  # type: ignore[attr-defined]
        if json_out:
            print_json({"router": zid, "listen": listen, "connect": connect or []})
        else:
            say(f"Zenoh router {zid} listening on {', '.join(listen)}")
        sys.stdout.flush()

    def peers(linked: list[dict[str, object]]) -> None:
        if json_out:
            print_json({"peers": linked})
        else:
            say("peers: " + (", ".join(f"{p['kind']} {p['zid']}" for p in linked) or "none"))
        sys.stdout.flush()

    serve_router(list(listen), list(connect or []), on_ready=ready, on_peers=peers)

