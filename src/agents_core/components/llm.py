"""``LLM``: a component that answers text with a language model.

Each step takes the text that fired it (or, on a timer or event, the latest text input), renders
it through the prompt templates, optionally adds documents from a vector database (RAG) and the
chat history, and asks the model. The answer is published on every output: whole, or while it is
generated when ``config.stream`` is on (chunks on ``StreamingString`` outputs, sentences on
``String`` outputs). When the model calls registered tools, the component runs them and, for
tools that want it, hands the results back to the model, for at most ``max_tool_rounds`` calls.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import jinja2

from ..actions import ACTION_MARK, component_action
from ..callbacks import DetectionsCallback
from ..clients.db_base import DBClient
from ..clients.model_base import ModelClient
from ..declarations.action_schema import describe_action
from ..declarations.component_method import ComponentMethod
from ..declarations.setup_calls import setup_method
from ..errors import AlgorithmFailure, ConfigError, WiringError
from ..messages import DetectionsMsg, StreamingStringMsg
from ..status import LifecycleState
from ..supported_types import Detections, StreamingString, String, SupportedType
from ..telemetry import switch as _telemetry
from ..topics import Topic
from .component_base import AllowedTypes, TriggerType
from .llm_config import LLMConfig
from .model_component import ModelComponent

__all__ = ["LLM", "ThinkStripper"]

_THINK_OPEN, _THINK_CLOSE = "<think>", "</think>"


class ThinkStripper:
    """Removes ``<think>...</think>`` blocks from text that arrives in pieces.

    Tags may be split across chunks, so a tail that could start a tag is held back until the next
    chunk (or :meth:`flush`) decides.
    """

    def __init__(self) -> None:
        self._inside = False
        self._held = ""

    def feed(self, chunk: str) -> str:
        """The visible part of ``chunk`` (possibly empty)."""
        text, out = self._held + chunk, []
        self._held = ""
        while text:
            tag = _THINK_CLOSE if self._inside else _THINK_OPEN
            pos = text.find(tag)
            if pos >= 0:
                if not self._inside:
                    out.append(text[:pos])
                text = text[pos + len(tag):]
                self._inside = not self._inside
                continue
            keep = _partial_tag_suffix(text, tag)
            visible, self._held = text[:len(text) - keep], text[len(text) - keep:]
            if not self._inside:
                out.append(visible)
            break
        return "".join(out)

    def flush(self) -> str:
        """What is held back at the end of the text (an unclosed think block is dropped)."""
        held, self._held = self._held, ""
        return "" if self._inside else held


def _partial_tag_suffix(text: str, tag: str) -> int:
    for n in range(min(len(tag) - 1, len(text)), 0, -1):
        if text.endswith(tag[:n]):
            return n
    return 0


def _variable_name(topic_name: str) -> str:
    """A topic name as a template variable (``camera/text`` → ``camera_text``)."""
    return re.sub(r"\W", "_", topic_name)


class _Tool:
    def __init__(self, func: Callable[..., Any], description: dict[str, Any], send_back: bool) -> None:
        self.func = func
        self.description = description
        self.send_back = send_back


class LLM(ModelComponent):
    """Answers text inputs with a language model (a model client, or the built-in local LLM).

    :param inputs: String topics (required) and optional Detections topics, whose labels can be
        used in prompt templates.
    :param outputs: String and/or StreamingString topics; a topic of another type (``PoseStamped``,
        say) gets the text answer through a publisher pre-processor that converts it
        (``add_publisher_preprocessor``; without one, configure refuses the output).
    :param model_client: the model client; None with ``config.enable_local_model``.
    :param config: an :class:`~agents_core.config.LLMConfig`.
    :param db_client: a vector database client, needed with ``config.enable_rag``.
    :param trigger: a topic, a list of topics, a rate in Hz or an Event.
    :param component_name: the component's name (also its node / key name).
    """

    config_class = LLMConfig
    allowed_inputs: AllowedTypes | None = MappingProxyType({"Required": [String], "Optional": [Detections]})
    # Any output type, as upstream: one that is not text needs a publisher pre-processor that turns
    # the answer into it (checked at configure, since it is added after construction).
    allowed_outputs: AllowedTypes | None = None
    handled_outputs: Sequence[type[SupportedType]] = (String, StreamingString)
    converts_outputs_with_preprocessor = True

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: LLMConfig | None = None,
        db_client: DBClient | None = None,
        trigger: TriggerType = 1.0,
        component_name: str = "llm",
        **kwargs: Any,
    ) -> None:
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config,
                         trigger=trigger, component_name=component_name, db_client=db_client, **kwargs)
        self.config: LLMConfig
        if self.config.enable_rag and db_client is None:
            raise WiringError(f"component {self.component_name!r}: config.enable_rag needs a db_client")
        #: The conversation so far (user and assistant turns; the system prompt is kept apart).
        self.messages: list[dict[str, Any]] = []
        # Prompts are plain text, not HTML: no autoescaping. A variable the template names but the inputs
        # lack renders empty, as upstream (its recipes rely on it: a Detections input that has not arrived).
        self._env = jinja2.Environment(autoescape=False)
        self._topic_templates: dict[str, jinja2.Template] = {}
        self._component_template: jinja2.Template | None = None
        self._tools: dict[str, _Tool] = {}
        self._mcp_toolboxes: list[Any] = []  # connections to config.mcp_servers, open while configured
        self._rag_where: dict[str, Any] | None = None  # a metadata filter for RAG (set_rag_filter)

    # -- prompts ------------------------------------------------------------------------------

    def set_system_prompt(self, prompt: str | None) -> None:
        """Set (or clear, with None) the system prompt; it survives history resets."""
        self.config.system_prompt = prompt

    @setup_method
    def set_topic_prompt(self, input_topic: Topic, template: str | Path) -> None:
        """Render the text of ``input_topic`` through a Jinja2 template before it is sent.

        ``template`` is the template text or a path to a file holding it. Variables are the input
        topic names (with characters other than letters, digits and ``_`` turned into ``_``), e.g.
        ``"Answer briefly: {{ question }}"`` for a topic named ``question``.
        """
        if not any(t.name == input_topic.name for t in self.inputs):
            raise WiringError(f"component {self.component_name!r}: {input_topic.name!r} is not one of its inputs")
        self._topic_templates[input_topic.name] = self._compile(template, f"prompt of topic {input_topic.name!r}")

    @setup_method
    def set_component_prompt(self, template: str | Path) -> None:
        """Build every query from one Jinja2 template over all input topics (see :meth:`set_topic_prompt`)."""
        self._component_template = self._compile(template, "component prompt")

    def _compile(self, template: str | Path, what: str) -> jinja2.Template:
        text = str(template)
        if isinstance(template, Path) or (len(text) < 4096 and "{" not in text and Path(text).is_file()):
            text = Path(text).read_text(encoding="utf-8")
        try:
            return self._env.from_string(text)
        except jinja2.TemplateSyntaxError as exc:
            raise ConfigError(f"component {self.component_name!r}: {what} is not a valid Jinja2 template: "
                              f"{exc}") from exc

    def _input_values(self) -> dict[str, Any]:
        values: dict[str, Any] = {}
        for name, cb in {**self.callbacks, **self.trig_callbacks}.items():
            value = cb.get_output()
            if value is None:
                continue
            if isinstance(value, DetectionsMsg):
                value = ", ".join(value.labels) if value.labels else "nothing"
            elif isinstance(cb, DetectionsCallback) and isinstance(value, list) \
                    and all(isinstance(d, dict) and "label" in d for d in value):
                # A Detections input reads as its labels in a prompt, as upstream's context string.
                value = ", ".join(d["label"] for d in value) if value else "nothing"
            values[_variable_name(name)] = value
        return values

    def _render(self, template: jinja2.Template, values: Mapping[str, Any], what: str) -> str:
        try:
            return template.render(**values)
        except jinja2.UndefinedError as exc:
            # A missing variable renders empty, but reading into one ({{ pose.x }}) cannot: say which.
            raise AlgorithmFailure(f"component {self.component_name!r}: {what} needs a value that has not "
                                   f"arrived yet: {exc}") from exc

    def _query_text(self, topic: Topic | None) -> str | None:
        values = self._input_values()
        text_topics = [t for t in self.inputs if issubclass(t.msg_type, String)]
        source = topic if topic is not None and issubclass(topic.msg_type, String) else next(
            (t for t in text_topics if _variable_name(t.name) in values), None)
        if source is None:
            return None
        query = values.get(_variable_name(source.name))
        if query is None:
            return None
        if source.name in self._topic_templates:
            query = self._render(self._topic_templates[source.name], values, f"prompt of {source.name!r}")
            values[_variable_name(source.name)] = query
        if self._component_template is not None:
            query = self._render(self._component_template, values, "component prompt")
        else:
            # Without a component template, detections still reach the model, as a short preface.
            seen = [f"{t.name}: {values[_variable_name(t.name)]}" for t in self.inputs
                    if issubclass(t.msg_type, Detections) and _variable_name(t.name) in values]
            if seen:
                query = "Objects detected (" + "; ".join(seen) + f").\n{query}"
        return str(query)

    # -- tools ----------------------------------------------------------------------------------

    @setup_method
    def register_tool(self, tool: Callable[..., Any], tool_description: Mapping[str, Any] | None = None,
                      send_tool_response_to_model: bool = False) -> None:
        """Let the model call ``tool``.

        :param tool_description: an OpenAI-style description, ``{"type": "function", "function":
            {"name", "description", "parameters"}}`` (or just the inner ``function`` dict); the
            name must be the function's name. None: the one a ``@component_action`` carries, else one
            built from the function's signature and docstring
            (:func:`agents_core.declarations.action_schema.action_schema`).
        :param send_tool_response_to_model: give the tool's result back to the model so it can
            answer with it; otherwise the result itself is published on the outputs.
        """
        if not callable(tool):
            raise ConfigError(f"component {self.component_name!r}: tool must be callable, got {tool!r}")
        if tool_description is None:
            tool_description = getattr(tool, ACTION_MARK, None)
        if tool_description is None:
            try:
                tool_description = describe_action(tool)
            except (TypeError, ValueError, AttributeError):
                raise ConfigError(f"component {self.component_name!r}: {tool!r} has no signature to describe; "
                                  "pass a tool_description") from None
        function = dict(tool_description.get("function", tool_description))
        name = function.get("name")
        if name != getattr(tool, "__name__", name):
            raise ConfigError(f"component {self.component_name!r}: tool description names {name!r} but the "
                              f"function is {tool.__name__!r}")
        if not isinstance(name, str) or not name:
            raise ConfigError(f"component {self.component_name!r}: a tool description needs a 'name'")
        if "parameters" in function and not isinstance(function["parameters"], dict):
            raise ConfigError(f"component {self.component_name!r}: tool {name!r}: 'parameters' must be a "
                              "JSON schema dict")
        self._tools[name] = _Tool(tool, {"type": "function", "function": function}, send_tool_response_to_model)

    def custom_on_configure(self) -> None:
        super().custom_on_configure()
        self._connect_mcp_servers()

    def custom_on_shutdown(self) -> None:
        self._disconnect_mcp_servers()
        super().custom_on_shutdown()

    def _connect_mcp_servers(self) -> None:
        """Offer the tools of ``config.mcp_servers`` to the model (replacing those of an earlier configure)."""
        self._disconnect_mcp_servers()
        if not self.config.mcp_servers:
            return
        from ..mcp.client import open_toolboxes  # noqa: PLC0415  (the mcp extra, only when servers are given)

        self._mcp_toolboxes = open_toolboxes(self.config.mcp_servers)
        try:
            for box in self._mcp_toolboxes:
                for tool in box.tools():
                    # The server's answer goes back to the model, which answers with it (as a tool should).
                    self._tools[tool.__name__] = _Tool(tool, tool.description, True)
                self._logger.info("MCP server %r: %d tool(s) offered to the model", box.spec.name,
                                  sum(1 for t in self._tools.values() if getattr(t.func, "_box", None) is box))
        except BaseException:  # a listing that failed (too large, timed out): no connection is left open
            self._disconnect_mcp_servers()
            raise

    def _disconnect_mcp_servers(self) -> None:
        boxes, self._mcp_toolboxes = self._mcp_toolboxes, []
        for box in boxes:
            self._tools = {k: t for k, t in self._tools.items() if getattr(t.func, "_box", None) is not box}
            box.close()

    def _tool_descriptions(self) -> list[dict[str, Any]]:
        if not self._tools:
            return []
        if self.model_client is not None and not self.model_client.supports_tool_calls:
            self._logger.warning("model client %s does not support tool calls; tools are not offered",
                                 type(self.model_client).__name__)
            return []
        return [t.description for t in self._tools.values()]

    def _run_tool(self, call: Mapping[str, Any]) -> tuple[_Tool | None, Any]:
        """The tool's return value (an error text when it failed or does not exist)."""
        name = call["function"]["name"]
        tool = self._tools.get(name)
        if tool is None:
            return None, f"error: there is no tool named {name!r}"
        tel = _telemetry.hooks
        if tel is None:
            return self._call_tool(tool, call)
        with tel.call("tool", name):
            return self._call_tool(tool, call)

    def _call_tool(self, tool: _Tool, call: Mapping[str, Any]) -> tuple[_Tool | None, Any]:
        name = call["function"]["name"]
        try:
            if isinstance(tool.func, ComponentMethod):  # another process's action (multiprocessing=True)
                return tool, tool.func.call(self.runtime.transport, call["function"]["arguments"])
            return tool, tool.func(**call["function"]["arguments"])
        except Exception as exc:
            # The model gets to see what went wrong and may try again differently.
            self._logger.warning("tool %s(%s) raised %s: %s", name, call["function"]["arguments"],
                                 type(exc).__name__, exc)
            return tool, f"error: {type(exc).__name__}: {exc}"

    def _check_outputs_converted(self) -> None:
        # A tool whose own return value is the answer (send_tool_response_to_model=False) may feed
        # an output of any type: the value is validated against it when published.
        if any(not tool.send_back for tool in self._tools.values()):
            return
        super()._check_outputs_converted()

    def _publish_tool_result(self, value: Any) -> None:
        """A tool's own return value on the outputs (``send_tool_response_to_model=False``), as upstream:
        an output with a pre-processor gets the value itself (to turn into its type, e.g. a list into a
        PoseStamped); a text output without one gets its JSON text."""
        if isinstance(value, str):
            self._publish_answer(value)
            return
        for pub in self.publishers_dict.values():
            if pub.has_preprocessors or not issubclass(pub.topic.msg_type, String):
                pub.publish(value)
                continue
            text = json.dumps(value, default=str)
            streaming = issubclass(pub.topic.msg_type, StreamingString)
            pub.publish(StreamingStringMsg(data=text, stream=False, done=True) if streaming else text)

    # -- RAG ------------------------------------------------------------------------------------

    @component_action
    def add_documents(self, ids: list[str], documents: list[str],
                      metadatas: list[dict[str, Any]] | None = None) -> bool:
        """Add documents to the component's vector database (used for RAG)."""
        if self.db_client is None:
            raise WiringError(f"component {self.component_name!r} has no db_client to add documents to")
        db_input: dict[str, Any] = {"collection_name": self._collection(), "ids": list(ids),
                                    "documents": list(documents), "distance_func": self.config.distance_func}
        if metadatas is not None:
            db_input["metadatas"] = list(metadatas)
        self._ensure_db_ready()
        self.db_client.add(db_input)
        return True

    @setup_method
    def set_rag_filter(self, where: dict[str, Any] | None) -> bool:
        """Only use documents whose metadata match ``where`` for RAG (e.g. ``{"layer": "detections"}`` on a
        MapEncoding collection); None: all documents."""
        if where is not None and (not isinstance(where, dict) or not where):
            raise ConfigError(f"component {self.component_name!r}: the RAG filter must be a non-empty dict or None")
        self._rag_where = dict(where) if where is not None else None
        return True

    def _collection(self) -> str:
        return self.config.collection_name or self.component_name.replace("/", "_")

    def _rag_context(self, query: str) -> str | None:
        if not (self.config.enable_rag and self.db_client is not None):
            return None
        db_input: dict[str, Any] = {"collection_name": self._collection(), "query": query,
                                    "n_results": self.config.n_results}
        if self._rag_where is not None:
            db_input["where"] = self._rag_where
        self._ensure_db_ready()  # down at configure: it may be back
        found = self.db_client.query(db_input)
        documents = list(found.get("documents") or [])
        metadatas = list(found.get("metadatas") or [None] * len(documents))
        if not documents:
            return None
        lines = []
        for doc, meta in zip(documents, metadatas, strict=False):
            lines.append(f"- {doc}" + (f" (metadata: {json.dumps(meta)})" if self.config.add_metadata and meta else ""))
        return "\n".join(lines)

    # -- the step -------------------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        query = self._query_text(kwargs.get("topic"))
        if query is None or not query.strip():
            return
        if query.strip().lower() == self.config.history_reset_phrase.lower():
            self.messages.clear()
            self._logger.info("chat history cleared")
            return
        self._answer(query)

    def _answer(self, query: str) -> str | None:
        """Ask the model ``query`` (with history and context), publish and remember the answer."""
        inference_input = self._create_input(query)
        if inference_input is None:
            return None
        answer = self._converse(inference_input)
        if answer is not None and self.config.chat_history:
            self._remember(query, answer)
        return answer

    def _create_input(self, query: str, images: Sequence[Any] | None = None, **kwargs: Any) -> dict[str, Any] | None:
        context = self._rag_context(query)
        content = f"Use this context if it helps:\n{context}\n\n{query}" if context else query
        user: dict[str, Any] = {"role": "user", "content": content}
        if images:
            user["images"] = list(images)
        messages: list[dict[str, Any]] = []
        if self.config.system_prompt:
            messages.append({"role": "system", "content": self.config.system_prompt})
        if self.config.chat_history:
            messages.extend(self.messages)
        messages.append(user)
        inference_input = {"query": messages, **self.inference_params}
        tools = self._tool_descriptions()
        if tools:
            inference_input["tools"] = tools
        return inference_input

    def _converse(self, inference_input: dict[str, Any]) -> str | None:
        """Call the model until it stops calling tools; publish and return the final answer."""
        messages = inference_input["query"]
        for _ in range(self.config.max_tool_rounds):
            result = self._call_inference(inference_input)
            calls = result.get("tool_calls") or []
            if not calls:
                return self._publish_answer(result["output"])
            text = result["output"] if isinstance(result["output"], str) else "".join(result["output"])
            messages.append({"role": "assistant", "content": text, "tool_calls": list(calls)})
            answer_again = False
            for call in calls:
                tool, output = self._run_tool(call)
                if tool is None or tool.send_back:
                    content = output if isinstance(output, str) else json.dumps(output, default=str)
                    messages.append({"role": "tool", "tool_call_id": call["id"], "name": call["function"]["name"],
                                     "content": content})
                    answer_again = True
                else:
                    self._publish_tool_result(output)
            if not answer_again:
                return None
        raise AlgorithmFailure(f"component {self.component_name!r}: the model was still calling tools after "
                               f"{self.config.max_tool_rounds} rounds (config.max_tool_rounds)")

    def _remember(self, query: str, answer: str) -> None:
        # Only text goes into the history: images are large and stale by the next question.
        self.messages.append({"role": "user", "content": query})
        self.messages.append({"role": "assistant", "content": answer})
        excess = len(self.messages) - self.config.history_size
        if excess > 0:
            del self.messages[:excess]
        # Never let the history start with an orphan answer.
        while self.messages and self.messages[0]["role"] != "user":
            self.messages.pop(0)

    # -- publishing -----------------------------------------------------------------------------

    def _text_publishers(self) -> tuple[list[Any], list[Any]]:
        streaming = [p for p in self.publishers_dict.values() if issubclass(p.topic.msg_type, StreamingString)]
        # Text outputs, and outputs whose pre-processor converts the text (checked at configure).
        plain = [p for p in self.publishers_dict.values() if not issubclass(p.topic.msg_type, StreamingString)
                 and (issubclass(p.topic.msg_type, String) or p.has_preprocessors)]
        return streaming, plain

    def _publish_answer(self, output: str | Iterable[str]) -> str:
        if isinstance(output, str):
            text = output
            if self.config.strip_think_tokens:
                stripper = ThinkStripper()
                text = stripper.feed(text) + stripper.flush()
            text = text.strip()
            streaming, plain = self._text_publishers()
            for pub in plain:
                pub.publish(text)
            for pub in streaming:
                pub.publish(StreamingStringMsg(data=text, stream=False, done=True))
            return text
        return self._publish_stream(output)

    def _publish_stream(self, chunks: Iterable[str]) -> str:
        """Publish a streamed answer as it arrives; returns the whole visible text.

        StreamingString outputs get each visible piece (``done=False``) and then an empty
        ``done=True`` message. When the stream fails midway (the server dropped, a stream timeout
        passed), the listeners still get that closing ``done=True`` message, with empty text (the
        partial answer has already gone out piece by piece), and then the error is raised again,
        so the step fails: the health becomes ALGORITHM_FAILURE (COMPONENT_FAILURE when the
        server cannot be reached at all) and the fallbacks run. The
        unfinished sentence held for String outputs is not published then.
        """
        streaming, plain = self._text_publishers()
        stripper = ThinkStripper() if self.config.strip_think_tokens else None
        parts: list[str] = []
        pending = ""
        brk = self.config.break_character
        try:
            for chunk in chunks:
                if self.lifecycle_state != LifecycleState.ACTIVE:
                    self._logger.info("deactivated while streaming: answer cut short")
                    break
                visible = stripper.feed(chunk) if stripper else chunk
                if not visible:
                    continue
                if not parts:
                    visible = visible.lstrip()  # models often open with a newline
                    if not visible:
                        continue
                parts.append(visible)
                for pub in streaming:
                    pub.publish(StreamingStringMsg(data=visible, stream=True, done=False))
                pending += visible
                while brk in pending:
                    cut = pending.index(brk) + len(brk)
                    sentence, pending = pending[:cut].strip(), pending[cut:]
                    if sentence:
                        for pub in plain:
                            pub.publish(sentence)
        except Exception:
            # Listeners must never wait for a "done" that does not come.
            self._close_streams(streaming)
            raise
        finally:
            close = getattr(chunks, "close", None)
            if callable(close):
                close()
        tail = stripper.flush() if stripper else ""
        if tail:
            parts.append(tail)
            pending += tail
            for pub in streaming:
                pub.publish(StreamingStringMsg(data=tail, stream=True, done=False))
        if pending.strip():
            for pub in plain:
                pub.publish(pending.strip())
        for pub in streaming:
            pub.publish(StreamingStringMsg(data="", stream=True, done=True))
        return "".join(parts).strip()

    def _close_streams(self, streaming: list[Any]) -> None:
        """The closing ``done=True`` message after a failed stream (a publish failing here is logged only)."""
        for pub in streaming:
            try:
                pub.publish(StreamingStringMsg(data="", stream=True, done=True))
            except Exception as exc:  # the stream's own error is the one to report
                self._logger.debug("closing message of a failed stream not published: %s", exc)

    # -- local model and warm-up ------------------------------------------------------------------

    def _deploy_local_model(self) -> None:
        from ..engines.local_llm import LocalLLM  # noqa: PLC0415  (llama-cpp-python is optional)

        self.local_model = LocalLLM(model_path=self.config.local_model_path, device=self.config.device_local_model,
                                    ncpu=self.config.ncpu_local_model)

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        result = self._call_inference({"query": [{"role": "user", "content": "Hello"}], "max_new_tokens": 4,
                                       "temperature": 0.0, "stream": False})
        output = result["output"]
        if not isinstance(output, str):
            for _ in output:  # drain the stream so the connection is released
                pass
