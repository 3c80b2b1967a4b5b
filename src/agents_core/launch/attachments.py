"""What a run starts beside its components: one table of attachments (web UI, Foxglove, recording, ...).

An attachment is named in a recipe with its options (``Recipe.attachments``: ``launcher.enable_ui()``
puts ``"ui"`` there, ``enable_foxglove()`` ``"foxglove"``, ``record()`` ``"record"``). When the run
starts, each one named is started from :data:`ATTACHMENTS`, in the table's order: the ``before``
ones once the transport is open and before the components configure (a recording must see the
first values), the ``after`` ones once every component is active (a UI shows them running). They
stop in the reverse order, the ``after`` ones first, the ``before`` ones just before the transport
closes. A package adds its own with :func:`register_attachment` (this wave's MCP server does).

An attachment's ``start(options, components, transport)`` imports what it needs itself (each is an
optional extra) and returns a handle with ``stop()`` (and ``url``, for ``announce``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal

import attrs

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..transport.contract import Transport
    from .report import LaunchReport

__all__ = ["ATTACHMENTS", "AttachmentKind", "RunningAttachments", "foxglove_options", "record_options",
           "register_attachment", "ui_options"]

logger = logging.getLogger(__name__)

#: ``start(options, components, transport) -> handle`` (the handle has ``stop()``).
Starter = Callable[[Mapping[str, Any], Sequence["Component"], "Transport"], Any]


@attrs.frozen
class AttachmentKind:
    """One kind of attachment: when it starts, how, and what the launch report says of it.

    :param stage: the words of a failure line: ``failed to <stage>``.
    """

    name: str
    phase: Literal["before", "after"]
    start: Starter
    stage: str
    announce: Callable[[LaunchReport, Any], None] | None = None


def _start_ui(options: Mapping[str, Any], components: Sequence[Component], transport: Transport) -> Any:
    from ..ui.launch import start_ui  # noqa: PLC0415  (the UI is optional)

    return start_ui(components, transport, **options)


def _start_foxglove(options: Mapping[str, Any], components: Sequence[Component], transport: Transport) -> Any:
    from ..foxglove.launch import start_foxglove  # noqa: PLC0415  (Foxglove is optional)

    return start_foxglove(components, transport, **options)


def _start_recording(options: Mapping[str, Any], components: Sequence[Component], transport: Transport) -> Any:
    recording = options["recording"]  # made by Launcher.record(), which returned it to the recipe
    recording.start(components, transport)
    return recording


#: Every attachment a run can start, by name, in start order (see the module docstring).
ATTACHMENTS: dict[str, AttachmentKind] = {
    "record": AttachmentKind("record", "before", _start_recording, "start the recording"),
    "ui": AttachmentKind("ui", "after", _start_ui, "start the web UI",
                         lambda report, server: report.ui(str(server.url))),
    "foxglove": AttachmentKind("foxglove", "after", _start_foxglove, "start the Foxglove server",
                               lambda report, bridge: report.foxglove(str(bridge.url))),
}


def ui_options(inputs: Sequence[Any] | None, outputs: Sequence[Any] | None, port: int,
               **settings: Any) -> dict[str, Any]:
    """The ``"ui"`` attachment's options (``Launcher.enable_ui``): the settings checked now."""
    from ..ui.settings import UISettings  # noqa: PLC0415  (the UI is optional)

    return {"inputs": inputs, "outputs": outputs, "settings": UISettings(port=port, **settings)}


def foxglove_options(topics: Sequence[Any] | None, port: int, **settings: Any) -> dict[str, Any]:
    """The ``"foxglove"`` attachment's options (``Launcher.enable_foxglove``): the settings checked now."""
    from ..foxglove.settings import FoxgloveSettings  # noqa: PLC0415  (Foxglove is optional)

    return {"topics": topics, "settings": FoxgloveSettings(port=port, **settings)}


def record_options(path: Any, **options: Any) -> dict[str, Any]:
    """The ``"record"`` attachment's options (``Launcher.record``); its ``recording`` is what ``record`` returns."""
    from ..recording.launch import RecipeRecording  # noqa: PLC0415  (recording is optional)

    return {"path": str(path), **options, "recording": RecipeRecording(path, **options)}


def register_attachment(kind: AttachmentKind) -> AttachmentKind:
    """Add (or replace) an attachment kind; a recipe names it in ``Recipe.attachments``."""
    if kind.phase not in ("before", "after"):
        raise ConfigError(f"attachment {kind.name!r}: phase must be 'before' or 'after', got {kind.phase!r}")
    ATTACHMENTS[kind.name] = kind
    return kind


class RunningAttachments:
    """The attachments of one run: started by phase, stopped in reverse; the handles by name."""

    def __init__(self, wanted: Mapping[str, Mapping[str, Any]]) -> None:
        unknown = sorted(set(wanted) - set(ATTACHMENTS))
        if unknown:
            raise ConfigError(f"unknown attachment(s) {unknown} (known: {sorted(ATTACHMENTS)})")
        self._wanted = dict(wanted)
        self._running: list[tuple[AttachmentKind, Any]] = []

    def get(self, name: str) -> Any:
        """The running handle of attachment ``name``, or None."""
        return next((handle for kind, handle in self._running if kind.name == name), None)

    def start(self, phase: str, components: Sequence[Component], transport: Transport,
              report: LaunchReport, failing: list[tuple[str | None, str]]) -> None:
        """Start the attachments of ``phase``; ``failing[0]`` says which one, should it fail."""
        for name, kind in ATTACHMENTS.items():
            if kind.phase != phase or name not in self._wanted:
                continue
            failing[0] = (None, kind.stage)
            handle = kind.start(self._wanted[name], components, transport)
            self._running.append((kind, handle))
            if kind.announce is not None:
                kind.announce(report, handle)

    def stop(self, phase: str) -> None:
        """Stop the running attachments of ``phase``, newest first (a failing stop is logged, not raised)."""
        keep = []
        for kind, handle in reversed(self._running):
            if kind.phase != phase:
                keep.append((kind, handle))
                continue
            try:
                handle.stop()
            except Exception as exc:
                logger.warning("the %s attachment did not stop cleanly: %s", kind.name, exc)
        self._running = list(reversed(keep))
