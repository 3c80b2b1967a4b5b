"""What a running recipe tells the person who started it: a few lines on stderr.

:class:`~agents_core.launch.Launcher` reports, without any logging configured::

    agents: transport zenoh (peer; listen tcp/127.0.0.1:7447; multicast scouting off)
      ✓ talker     active  healthy
      ✓ listener   active  healthy
    agents: web UI at http://127.0.0.1:5001/
    agents: 2 component(s) running; press Ctrl-C to stop

and, when something fails, which component and why (``✗ vision  failed to configure: ...``).
The lines are coloured by ``rich`` when it is installed (the ``cli`` extra) and stderr is a
terminal, plain text otherwise. ``Launcher(quiet=True)``, ``AGENTS_QUIET=1`` or a level above
INFO on the ``agents_core`` logger silence them (see :mod:`agents_core.support.console`).

The transport line is the transport's own (its descriptor's ``describe``: Zenoh's mode and
endpoints, ROS 2's domain id and discovery range); this module imports neither zenoh nor rclpy.
"""

from __future__ import annotations

import sys
from typing import Any, TextIO

from ..support.console import quiet_requested

__all__ = ["LaunchReport", "already_reported", "component_row", "describe_transport"]

#: The start failure the current launch's report printed, ``✗ <who> failed to <stage>: <reason>`` with its
#: whitespace folded (so the one error line at exit need not repeat it); a new launch's report clears it.
_last_failure: list[str] = []


def already_reported(text: str) -> bool:
    """Whether the current launch's report printed a start failure whose reason is ``text`` (whitespace folded)."""
    if not _last_failure or not text:
        return False
    reason = _last_failure[-1].partition(": ")[2]  # who and stage have no ": " (names are topic names)
    return " ".join(text.split()) == reason

_WIDTH = 12  # the component-name column; longer names simply push the row


def describe_transport(transport: Any) -> str:
    """One line naming ``transport`` and where it reaches (endpoints, domain, this process): its descriptor's words."""
    from ..transport.registry import descriptor_of  # noqa: PLC0415

    return descriptor_of(transport).summary(transport)


class LaunchReport:
    """The status lines of one launcher run (silent when quiet).

    :param quiet: True silences it; None asks :func:`agents_core.support.console.quiet_requested`.
    :param stream: where the lines go (stderr by default).
    """

    def __init__(self, quiet: bool | None = None, stream: TextIO | None = None) -> None:
        self._stream = stream
        self.quiet = quiet_requested(quiet)
        _last_failure.clear()  # a launch starts: an earlier one's failure (caught, say) is not its reason
        self._console: Any = None
        if not self.quiet and self._out().isatty():
            try:
                from rich.console import Console  # noqa: PLC0415  (rich is optional: the cli extra)
            except ImportError:
                pass
            else:
                self._console = Console(file=self._out(), highlight=False, soft_wrap=True)

    def _out(self) -> TextIO:
        return self._stream if self._stream is not None else sys.stderr

    def _line(self, plain: str, styled: str | None = None) -> None:
        if self.quiet:
            return
        try:
            if self._console is not None:
                self._console.print(styled if styled is not None else plain)
            else:
                out = self._out()
                out.write(plain + "\n")
                out.flush()
        except (OSError, ValueError):  # a closed stderr must not stop the recipe
            pass

    def transport(self, transport: Any) -> None:
        """The transport line (name and endpoints)."""
        text = describe_transport(transport)
        self._line(f"agents: transport {text}", f"[bold]agents:[/] transport [cyan]{_escape(text)}[/]")

    def component(self, name: str, state: str, health: str, note: str = "") -> None:
        """One component's row, as it comes up (or changes)."""
        mark = "✓" if state == "active" and not health.endswith("failure") else "•"
        tail = f"  {note}" if note else ""
        plain = f"  {mark} {name:<{_WIDTH}} {state:<8} {health}{tail}"
        colour = "green" if mark == "✓" else "yellow"
        styled = (f"  [{colour}]{mark}[/] {_escape(name):<{_WIDTH}} {state:<8} {health}"
                  f"{_escape(tail)}")
        self._line(plain, styled)

    def ui(self, url: str) -> None:
        """The web UI's address."""
        self._line(f"agents: web UI at {url}", f"[bold]agents:[/] web UI at [link={url}]{url}[/link]")

    def foxglove(self, url: str) -> None:
        """The Foxglove WebSocket server's address."""
        self._line(f"agents: Foxglove at {url}")

    def line(self, text: str) -> None:
        """One more line of the launch (an attachment's address, say)."""
        self._line(text)

    def running(self, count: int) -> None:
        """Everything is up: how many components, and how to stop."""
        text = f"{count} component(s) running; press Ctrl-C to stop"
        self._line(f"agents: {text}", f"[bold]agents:[/] [green]{text}[/]")

    def failed(self, name: str | None, stage: str, reason: BaseException | str) -> None:
        """A failure while starting: which component (if one), at which stage, and why."""
        why = str(reason)
        if isinstance(reason, BaseException):
            why = why or type(reason).__name__
        who = f"{name:<{_WIDTH}} " if name else ""
        plain = f"  ✗ {who}failed to {stage}: {why}"
        if not self.quiet:
            _last_failure[:] = [" ".join(plain.split())]
            from .short_errors import one_line_if_uncaught  # noqa: PLC0415  (it imports this module)

            one_line_if_uncaught()  # `with launcher:` in a script: this line, not the traceback, if uncaught
        self._line(plain, f"  [red]✗[/] {_escape(who)}failed to {stage}: [red]{_escape(why)}[/]")


def _escape(text: str) -> str:
    """``text`` with rich's markup brackets escaped."""
    return text.replace("[", r"\[")


def component_row(component: Any) -> tuple[str, str, str]:
    """(name, state, health) of an in-process component, in the words the report uses."""
    state = getattr(component.lifecycle_state, "value", str(component.lifecycle_state))
    health = component.health_status.name.lower()
    return component.component_name, str(state), health
