"""What the spec's text says beyond its ```python blocks (issue 37), read from the spec file where it can be.

- the three hierarchies it draws (components, configs, models): each child is a subclass of its
  parent here, with the fields "(adds ...)" names, or the difference is a row of docs/porting.md;
- the messages tables of messages.md: every message and action file exists in ``interfaces/`` with
  the fields the description names;
- custom_client.md's contract in words: ``_initialize`` only with ``init_on_activation``, a Generator
  as the ``'output'`` value streams, the model given as a dict, the constructor's defaults;
- architecture.md's trigger table (an ``Event`` trigger fires the step when raised, ``None`` only for
  server run types) and the config deep-copied at init; messages.md's callbacks (one per topic, an
  Image callback gives a numpy array).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, MutableMapping
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.clients.model_base import ModelClient
from agents_core.components import LLM, Component
from agents_core.config import LLMConfig
from agents_core.errors import WiringError
from agents_core.messages import ImageMsg, StreamingStringMsg
from agents_core.models import GenericLLM
from agents_core.ros import Event
from agents_core.runtime.run_type import ComponentRunType

from ..conftest import wait_for
from .spec_blocks import REPO, spec_text
from .test_porting_names import ROWS

_TREE_LINE = re.compile(r"^(?P<lead>[\s│├└─]*)(?P<names>\w+(?: / \w+)*)(?: \((?P<note>[^)]*)\))?\s*$")


def _drawing(after_heading: str) -> str:
    """The first fenced drawing (a ``` block without a language) after ``after_heading``."""
    text = spec_text()
    start = text.index(after_heading)
    match = re.search(r"^```\n(.*?)^```", text[start:], re.MULTILINE | re.DOTALL)
    assert match, f"no drawing after {after_heading!r}"
    return match.group(1)


def _edges(drawing: str) -> Iterator[tuple[str, str, str]]:
    """(parent, child, note) for each line of a tree drawing; ``VLM / MLLM`` gives one edge per name."""
    stack: list[tuple[int, list[str]]] = []
    for line in drawing.splitlines():
        found = _TREE_LINE.match(line)
        if not found:
            continue
        column, names, note = len(found["lead"]), found["names"].split(" / "), found["note"] or ""
        while stack and stack[-1][0] >= column:
            stack.pop()
        if stack:
            for name in names:
                yield stack[-1][1][0], name, note
        stack.append((column, names))


def _documented(*names: str) -> bool:
    documented = {spec for spec, _ in ROWS}
    return any(name in documented for name in names)


def _check_tree(heading: str, module: Any, minimum: int) -> None:
    edges = list(_edges(_drawing(heading)))
    assert len(edges) >= minimum, f"the drawing after {heading!r} gave only {edges}"
    wrong = []
    for parent, child, note in edges:
        if _documented(parent, child):
            continue  # a difference docs/porting.md lists, with its reason
        here_parent, here_child = getattr(module, parent, None), getattr(module, child, None)
        if here_parent is None or here_child is None or not issubclass(here_child, here_parent):
            wrong.append(f"{child} -> {parent}")
            continue
        alias = re.fullmatch(r"aliased as (\w+)", note)
        if alias and getattr(module, alias.group(1), None) is not here_child:
            wrong.append(f"{alias.group(1)} is not {child}")
        added = re.fullmatch(r"adds ([\w, ]+)", note)
        if added and attrs.has(here_child):
            fields = {f.name for f in attrs.fields(here_child)}
            wrong += [f"{child}.{name}" for name in (n.strip() for n in added.group(1).split(","))
                      if " " not in name and name not in fields]
    assert not wrong, f"the spec's hierarchy after {heading!r} differs here, not in docs/porting.md: {wrong}"


def test_the_component_hierarchy_is_the_spec_s_or_documented() -> None:
    from agents_core import components  # noqa: PLC0415

    _check_tree("## Component Hierarchy", components, minimum=10)


def test_the_configuration_chain_is_the_spec_s_or_documented() -> None:
    from agents_core import config  # noqa: PLC0415

    _check_tree("## Configuration Chain", config, minimum=10)
    # "Each config class uses @define(kw_only=True) ... implements _get_inference_params() -> Dict".
    for _, name, _ in _edges(_drawing("## Configuration Chain")):
        cls = getattr(config, name)
        assert attrs.has(cls) and all(f.kw_only for f in attrs.fields(cls)), name
        assert isinstance(cls()._get_inference_params(), dict), name


def test_the_model_hierarchy_and_the_fields_each_model_adds() -> None:
    from agents_core import models  # noqa: PLC0415

    _check_tree("## Existing Model Hierarchy", models, minimum=13)
    for _, name, _ in _edges(_drawing("## Existing Model Hierarchy")):  # "Always use @define(kw_only=True)"
        cls = getattr(models, name)
        assert attrs.has(cls) and all(f.kw_only for f in attrs.fields(cls)), name


# -- messages.md's tables -----------------------------------------------------------------------------


def _table_rows(heading: str) -> list[list[str]]:
    text = spec_text()
    section = text[text.index(heading):]
    section = section[:section.index("\n#", 1)]
    return [[c.strip() for c in line.strip().strip("|").split("|")] for line in section.splitlines()
            if line.startswith("| `")]


def _msg_fields(path: Path) -> set[str]:
    fields = set()
    for raw in path.read_text(encoding="utf-8").splitlines():
        line = raw.split("#", 1)[0].strip()
        if line and "=" not in line:  # a field, not a constant
            fields.add(line.split()[-1])
    return fields


def test_every_message_of_the_messages_table_exists_with_the_fields_it_names() -> None:
    rows = _table_rows("## Existing Message Types")
    assert len(rows) == 9, rows
    wrong = []
    for cells in rows:
        name, file = cells[0].strip("`"), cells[1].strip("`")
        path = REPO / "interfaces" / "msg" / file
        if not path.is_file():
            wrong.append(f"{file}: no interfaces/msg/{file}")
            continue
        fields = _msg_fields(path)
        named = re.findall(r"`([a-z_]+)`", cells[2])
        wrong += [f"{name}.{field}" for field in named if field not in fields]
    assert not wrong, wrong
    for cells in _table_rows("### Action Types"):
        assert (REPO / "interfaces" / "action" / cells[1].strip("`")).is_file(), cells


# -- custom_client.md in words ----------------------------------------------------------------------


class _Streaming(ModelClient):
    """Its ``_inference`` returns a Generator as the 'output' value (custom_client.md); records its hooks."""

    def __init__(self, model: Any = None, **kwargs: Any) -> None:
        super().__init__(model or GenericLLM(name="gen", checkpoint="gen"), **kwargs)
        self.hooks: list[str] = []

    def _check_connection(self) -> None:
        self.hooks.append("check")

    def _initialize(self) -> None:
        self.hooks.append("init")

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        self.hooks.append("inference")

        def tokens() -> Iterator[str]:
            yield from ("Hel", "lo ", "there")

        return {"output": tokens()}

    def _deinitialize(self) -> None:
        self.hooks.append("deinit")


def test_the_client_constructor_defaults_and_a_model_given_as_a_dict() -> None:
    client = _Streaming()
    assert (client.inference_timeout, client.init_on_activation) == (30, True)
    again = _Streaming(client.serialize()["model"])  # "Model or Dict (attrs class or deserialized dict)"
    assert (again.model_name, again.model_type, again.model_init_params) == ("gen", "GenericLLM",
                                                                               client.model_init_params)


@pytest.mark.parametrize("output_type", ["StreamingString", "String"])
def test_a_generator_as_the_output_value_streams_and_initialize_follows_init_on_activation(output_type: str) -> None:
    question, answer = Topic("question", "String"), Topic("answer", output_type)
    client = _Streaming(init_on_activation=False)
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, trigger=question,
              config=LLMConfig(stream=True))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    got: list[Any] = []
    with launcher:
        assert client.hooks == ["check"], "_initialize runs only if init_on_activation is True"
        launcher.transport.create_subscription(answer, got.append)
        launcher.transport.create_publisher(question).publish("hi")
        assert wait_for(lambda: bool(got) and (output_type == "String" or got[-1].done), timeout=10), llm.health_message
    if output_type == "String":
        assert got == ["Hello there"]
    else:
        assert all(isinstance(m, StreamingStringMsg) and m.stream for m in got)
        assert [m.data for m in got if m.data] == ["Hel", "lo ", "there"]


# -- architecture.md: triggers, the config copy; messages.md: callbacks ---------------------------------


class _Step(Component):
    def __init__(self, **kwargs: Any) -> None:
        self.steps: list[dict[str, Any]] = []
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.steps.append(kwargs)


def test_an_event_trigger_fires_the_step_when_the_event_is_raised() -> None:
    estimate = Event(name="estimate_depth")  # custom_component.md's event, with no condition
    step = _Step(inputs=[Topic("camera", "Image")], outputs=[], trigger=estimate, component_name="stepper")
    assert step.run_type == ComponentRunType.EVENT
    launcher = Launcher("memory")
    launcher.add_pkg(components=[step])
    with launcher:
        assert not wait_for(lambda: bool(step.steps), timeout=0.3), "it fired without the event"
        estimate.trigger()
        assert wait_for(lambda: len(step.steps) == 1)


def test_a_none_trigger_is_only_valid_for_server_run_types() -> None:
    with pytest.raises(WiringError, match="only valid for server components"):
        _Step(inputs=[], outputs=[], trigger=None)
    for run_type in (ComponentRunType.SERVER, ComponentRunType.ACTION_SERVER):
        assert _Step(inputs=[], outputs=[], trigger=None, run_type=run_type).run_type == run_type


def test_the_config_is_deep_copied_at_init() -> None:
    shared = LLMConfig(temperature=0.3)
    question = Topic("question", "String")
    first, second = (LLM(inputs=[question], outputs=[Topic("answer", "String")], model_client=_Streaming(),
                         config=shared, trigger=question, component_name=name) for name in ("first", "second"))
    first.config.temperature = 0.9
    assert (shared.temperature, second.config.temperature) == (0.3, 0.3)


def test_callbacks_are_one_per_topic_and_an_image_callback_gives_a_numpy_array() -> None:
    camera = Topic("camera", "Image")
    one, two = (_Step(inputs=[camera], outputs=[], trigger=1.0, component_name=n) for n in ("one", "two"))
    assert one.callbacks["camera"] is not two.callbacks["camera"]
    frame = np.arange(12, dtype=np.uint8).reshape(2, 2, 3)
    one.callbacks["camera"]._receive(ImageMsg(data=frame, encoding="rgb8"))
    output = one.callbacks["camera"].get_output()
    assert isinstance(output, np.ndarray) and np.array_equal(output, frame)
    assert two.callbacks["camera"].get_output() is None


def test_every_type_s_callback_class_inherits_from_generic_callback() -> None:
    from agents_core.callbacks import DetectionsCallback, GenericCallback  # noqa: PLC0415
    from agents_core.ros import Detections, String  # noqa: PLC0415
    from agents_core.supported_types import registered_types  # noqa: PLC0415

    # messages.md: "Each SupportedType.callback class inherits from GenericCallback".
    wrong = {name: t.callback for name, t in registered_types().items()
             if not (isinstance(t.callback, type) and issubclass(t.callback, GenericCallback))}
    assert not wrong, wrong
    assert String.callback is GenericCallback and Detections.callback is DetectionsCallback


def test_the_local_wrappers_take_model_path_device_ncpu_in_that_order() -> None:
    import inspect  # noqa: PLC0415

    from agents_core import utils  # noqa: PLC0415 - architecture.md: "the local model wrappers live in agents/utils/"

    for name in ("LocalLLM", "LocalVLM", "LocalVisionModel", "LocalSTT", "LocalTTS"):
        params = list(inspect.signature(getattr(utils, name)).parameters.values())[:3]
        assert [(p.name, p.kind) for p in params] == [
            (n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in ("model_path", "device", "ncpu")], name


def test_local_llm_returns_the_output_whole_or_as_a_generator() -> None:
    from ..components.models_dir import needs_smollm2  # noqa: PLC0415

    needs_smollm2()
    from agents_core.engines.model_files import default_llm_path  # noqa: PLC0415
    from agents_core.utils import LocalLLM  # noqa: PLC0415

    model = LocalLLM(str(default_llm_path()), "cpu", 1)  # architecture.md's order, positionally
    try:
        query = {"query": [{"role": "user", "content": "Say hello."}], "temperature": 0.0, "max_new_tokens": 8}
        whole = model(query)
        assert isinstance(whole["output"], str) and whole["output"].strip()
        streamed = model({**query, "stream": True})["output"]
        assert not isinstance(streamed, str) and iter(streamed) is streamed, "a generator of text chunks"
        assert "".join(streamed).strip() == whole["output"].strip()
    finally:
        model.close()
