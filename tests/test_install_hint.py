"""Error messages name the install command that works for how the package was installed."""

from __future__ import annotations

from pathlib import Path

import pytest

from agents_core.support.install_hint import install_hint
from agents_core.transport.registry import TRANSPORT_ALIASES, TransportNotAvailableError, resolve_transport

ROOT = Path(__file__).resolve().parents[1]


def test_a_checkout_gets_the_editable_install_of_its_own_path() -> None:
    assert install_hint("zenoh", ROOT / "pyproject.toml") == f"pip install -e '{ROOT}[zenoh]'"


def test_an_installed_copy_gets_the_registry_form(tmp_path: Path) -> None:
    assert install_hint("ui", tmp_path / "pyproject.toml") == "pip install 'agents-core[ui]'"
    other = tmp_path / "pyproject.toml"
    other.write_text('[project]\nname = "someone-else"\nversion = "1.0"\n', encoding="utf-8")
    assert install_hint("ui", other) == "pip install 'agents-core[ui]'"


def test_a_missing_transport_extra_names_the_command(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(TRANSPORT_ALIASES, "nowhere", ("agents_nowhere_adapter:Transport", "nowhere"))
    with pytest.raises(TransportNotAvailableError) as raised:
        resolve_transport("nowhere")
    assert install_hint("nowhere") in str(raised.value)
    assert "'nowhere' transport" in str(raised.value)
