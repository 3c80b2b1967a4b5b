"""Traces and metrics on OpenTelemetry (the ``otel`` extra): off by default, at no import cost.

Turn it on with the standard variables (``OTEL_EXPORTER_OTLP_ENDPOINT=http://127.0.0.1:4318``
is enough, in every process of a recipe) or ``Launcher(telemetry=...)``
(:mod:`agents_core.telemetry.settings`). What is traced and measured: :mod:`agents_core.telemetry.otel`.
While it is off, nothing of OpenTelemetry is imported: the instrumented paths read one module
attribute (:data:`agents_core.telemetry.switch.hooks`) and go on.

:func:`configure` turns it on in this process (idempotent); :func:`shutdown` exports what is
left and turns it off (it also runs at interpreter exit).
"""

from __future__ import annotations

import atexit
import logging
import threading
from typing import TYPE_CHECKING, Any

from ..support.install_hint import install_hint
from ..support.lazy import lazy_facade
from . import switch
from .settings import TelemetrySettings as TelemetrySettings
from .settings import settings_from_env as settings_from_env
from .settings import telemetry_settings as telemetry_settings

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__, own=("active_settings", "configure", "configure_from", "enabled",
                                                      "flush", "shutdown"))

logger = logging.getLogger(__name__)
_lock = threading.Lock()
_hooks: Any = None
_settings: TelemetrySettings | None = None
_warned = False


def enabled() -> bool:
    """Whether telemetry is on in this process."""
    return switch.hooks is not None


def active_settings() -> TelemetrySettings | None:
    """The settings telemetry was turned on with in this process (None while off): a launcher's
    component processes get them in their spec."""
    return _settings if _hooks is not None else None


def configure(settings: TelemetrySettings | None, service_name: str = "agents", component: str | None = None) -> bool:
    """Turn telemetry on in this process with ``settings`` (None: nothing); whether it is on after.

    Without the ``otel`` extra it stays off, with one WARNING naming the install line. Already on:
    nothing changes (the first settings stay).
    """
    global _hooks, _settings, _warned  # noqa: PLW0603  # one set of providers per process
    if settings is None:
        return enabled()
    with _lock:
        if _hooks is not None:
            return True
        try:
            from .otel import OtelHooks  # noqa: PLC0415  (the otel extra)
        except ImportError as exc:
            if not _warned:
                _warned = True
                logger.warning("telemetry asked for, but OpenTelemetry is not installed (%s): %s",
                               install_hint("otel"), exc)
            return False
        _hooks = OtelHooks(settings, service_name, component)
        _settings = settings
        switch.hooks = _hooks
    atexit.register(shutdown)
    return True


def configure_from(value: Any, service_name: str = "agents", component: str | None = None) -> bool:
    """:func:`configure` with what ``Launcher(telemetry=value)`` means (:func:`telemetry_settings`)."""
    return configure(telemetry_settings(value), service_name, component)


def flush(timeout_s: float = 2.0) -> None:
    """Export the spans and metrics buffered now (nothing while off)."""
    hooks = _hooks
    if hooks is not None:
        hooks.flush(timeout_s)


def shutdown() -> None:
    """Export what is left and turn telemetry off in this process; idempotent."""
    global _hooks
    with _lock:
        hooks, _hooks = _hooks, None
        switch.hooks = None
    if hooks is not None:
        try:
            hooks.shutdown()
        except Exception as exc:  # an exporter that cannot reach its receiver at exit
            logger.debug("telemetry shutdown: %s", exc)
