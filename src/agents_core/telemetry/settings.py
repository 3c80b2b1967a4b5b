"""``TelemetrySettings``: where traces and metrics go, from ``Launcher(telemetry=...)`` or the standard variables.

Telemetry is on when either is given:

- the standard OpenTelemetry variables: ``OTEL_EXPORTER_OTLP_ENDPOINT`` (or
  ``OTEL_EXPORTER_OTLP_TRACES_ENDPOINT``) set turns it on in every process of a recipe (the
  launcher's and each component's); ``OTEL_EXPORTER_OTLP_PROTOCOL`` (``http/protobuf``, the
  default, or ``grpc``), ``OTEL_SERVICE_NAME``, ``OTEL_RESOURCE_ATTRIBUTES``, the exporters'
  headers, timeouts and ``OTEL_BSP_*`` / ``OTEL_METRIC_EXPORT_INTERVAL`` are read by the
  OpenTelemetry SDK itself; ``OTEL_SDK_DISABLED=true`` turns it off again;
- ``Launcher(telemetry=...)``: True (the variables, or the SDK's default endpoint), an endpoint
  URL, a mapping of :class:`TelemetrySettings` fields, or a :class:`TelemetrySettings`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from attrs import asdict, define, field

from ..errors import ConfigError

__all__ = ["ENDPOINT_VARS", "PROTOCOLS", "TelemetrySettings", "settings_from_env", "telemetry_settings"]

#: The variables whose presence turns telemetry on.
ENDPOINT_VARS = ("OTEL_EXPORTER_OTLP_ENDPOINT", "OTEL_EXPORTER_OTLP_TRACES_ENDPOINT")
#: The OTLP protocols the ``otel`` extra exports with.
PROTOCOLS = ("http/protobuf", "grpc")


def _protocol(_instance: Any, _attribute: Any, value: str | None) -> None:
    if value is not None and value not in PROTOCOLS:
        raise ConfigError(f"telemetry protocol {value!r} is not one of {', '.join(PROTOCOLS)}")


def _interval(_instance: Any, _attribute: Any, value: float | None) -> None:
    if value is not None and not (isinstance(value, int | float) and 0.05 <= value <= 3600):
        raise ConfigError(f"telemetry metrics_interval_s must be a number of seconds in [0.05, 3600], got {value!r}")


def _ratio(_instance: Any, _attribute: Any, value: float | None) -> None:
    if value is not None and not (isinstance(value, int | float) and not isinstance(value, bool)
                                  and 0.0 <= value <= 1.0):
        raise ConfigError(f"telemetry sample_ratio must be a number in [0, 1], got {value!r}")


@define(frozen=True)
class TelemetrySettings:
    """Where and how a recipe's processes export traces and metrics (None: the standard variables say).

    :param endpoint: the OTLP receiver: ``http://host:4318`` (http/protobuf; ``/v1/traces`` and
        ``/v1/metrics`` are added) or ``http://host:4317`` (grpc).
    :param protocol: ``"http/protobuf"`` or ``"grpc"``.
    :param service_name: the ``service.name`` of every process (default: the component's name in a
        component process, ``agents`` in the launcher's).
    :param metrics_interval_s: how often metrics are exported (the SDK's default is 60 s).
    :param sample_ratio: the share of new traces recorded, 0..1 (None: ``OTEL_TRACES_SAMPLER``, by
        default all); a trace keeps the decision of the process where it started.
    """

    endpoint: str | None = None
    protocol: str | None = field(default=None, validator=_protocol)
    service_name: str | None = None
    metrics_interval_s: float | None = field(default=None, validator=_interval)
    sample_ratio: float | None = field(default=None, validator=_ratio)

    def to_dict(self) -> dict[str, Any]:
        """The fields as plain data (what a component process's spec carries)."""
        return asdict(self)

    def resolved_protocol(self) -> str:
        """The protocol: this one's, else ``OTEL_EXPORTER_OTLP_PROTOCOL``, else http/protobuf."""
        chosen = self.protocol or os.environ.get("OTEL_EXPORTER_OTLP_TRACES_PROTOCOL") or \
            os.environ.get("OTEL_EXPORTER_OTLP_PROTOCOL") or "http/protobuf"
        if chosen not in PROTOCOLS:
            raise ConfigError(f"OTEL_EXPORTER_OTLP_PROTOCOL={chosen!r} is not one of {', '.join(PROTOCOLS)}")
        return chosen


def settings_from_env(environ: Mapping[str, str] | None = None) -> TelemetrySettings | None:
    """Settings when the standard variables turn telemetry on (an endpoint set), else None."""
    env = os.environ if environ is None else environ
    if env.get("OTEL_SDK_DISABLED", "").strip().lower() == "true":
        return None
    if not any(env.get(name, "").strip() for name in ENDPOINT_VARS):
        return None
    return TelemetrySettings()


def telemetry_settings(value: Any) -> TelemetrySettings | None:
    """What ``Launcher(telemetry=value)`` means: None (the variables decide), False (off), True, a URL, a mapping."""
    if value is None:
        return settings_from_env()
    if value is False:
        return None
    if value is True:
        return TelemetrySettings()
    if isinstance(value, TelemetrySettings):
        return value
    if isinstance(value, str):
        return TelemetrySettings(endpoint=value)
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - {"endpoint", "protocol", "service_name", "metrics_interval_s", "sample_ratio"})
        if unknown:
            raise ConfigError(f"telemetry: unknown field(s) {unknown}; the fields are endpoint, protocol, "
                              "service_name, metrics_interval_s, sample_ratio")
        return TelemetrySettings(**value)
    raise ConfigError(f"telemetry must be None, a bool, an endpoint URL, a mapping or TelemetrySettings, "
                      f"got {type(value).__name__}")
