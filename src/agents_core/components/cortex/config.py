"""``CortexConfig``: the settings of the :class:`~agents_core.components.cortex.Cortex` planner.

It lives with its component (``agents_core.config`` re-exports it on first use) so the shared
config module does not grow past its size and does not import the components.
"""

from __future__ import annotations

from typing import Any

from attrs import define, field

from ... import base_validators
from ..llm_config import LLMConfig

__all__ = ["CortexConfig"]


@define(kw_only=True)
class CortexConfig(LLMConfig):
    """Settings of the Cortex task planner and executor.

    A task runs as plan-execute *iterations*: the planner model (with every tool offered) either
    researches (``inspect_component`` and planning-phase tools, answered and fed back) or returns
    the steps of a plan; each step is confirmed by a short model call before it is dispatched; the
    results go back to the planner, which may plan more steps or answer in text to finish.

    :param max_planning_steps: the most planner calls in one planning phase (research rounds and
        rejected plans included); a planner still researching after that ends the task, aborted.
    :param max_execution_steps: the most steps of one plan (longer plans are cut) and the most
        plan-execute iterations of one task; at most ``max_execution_steps ** 2`` steps run.
    :param confirmation_temperature: sampling temperature of the confirmation calls.
    :param confirmation_max_tokens: the most tokens of a confirmation answer (room for a tool call
        that rewrites the next step's arguments).
    :param confirmation_timeout: seconds a confirmation call may take; a later answer is an ABORT
        (the task fails closed rather than acting unconfirmed).
    :param monitoring_interval: seconds between checks of the goals a task started while the
        confirmation model answers CONTINUE (wait for them).
    :param dispatch_timeout: seconds a component action (``execute_method``) may take.
    :param goal_accept_timeout: seconds a component's action server may take to accept a goal.
    :param discovery_timeout: seconds to look for components on the transport when a task starts.
    :param planning_tools: names of component actions (``"<component>.<method>"``) used while
        planning, to research, instead of as plan steps; a component action whose description says
        ``"phase": "planning"`` (or ``"both"``) is one without being listed.
    :param action_servers: action-server components the planner may send goals to, with their
        action type (``{"navigation": "NavigateToPose"}``), for components whose ``describe`` does
        not name their action type.
    :param allowed_components: the components whose actions and goals the planner is offered.
        None (the default): the components of Cortex's own recipe (the Launcher tells Cortex their
        names when they are added); ``["*"]``: any component the transport shows (peers from other
        recipes included, an explicit opt-in); a list: those names only. Components named in
        ``action_servers`` are always allowed. Another component is neither described nor offered.
    :param task_timeout: seconds one task may run, planning and execution together (600 by
        default); past it the task is aborted, its goals canceled, and the next task accepted.
    :param max_confirmation_rounds: how many times in a row the confirmation model may answer
        CONTINUE for one step (20 by default); one more is an ABORT of the task.
    :param mcp_servers: (from :class:`LLMConfig`) MCP servers whose tools the planner is offered
        as ``<server>__<tool>`` plan steps (research tools when named in ``planning_tools``), under
        their guardrails (``allow``, ``limits``, ``approval``, ``rate_limit``); connected at configure.
    :param recipe_components: set by the Launcher (the names of the recipe's components); leave it
        None and use ``allowed_components``.

    ``chat_history`` and ``stream`` are ignored: the planner keeps its own conversation per task
    and never streams.
    """

    max_planning_steps: int = field(default=10, validator=base_validators.in_range(1, 1000))
    max_execution_steps: int = field(default=10, validator=base_validators.in_range(1, 1000))
    confirmation_temperature: float = field(default=0.3, validator=base_validators.in_range(0.0, 2.0))
    confirmation_max_tokens: int = field(default=500, validator=base_validators.in_range(1, 1_000_000))
    confirmation_timeout: float = field(default=30.0, validator=base_validators.gt(0.0))
    monitoring_interval: float = field(default=2.0, validator=base_validators.gt(0.0))
    dispatch_timeout: float = field(default=30.0, validator=base_validators.gt(0.0))
    goal_accept_timeout: float = field(default=5.0, validator=base_validators.gt(0.0))
    discovery_timeout: float = field(default=1.0, validator=base_validators.gt(0.0))
    planning_tools: list[str] = field(factory=list)
    action_servers: dict[str, str] = field(factory=dict)
    allowed_components: list[str] | None = None
    task_timeout: float = field(default=600.0, validator=base_validators.gt(0.0))
    max_confirmation_rounds: int = field(default=20, validator=base_validators.in_range(1, 100_000))
    recipe_components: list[str] | None = None

    def _get_inference_params(self) -> dict[str, Any]:
        # The planner reads whole answers (tool calls arrive whole): never streamed.
        return {"temperature": self.temperature, "max_new_tokens": self.max_new_tokens, "stream": False}

    def _get_confirmation_params(self) -> dict[str, Any]:
        """The parameters of a confirmation call."""
        return {"temperature": self.confirmation_temperature, "max_new_tokens": self.confirmation_max_tokens,
                "stream": False}
