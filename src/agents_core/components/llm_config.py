"""``LLMConfig``: the settings of ``LLM`` (:mod:`agents_core.components.llm`), beside it.

Public as ``agents_core.config.LLMConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from typing import Any

from attrs import define, field

from .. import base_validators
from ..config import ModelComponentConfig
from ..errors import ConfigError

__all__ = ["LLMConfig"]


def _mcp_servers(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, list):
        raise ConfigError(f"{type(instance).__name__}.mcp_servers: expected a list of MCP servers, got {value!r}")
    if value:
        from ..mcp.client import server_spec  # noqa: PLC0415  (checked where given: a bad entry fails early)

        for entry in value:
            server_spec(entry)


@define(kw_only=True)
class LLMConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.llm.LLM` component.

    :param system_prompt: the first message of every conversation (None: none).
    :param chat_history: keep the conversation between steps.
    :param history_size: how many past messages (user and assistant) the history keeps.
    :param history_reset_phrase: a query equal to this (case-insensitive) clears the history; the
        system prompt stays.
    :param temperature: sampling temperature.
    :param max_new_tokens: the most tokens one answer may have.
    :param stream: publish the answer while it is generated: chunk by chunk on StreamingString
        outputs, sentence by sentence (split at ``break_character``) on String outputs.
    :param break_character: where a streamed answer is cut for String outputs.
    :param strip_think_tokens: remove ``<think>...</think>`` blocks (reasoning models) from answers.
    :param max_tool_rounds: the most model calls in one step when the model keeps calling tools.
    :param enable_rag: look up the query in the component's vector database and give the model
        the ``n_results`` closest documents as context.
    :param collection_name: the database collection used for RAG.
    :param distance_func: ``"l2"``, ``"cosine"`` or ``"ip"``: the metric of the RAG collection when
        ``add_documents`` creates it (an existing collection keeps its own).
    :param n_results: how many documents RAG adds.
    :param add_metadata: also give the model the documents' metadata.
    :param mcp_servers: MCP servers whose tools the model may call (the ``mcp`` extra): each a URL
        (Streamable HTTP), a command line as a list (stdio) or a mapping of
        :class:`agents_core.mcp.client.McpServerSpec` fields (``allow``, ``limits``, ``approval``, ...).
    """

    system_prompt: str | None = field(default=None, validator=base_validators.optional_str)
    chat_history: bool = field(default=False)
    history_size: int = field(default=10, validator=base_validators.in_range(2, 10_000))
    history_reset_phrase: str = field(default="chat reset", validator=base_validators.non_empty_str)
    temperature: float = field(default=0.8, validator=base_validators.in_range(0.0, 2.0))
    max_new_tokens: int = field(default=500, validator=base_validators.in_range(1, 1_000_000))
    mcp_servers: list[Any] = field(factory=list, validator=_mcp_servers)
    stream: bool = field(default=False)
    break_character: str = field(default=".", validator=base_validators.non_empty_str)
    strip_think_tokens: bool = field(default=True)
    max_tool_rounds: int = field(default=5, validator=base_validators.in_range(1, 100))
    enable_rag: bool = field(default=False)
    collection_name: str | None = field(default=None, validator=base_validators.optional_str)
    distance_func: str = field(default="l2", validator=base_validators.in_(["l2", "cosine", "ip"]))
    n_results: int = field(default=1, validator=base_validators.in_range(1, 1000))
    add_metadata: bool = field(default=False)

    def _get_inference_params(self) -> dict[str, Any]:
        return {"temperature": self.temperature, "max_new_tokens": self.max_new_tokens, "stream": self.stream}

