"""An attached UI whose components do not all describe themselves (issue 25, item 6): the UI starts,
shows each such component as "unavailable" with the reason, and the others work."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from agents_core import Launcher
from agents_core.errors import RemoteError
from agents_core.ui import UISettings

from .ui_parts import shouter

MALFORMED: dict[str, Any] = {
    "a_list": ["not", "a", "mapping"],
    "bad_inputs": {"name": "bad_inputs", "component_type": "X", "run_type": "event", "state": "active",
                   "health": "HEALTHY", "inputs": "words", "outputs": [], "actions": {}},
    "bad_entry": {"name": "bad_entry", "component_type": "X", "run_type": "event", "state": "active",
                  "health": "HEALTHY", "inputs": [{"name": 3}], "outputs": [], "actions": {}},
}


def test_components_without_or_with_a_malformed_describe_are_unavailable() -> None:
    from agents_core.ui.attach import attach  # noqa: PLC0415

    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        transport = launcher.transport
        services = [transport.create_service(f"{name}/describe", lambda request, reply=reply: reply)
                    for name, reply in MALFORMED.items()]
        try:
            names = ["shouter", "ghost", *MALFORMED]  # ghost: nothing answers its describe
            server = attach(transport, components=names, settings=UISettings(port=0), timeout=0.5)
            try:
                doc = httpx.get(f"{server.url}api/interfaces", timeout=30).json()
                shown = {c["name"]: c for c in doc["components"]}
                assert set(shown) == set(names)
                for name in ["ghost", *MALFORMED]:
                    assert shown[name]["state"] == "unavailable", shown[name]
                    assert shown[name]["error"], "the reason is shown"
                assert "describe reply" in shown["a_list"]["error"]
                assert "not a list" in shown["bad_inputs"]["error"]
                assert shown["shouter"]["state"] == "active" and [i["name"] for i in doc["inputs"]] == ["words"]
                # the working component works
                reply = httpx.post(f"{server.url}api/components/shouter/actions/set_volume", json={"args": [3]},
                                   timeout=10)
                assert reply.json()["result"] == 3
                # the unavailable one answers 503 with its reason, not a 500
                refused = httpx.post(f"{server.url}api/components/ghost/transition",
                                     json={"transition": "deactivate"}, timeout=30)
                assert refused.status_code == 503 and "ghost" in refused.json()["error"]
            finally:
                server.stop()
        finally:
            for service in services:
                service.close()


@pytest.mark.parametrize("reply", [None, 3, "text", {"inputs": [], "outputs": [], "actions": []},
                                   {"inputs": [], "outputs": [{"name": "a"}], "actions": {}}])
def test_checked_description_refuses_shapes_it_cannot_use(reply: Any) -> None:
    from agents_core.ui.recipe_view import checked_description  # noqa: PLC0415

    with pytest.raises(RemoteError, match="'x'"):
        checked_description("x", reply)
