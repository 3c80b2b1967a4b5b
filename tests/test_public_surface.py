"""The package's public surface: imports without middleware, exports, transport resolution errors."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import agents_core
import agents_core.ros
from agents_core import errors
from agents_core.errors import AgentsError, ConfigError, TransportNotAvailableError
from agents_core.support.install_hint import install_hint
from agents_core.transport import MemoryTransport, resolve_transport


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)


def test_import_pulls_in_no_middleware() -> None:
    result = _run("import sys, agents_core, agents_core.ros, agents_core.components, agents_core.clients;"
                  "bad = [m for m in ('rclpy', 'zenoh') if m in sys.modules]; print(bad); sys.exit(bool(bad))")
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize(("name", "module"), [("zenoh", "zenoh"), ("ros2", "rclpy")])
def test_missing_extra_is_named_in_the_error(name: str, module: str) -> None:
    # Blocking the import in a fresh interpreter simulates a machine without the extra.
    result = _run(f"import sys; sys.modules[{module!r}] = None\n"
                  "from agents_core import resolve_transport\n"
                  f"try:\n    resolve_transport({name!r})\n"
                  "except ImportError as e:\n    print(type(e).__name__, e)\n")
    assert "TransportNotAvailableError" in result.stdout, result.stderr
    assert install_hint(name) in result.stdout  # the checkout's own install command


def test_typo_in_transport_name_suggests_the_right_one() -> None:
    with pytest.raises(TransportNotAvailableError, match="did you mean 'memory'"):
        resolve_transport("memroy")


def test_transport_resolution_by_env_and_object(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AGENTS_TRANSPORT", "memory")
    transport = resolve_transport(None)
    assert isinstance(transport, MemoryTransport)
    assert resolve_transport(transport) is transport
    with pytest.raises(ConfigError):
        resolve_transport(42)  # type: ignore[arg-type]
    transport.close()


def test_ros_compat_module_exports() -> None:
    for name in ["Topic", "FixedInput", "SupportedType", "base_validators", "Launcher", "Event", "Action",
                 "String", "Image", "Audio", "Detections", "StreamingString", "component_action", "Memory",
                 "MemLayer", "MemoryConfig"]:
        assert hasattr(agents_core.ros, name), name
    assert callable(agents_core.ros.base_validators.gt)


@pytest.mark.parametrize("module", ["agents_core", "agents_core.ros", "agents_core.transport",
                                    "agents_core.components", "agents_core.clients", "agents_core.errors",
                                    "agents_core.messages", "agents_core.supported_types", "agents_core.utils",
                                    "agents_core.config"])
def test_all_lists_only_real_names(module: str) -> None:
    # On the lazy packages, hasattr() imports the name's module: every entry must resolve.
    mod = importlib.import_module(module)
    for name in mod.__all__:
        assert hasattr(mod, name), f"{module}.__all__ names {name!r}, which does not exist"


def test_star_imports_bind_every_listed_name() -> None:
    # A fresh interpreter: star imports of the lazy modules resolve each name of __all__ on the way.
    result = _run("import importlib\n"
                  "for m in ('agents_core', 'agents_core.ros', 'agents_core.components', 'agents_core.clients',"
                  " 'agents_core.utils'):\n"
                  "    ns = {}\n"
                  "    exec(f'from {m} import *', ns)\n"
                  "    missing = set(importlib.import_module(m).__all__) - set(ns)\n"
                  "    assert not missing, (m, missing)\n")
    assert result.returncode == 0, result.stdout + result.stderr


def test_error_tree_has_one_root_and_builtin_meanings() -> None:
    for name in errors.__all__:
        assert issubclass(getattr(errors, name), AgentsError)
    assert issubclass(errors.ConfigError, ValueError)
    assert issubclass(errors.RequestTimeoutError, TimeoutError)
    assert issubclass(errors.TransportNotAvailableError, ImportError)
    for name in errors.__all__:
        assert name in (errors.__doc__ or ""), f"{name} missing from the tree in the module docstring"
