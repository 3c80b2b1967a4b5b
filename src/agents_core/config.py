"""Configuration classes: attrs data with validators, loadable from YAML, TOML or JSON files.

Every config is an attrs class declared with ``@define(kw_only=True)``; assigning a field later
runs its validator again, so a parameter update can never leave a config invalid.

A config file holds either the fields directly or one section per component name::

    # agents.yaml
    llm:
      warmup: true
      execution_queue_depth: 4
"""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, TypeVar

import attrs
from attrs import define, field

from . import base_validators
from .errors import ConfigError
from .support.checked_attrs import CheckedFieldsMeta, name_hints
from .support.lazy import lazy_facade

#: Field metadata of settings read only at configure (model files, local model placement):
#: ``set_param`` refuses them on a configured component instead of storing a value that
#: would not take effect.
AT_CONFIGURE: dict[str, Any] = {"applies": "at configure"}


def configure_time_fields(config: Any) -> set[str]:
    """Names of the fields of ``config`` that take effect only at configure."""
    return {a.name for a in attrs.fields(type(config)) if a.metadata.get("applies") == "at configure"}

T = TypeVar("T", bound="BaseAttrs")


def _parse(text: str, suffix: str, source: Path) -> Any:
    """The data of a config file's text. The parsers are imported here, when a file is read: the
    components import this module, and a process configured in code should not load PyYAML."""
    if suffix in (".yaml", ".yml"):
        import yaml  # noqa: PLC0415

        try:
            return yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise ConfigError(f"config file {source} is not valid YAML: {exc}") from exc
    if suffix == ".toml":
        if sys.version_info >= (3, 11):
            import tomllib  # noqa: PLC0415
        else:  # pragma: no cover - exercised on Python 3.10 only
            import tomli as tomllib  # noqa: PLC0415
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"config file {source} is not valid TOML: {exc}") from exc
    if suffix == ".json":
        try:
            return json.loads(text)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"config file {source} is not valid JSON: {exc}") from exc
    raise ConfigError(f"config file {source}: unknown format {suffix!r} (use .yaml, .yml, .toml or .json)")


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read a YAML (.yaml/.yml), TOML (.toml) or JSON (.json) file into a dict."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read config file {p}: {exc}") from exc
    data = _parse(text, p.suffix.lower(), p)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"config file {p} must hold a mapping at the top, got {type(data).__name__}")
    return data


@define(kw_only=True)
class BaseAttrs(metaclass=CheckedFieldsMeta):
    """Base of configs and model descriptions: dict and file round trips with clear errors."""

    def asdict(self) -> dict[str, Any]:
        """The fields as a plain dict (nested attrs values become dicts too)."""
        return attrs.asdict(self, recurse=True)

    @classmethod
    def from_dict(cls: type[T], data: dict[str, Any], *, source: str = "") -> T:
        """Build from a dict, rejecting keys that are not fields (a typo must not pass silently)."""
        names = {a.alias for a in attrs.fields(cls) if a.init}
        unknown = sorted(set(data) - names)
        where = f" in {source}" if source else ""
        if unknown:
            raise ConfigError(f"{cls.__name__}: unknown field(s) {unknown}{where} ({name_hints(unknown, names)}); "
                              f"known fields: {sorted(names)}")
        try:
            return cls(**data)
        except (TypeError, ConfigError) as exc:
            raise ConfigError(f"{cls.__name__}{where}: {exc}") from exc

    @classmethod
    def from_file(cls: type[T], path: str | Path, section: str | None = None) -> T:
        """Load from a YAML / TOML / JSON file, from ``section`` when the file has one by that name."""
        data = load_config_file(path)
        if section is not None and isinstance(data.get(section), dict):
            data = data[section]
        return cls.from_dict(data, source=str(path))

    def update(self, **values: Any) -> None:
        """Set several fields, validating each; on an invalid value nothing is changed."""
        trial = copy.deepcopy(self)
        known = [a.name for a in attrs.fields(type(self)) if not a.name.startswith("_")]
        for name, value in values.items():
            if not hasattr(trial, name) or name.startswith("_"):
                raise ConfigError(f"{type(self).__name__} has no parameter {name_hints([name], known)}")
            setattr(trial, name, value)
        for name in values:
            setattr(self, name, getattr(trial, name))


@define(kw_only=True)
class BaseComponentConfig(BaseAttrs):
    """Settings every component has.

    :param execution_queue_depth: how many pending steps the component's worker keeps.
    :param queue_full_policy: when that queue is full, ``"drop_oldest"`` discards the oldest
        pending step (the newest input wins, the default for robots) and ``"drop_newest"``
        discards the incoming one; either way the drop is counted.
    :param status_rate: how often (Hz) the health status is re-published when nothing changes.
    :param log_level: ``"debug"``, ``"info"``, ``"warning"`` or ``"error"``.
    :param step_finish_timeout: how long (s) a deactivate waits for a running step to finish;
        a step still running then has its outputs discarded (counted), never reported as a failure.

    All of them can be changed on a running component (``set_param``) and take effect at once.
    """

    execution_queue_depth: int = field(default=10, validator=base_validators.in_range(1, 100_000))
    queue_full_policy: Literal["drop_oldest", "drop_newest"] = field(
        default="drop_oldest", validator=base_validators.in_(["drop_oldest", "drop_newest"])
    )
    status_rate: float = field(default=1.0, validator=base_validators.in_range(0.01, 10.0))
    log_level: str = field(default="info", validator=base_validators.in_(["debug", "info", "warning", "error"]))
    step_finish_timeout: float = field(default=5.0, validator=base_validators.in_range(0.0, 600.0))


@define(kw_only=True)
class ModelComponentConfig(BaseComponentConfig):
    """Settings of components that call a model.

    :param warmup: run one inference during configure so the first real one is fast.
    :param enable_local_model: use the built-in local model instead of a model client.
    :param device_local_model: ``"auto"`` (default: the GPU when the local model's backend can use
        one, else the CPU), ``"cuda"`` (the GPU; the CPU with a WARNING where the backend cannot use
        one) or ``"cpu"``; see :mod:`agents_core.engines.device`.
    :param ncpu_local_model: CPU threads for the local model.
    :param local_model_path: a local file path or a hub repository id for the local model.

    These apply at configure: ``set_param`` refuses them while the component is configured.
    """

    warmup: bool = field(default=False, metadata=AT_CONFIGURE)
    enable_local_model: bool = field(default=False, metadata=AT_CONFIGURE)
    device_local_model: Literal["auto", "cpu", "cuda"] = field(
        default="auto", validator=base_validators.in_(["auto", "cpu", "cuda"]), metadata=AT_CONFIGURE)
    ncpu_local_model: int = field(default=1, validator=base_validators.gt(0), metadata=AT_CONFIGURE)
    local_model_path: str | None = field(default=None, metadata=AT_CONFIGURE)

    def _get_inference_params(self) -> dict[str, Any]:
        """The subset of fields sent with each inference call (none by default)."""
        return {}


# The component configs, re-exported on first use: this module never imports the component packages
# (which import this one), and a recipe does not pay for building the attrs classes of the configs
# it does not use.
if TYPE_CHECKING:
    from .components.cortex.config import CortexConfig as CortexConfig
    from .components.llm_config import LLMConfig as LLMConfig
    from .components.map_encoding_config import MapConfig as MapConfig
    from .components.memory.config import MemoryConfig as MemoryConfig
    from .components.mllm_config import MLLMConfig as MLLMConfig
    from .components.mllm_config import VLMConfig as VLMConfig
    from .components.semantic_router_config import SemanticRouterConfig as SemanticRouterConfig
    from .components.speech_to_text_config import SpeechToTextConfig as SpeechToTextConfig
    from .components.text_to_speech_config import TextToSpeechConfig as TextToSpeechConfig
    from .components.video_maker_config import VideoMessageMakerConfig as VideoMessageMakerConfig
    from .components.vision.config import VisionConfig as VisionConfig
    from .components.vla.config import VLAConfig as VLAConfig
else:
    __getattr__, __dir__ = lazy_facade(__name__, own=("BaseAttrs", "BaseComponentConfig", "ModelComponentConfig",
                                                      "configure_time_fields", "load_config_file"))
