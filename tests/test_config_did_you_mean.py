"""A misspelt field in a config file gets the same "did you mean" as a misspelt constructor argument."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.config import BaseComponentConfig
from agents_core.errors import ConfigError


class Quiet(Component):
    """Does nothing; only its config matters here."""

    def _execution_step(self, **kwargs: Any) -> None:
        return None


def _component(config_file: Path | None = None) -> Quiet:
    return Quiet(inputs=[], outputs=[Topic("out", "String")], trigger=1.0, component_name="quiet",
                 config_file=config_file)


def test_launcher_config_file_section_suggests_the_field(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text("transport:\n  name: memory\nquiet:\n  stauts_rate: 2.0\n")
    launcher = Launcher(config_file=path)
    launcher.add_pkg(components=[_component()])
    with pytest.raises(ConfigError) as caught:
        launcher.start()
    launcher.stop()
    text = str(caught.value)
    assert f"config file {path}, section 'quiet'" in text
    assert "'stauts_rate' (did you mean 'status_rate'?)" in text


def test_component_config_file_section_suggests_the_field(tmp_path: Path) -> None:
    path = tmp_path / "quiet.toml"
    path.write_text("[quiet]\nexecution_queue_dept = 3\n")
    with pytest.raises(ConfigError, match=r"'execution_queue_dept' \(did you mean 'execution_queue_depth'\?\)"):
        _component(config_file=path)


def test_from_dict_and_update_suggest_the_field() -> None:
    with pytest.raises(ConfigError, match=r"unknown field\(s\) \['log_levle'\] "
                                          r"\('log_levle' \(did you mean 'log_level'\?\)\); known fields"):
        BaseComponentConfig.from_dict({"log_levle": "debug"})
    config = BaseComponentConfig()
    with pytest.raises(ConfigError, match=r"has no parameter 'queue_full_polcy' \(did you mean 'queue_full_policy'"):
        config.update(queue_full_polcy="drop_newest")
    with pytest.raises(ConfigError, match=r"has no parameter 'zzz'$"):
        config.update(zzz=1)


def test_transport_section_suggests_the_option(tmp_path: Path) -> None:
    pytest.importorskip("zenoh")
    path = tmp_path / "robot.yaml"
    path.write_text("transport:\n  name: zenoh\n  mdoe: peer\n")
    launcher = Launcher(config_file=path)
    launcher.add_pkg(components=[_component()])
    with pytest.raises(ConfigError, match=r"'mdoe' \(did you mean 'mode'\?\)"):
        launcher.start()
    launcher.stop()
