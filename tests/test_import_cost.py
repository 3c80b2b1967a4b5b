"""What importing the package costs: the light path loads no model stack, and lazy names resolve to the real objects.

Each check runs in a fresh interpreter (the test process itself has imported everything), records
the modules that were not loaded before the statement and reports them as JSON. Timing is not
tested here (too machine-dependent); ``benchmarks/imports.py`` measures it.
"""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

#: Third-party packages of the model stack (and OpenTelemetry, off by default): none may load before a model
#: component or client is used.
HEAVY = ("httpx", "jinja2", "yaml", "llama_cpp", "emem", "hnswlib", "opentelemetry")

#: Modules that are model components or hold them: never on the light path.
MODEL_COMPONENT_MODULES = ("agents_core.components.model_component", "agents_core.components.llm",
                           "agents_core.components.mllm", "agents_core.components.semantic_router")

#: Statements that must not load the model stack: the package, the upstream names a relay uses,
#: the component runtime and the bare sub-packages.
LIGHT = [
    "import agents_core",
    "from agents_core.ros import Topic, Launcher, String",
    "from agents_core import Topic, Launcher, Event, Action, MemoryTransport, BaseComponentConfig",
    "from agents_core.components import Component, ComponentRunType",
    "import agents_core.components, agents_core.clients, agents_core.utils, agents_core.ros",
    "import agents_core.engines, agents_core.launch, agents_core.components.vision, agents_core.components.vla",
    "import agents_core.config",
    "import agents_core.components.memory",
]

#: (package, name, defining module): reading the name from the package gives the defining module's object.
LAZY_NAMES = [
    ("agents_core", "Topic", "agents_core.topics"),
    ("agents_core", "ModelComponent", "agents_core.components.model_component"),
    ("agents_core.components", "LLM", "agents_core.components.llm"),
    ("agents_core.components", "Component", "agents_core.components.component_base"),
    ("agents_core.clients", "OllamaClient", "agents_core.clients.ollama"),
    ("agents_core.clients", "ChromaClient", "agents_core.clients.chroma.client"),
    ("agents_core.ros", "Route", "agents_core.components.semantic_router"),
    ("agents_core.ros", "String", "agents_core.supported_types"),
    ("agents_core.utils", "LocalLLM", "agents_core.engines.local_llm"),
    ("agents_core.utils", "ObjectTracker", "agents_core.components.vision.tracking"),
    ("agents_core.engines", "LocalSTT", "agents_core.engines.local_stt"),
    ("agents_core.components", "Vision", "agents_core.components.vision.component"),
    ("agents_core.components", "VLA", "agents_core.components.vla.component"),
    ("agents_core.clients", "LeRobotClient", "agents_core.clients.lerobot.client"),
    ("agents_core", "Launcher", "agents_core.launch.launcher"),
    ("agents_core.components", "Memory", "agents_core.components.memory.component"),
    ("agents_core.config", "MemoryConfig", "agents_core.components.memory.config"),
    ("agents_core.ros", "MemLayer", "agents_core.components.memory.layers"),
]

#: The modules whose re-exports are lazy.
LAZY_MODULES = ["agents_core", "agents_core.ros", "agents_core.components", "agents_core.clients",
                "agents_core.utils", "agents_core.engines", "agents_core.launch", "agents_core.components.vision",
                "agents_core.components.vla", "agents_core.clients.lerobot", "agents_core.clients.chroma"]

_PROBE = textwrap.dedent("""
    import json, sys
    before = set(sys.modules)
    {code}
    loaded = sorted(set(sys.modules) - before)
    # A module of agents_core.components that defines a Component subclass is a component module
    # (the runtime's own modules define none); looking at the loaded modules imports nothing.
    base = sys.modules.get("agents_core.components.component_base")
    components = []
    for name in loaded:
        module = sys.modules.get(name)
        if base is None or module is None or not name.startswith("agents_core.components."):
            continue
        for value in list(vars(module).values()):
            if isinstance(value, type) and issubclass(value, base.Component) and value is not base.Component \\
                    and value.__module__ == name:
                components.append(name + "." + value.__name__)
    print(json.dumps({{"loaded": loaded, "components": sorted(components)}}))
""")


def _fresh(code: str) -> dict[str, Any]:
    """Run ``code`` in a new interpreter; what it loaded (modules not there at start-up)."""
    result = subprocess.run([sys.executable, "-c", _PROBE.format(code=code)], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


@pytest.mark.parametrize("code", LIGHT)
def test_light_path_loads_no_model_stack(code: str) -> None:
    got = _fresh(code)
    loaded = got["loaded"]
    heavy = sorted(m for m in loaded if m.split(".")[0] in HEAVY)
    assert not heavy, f"{code!r} imported {heavy}"
    clients = [m for m in loaded if m.startswith("agents_core.clients.")]
    assert not clients, f"{code!r} imported clients {clients}"
    models = [m for m in loaded
              if m in MODEL_COMPONENT_MODULES or m.startswith(("agents_core.utils.", "agents_core.engines."))]
    assert not models, f"{code!r} imported model modules {models}"
    assert not got["components"], f"{code!r} imported components {got['components']}"


def test_plain_import_loads_nothing_but_the_package() -> None:
    loaded = _fresh("import agents_core")["loaded"]
    ours = [m for m in loaded if m.startswith("agents_core")]
    assert ours == ["agents_core", "agents_core.support", "agents_core.support.lazy"], ours
    assert "numpy" not in loaded


def test_recipe_import_loads_no_numpy() -> None:
    # numpy costs more than the rest of a relay recipe's imports together: the types import it at first use.
    loaded = _fresh("from agents_core.ros import Topic, Launcher, String")["loaded"]
    assert "numpy" not in loaded, [m for m in loaded if m.startswith("numpy")][:5]


def test_numpy_loads_at_first_use_and_values_stay_numpy() -> None:
    code = textwrap.dedent("""
        import sys
        from agents_core.ros import Float32, Float32MultiArray, Image, String
        from agents_core.supported_types import get_type
        from agents_core.messages import IMAGE_ENCODINGS
        assert String.validate("hi") == "hi" and Float32.validate(0.5) == 0.5
        assert "rgb8" in IMAGE_ENCODINGS and "numpy" not in sys.modules
        import numpy as np
        assert Float32MultiArray.value_class is np.ndarray and Float32MultiArray.dtype is np.float32
        assert get_type("Float64MultiArray").validate([[1, 2]]).dtype == np.float64
        assert IMAGE_ENCODINGS["16UC1"] == (np.uint16, 1)
        assert Float32.validate(np.float32(2.0)) == 2.0
        msg = Image.validate(np.zeros((2, 3, 3), np.uint8))
        assert type(msg.data) is np.ndarray and msg.encoding == "rgb8"
        assert type(Image.to_output(msg)) is np.ndarray
    """)
    _fresh(code)


def test_recipe_import_builds_only_the_types_it_names() -> None:
    # The image, perception, sensor... classes are built when the registry is first used, not on import.
    loaded = _fresh("from agents_core.ros import Topic, Launcher, String")["loaded"]
    families = [m for m in loaded if m.startswith("agents_core.types.")
                and m.rsplit(".", 1)[1] not in ("base", "fields", "text", "component_status")]
    assert not families, families


def test_builtin_types_register_at_first_use_before_user_types() -> None:
    code = textwrap.dedent("""
        import sys, threading
        from agents_core.supported_types import SupportedType, add_additional_datatypes, get_type, registered_types
        assert "agents_core.types.media" not in sys.modules
        class Mine(SupportedType):
            value_class = str
        add_additional_datatypes([Mine])
        from agents_core.types import BUILTIN_TYPES
        names = list(registered_types())
        assert names == [t.__name__ for t in BUILTIN_TYPES] + ["Mine"], names
        assert get_type("Image").__module__ == "agents_core.types.media"
    """)
    _fresh(code)


def test_types_looked_up_by_name_from_two_threads_at_once() -> None:
    code = textwrap.dedent("""
        import threading
        from agents_core.supported_types import get_type
        found, start = [], threading.Barrier(4)
        def look(name):
            start.wait(timeout=10)
            found.append(get_type(name).__name__)
        threads = [threading.Thread(target=look, args=(n,)) for n in ("CameraInfo", "Image", "Pose", "JointState")]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=30)
        assert sorted(found) == ["CameraInfo", "Image", "JointState", "Pose"], found
    """)
    _fresh(code)


@pytest.mark.parametrize(("package", "name", "module"), LAZY_NAMES)
def test_lazy_name_is_the_defining_modules_object(package: str, name: str, module: str) -> None:
    code = textwrap.dedent(f"""
        import importlib, sys
        package = importlib.import_module({package!r})
        assert {module!r} not in sys.modules, "imported before use"
        assert {name!r} not in vars(package), "bound before use"
        value = getattr(package, {name!r})
        assert value is getattr(importlib.import_module({module!r}), {name!r})
        assert vars(package)[{name!r}] is value, "not cached on the package"
        assert getattr(package, {name!r}) is value
    """)
    loaded = _fresh(code)["loaded"]
    assert "llama_cpp" not in loaded  # the local model classes import it only when a model is created


def test_from_import_and_star_import_resolve_lazy_names() -> None:
    code = textwrap.dedent("""
        from agents_core.components import *
        from agents_core.clients import *
        import agents_core.components as c
        assert LLM is c.llm.LLM and SemanticRouter is c.semantic_router.SemanticRouter
        assert OllamaClient.__module__ == "agents_core.clients.ollama"
    """)
    loaded = _fresh(code)["loaded"]
    assert "httpx" in loaded  # using them does load the stack


def test_client_registry_names_every_builtin_client() -> None:
    # client_from_spec rebuilds a client by class name: taken from the package, it knows them all.
    code = textwrap.dedent("""
        from agents_core.clients import __all__ as names, client_types
        known = client_types()
        missing = [n for n in names if n.endswith("Client") and n not in ("BaseClient", "DBClient", "ModelClient")
                   and n not in known]
        assert not missing, missing
    """)
    _fresh(code)


def test_chroma_client_rebuilds_an_embedding_client_nobody_imported() -> None:
    # The spec names OllamaClient, whose module the child never imports itself.
    from agents_core.clients import OllamaClient  # noqa: PLC0415
    from agents_core.models import OllamaModel  # noqa: PLC0415

    spec = OllamaClient(model=OllamaModel(name="embedder", checkpoint="nomic-embed-text")).serialize()
    code = textwrap.dedent(f"""
        from agents_core.clients import ChromaClient
        from agents_core.vectordbs import ChromaDB
        client = ChromaClient(db=ChromaDB(name="docs"), embedding_client={spec!r})
        assert type(client.embedding_client).__name__ == "OllamaClient"
    """)
    _fresh(code)


def test_submodules_stay_reachable_as_attributes() -> None:
    # An eager package made `agents_core.transport` work after `import agents_core`; the lazy one still does.
    code = textwrap.dedent("""
        import agents_core
        assert agents_core.transport.MemoryTransport.__name__ == "MemoryTransport"
        assert agents_core.components.llm.LLM is agents_core.components.LLM
        assert agents_core.config.load_config_file
    """)
    _fresh(code)


@pytest.mark.parametrize("module", LAZY_MODULES)
def test_unknown_name_is_an_attribute_error(module: str) -> None:
    mod = importlib.import_module(module)
    with pytest.raises(AttributeError, match="has no attribute 'NoSuchName'"):
        _ = mod.NoSuchName
    assert not hasattr(mod, "NoSuchName")
    with pytest.raises(ImportError):
        exec(f"from {module} import NoSuchName", {})


@pytest.mark.parametrize("module", LAZY_MODULES)
def test_dir_lists_every_exported_name(module: str) -> None:
    mod = importlib.import_module(module)
    assert set(mod.__all__) <= set(dir(mod))


def _type_checking_imports(path: Path) -> dict[str, set[str]]:
    """The ``if TYPE_CHECKING:`` imports of a module, as module (relative, ``.x``) -> names."""
    found: dict[str, set[str]] = {}
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for stmt in node.body:
                assert isinstance(stmt, ast.ImportFrom), ast.dump(stmt)
                where = "." * stmt.level + (stmt.module or "")
                for alias in stmt.names:
                    if where.strip(".") == "":  # `from . import module`: the module itself
                        found.setdefault(where + alias.name, set()).add(alias.name)
                    else:
                        found.setdefault(where, set()).add(alias.asname or alias.name)
    return found


@pytest.mark.parametrize("module", LAZY_MODULES)
def test_lazy_table_type_checking_imports_and_all_agree(module: str) -> None:
    # Three lists name the exports (the lazy table, the imports type checkers read, __all__): a
    # client added to one and not the others would be invisible to mypy, or to star imports.
    mod = importlib.import_module(module)
    table: dict[str, tuple[str, ...]] = mod._EXPORTS
    assert mod.__file__ is not None
    typed = _type_checking_imports(Path(mod.__file__))
    modules = {path: {name} for name, path in getattr(mod, "_MODULE_EXPORTS", {}).items()}
    assert typed == {k: set(v) for k, v in table.items()} | modules
    exported = {n for names in table.values() for n in names} | {n for names in modules.values() for n in names}
    assert exported == set(mod.__all__) - {"__version__"}
    assert len(mod.__all__) == len(set(mod.__all__))


@pytest.mark.parametrize("module", ["agents_core.supported_types", "agents_core.messages"])
def test_type_facades_lazy_table_agrees_with_type_checking_imports(module: str) -> None:
    # The façades re-export the families' names lazily: the table, the imports type checkers read and
    # __all__ must name the same things, and every exported name must resolve.
    mod = importlib.import_module(module)
    assert mod.__file__ is not None
    typed = _type_checking_imports(Path(mod.__file__))
    assert typed == {k: set(v) for k, v in mod._EXPORTS.items()}
    lazy = {n for names in mod._EXPORTS.values() for n in names}
    assert lazy <= set(mod.__all__)
    assert all(getattr(mod, name) is not None for name in mod.__all__)
    assert set(mod.__all__) <= set(dir(mod))
