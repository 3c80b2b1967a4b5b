"""``Cortex``: plans and carries out tasks over the actions of the other components; the system monitor.

Cortex is an action server (``VisionLanguageAction`` goals: the goal's ``task`` is the sentence
to carry out; feedback ``status`` narrates each step; the result says what happened). A task
runs as plan-execute iterations (:mod:`.planner`, :mod:`.executor`), at most
``max_execution_steps`` of them, until the planner answers in text.

The tools the models are offered (:mod:`.tools`) are found when each task starts: the recipe's
``actions``, and every component the transport can see (``discover``), described through its
``describe`` service: its ``@component_action`` methods (``"<component>.<method>"``) and, for an
action-server component whose action type is known, its goals (``"<component>.send_goal"``).
``inspect_component`` lets the planner read a component's description. So a Cortex needs no
import of the components it drives, and drives them in this process or in others alike.

Tasks also arrive as text on the String topic ``<component_name>/task``
(:attr:`Cortex.ui_main_action_input`, the web UI's text box): each message is sent to the
action server as a goal, as any client would send it.

Cortex watches the status topic of every component it found (:mod:`.monitor`); a task is
aborted when a component it depends on fails. A cancel stops the task between steps and
cancels the goals it started.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ...actions import Action
from ...clients.db_base import DBClient
from ...clients.model_base import ModelClient
from ...errors import ComponentError, ConfigError, WiringError
from ...runtime.run_type import ComponentRunType
from ...status import LifecycleState
from ...supported_types import StreamingString, String
from ...topics import Topic
from ...transport.contract import Subscription
from ...transport.goals import ACTION_TYPES, action_type
from ...transport.graph import describe_component
from ..model_component import ModelComponent
from ..wiring import AllowedTypes
from .config import CortexConfig
from .dispatch import Dispatcher
from .executor import Executor
from .monitor import HealthWatch
from .peers import DescribeRefused, allowed, as_data, checked_description
from .planner import PLANNING_PROMPT, Planner
from .tools import INSPECT, Tool, ToolBox, goal_schema
from .transfer import ACTION_CODEC  # noqa: F401  (registers how its actions cross to a component process)

if TYPE_CHECKING:
    from ...transport.goals import GoalHandle

__all__ = ["Cortex"]

#: The longest task text taken from the task topic (longer text is cut).
MAX_TASK_CHARS = 4000


def _first_paragraph(text: str | None) -> str:
    return (text or "").strip().split("\n\n")[0].replace("\n", " ").strip()


class Cortex(ModelComponent):
    """A task planner and executor over the recipe's actions and the components' actions.

    :param actions: Actions the planner may run as plan steps; each needs a description (an
        ``action.description`` attribute, else its method's docstring). Their arguments are the
        ones fixed in the Action.
    :param output: a String / StreamingString topic for answers that need no action.
    :param model_client: the planner model (with tool calls), or None with ``config.enable_local_model``.
    :param db_client: a vector database for RAG context while planning (``config.enable_rag``).
    :param config: a :class:`~agents_core.config.CortexConfig`.
    :param component_name: the component's name; tasks go to its action server of that name.
    """

    config_class = CortexConfig
    handled_outputs = (String, StreamingString)
    _action_type = "VisionLanguageAction"

    def __init__(self, *, actions: Sequence[Action] | None = None, output: Topic | None = None,
                 model_client: ModelClient | None = None, db_client: DBClient | None = None,
                 config: CortexConfig | None = None, component_name: str = "cortex", **kwargs: Any) -> None:
        for ignored in ("inputs", "outputs", "trigger"):
            if ignored in kwargs:
                raise WiringError(f"component {component_name!r}: a Cortex takes no {ignored!r}; tasks arrive as goals")
        kwargs.setdefault("run_type", ComponentRunType.ACTION_SERVER)
        self.allowed_outputs: AllowedTypes = {"Required": [], "Optional": [String, StreamingString]}
        super().__init__(inputs=None, outputs=[output] if output is not None else None, model_client=model_client,
                         config=config, trigger=None, component_name=component_name, db_client=db_client, **kwargs)
        self.config: CortexConfig
        if self.config.enable_rag and db_client is None:
            raise WiringError(f"component {self.component_name!r}: config.enable_rag needs a db_client")
        self._tools = ToolBox()
        self._tools.add(self._inspect_tool([]))
        self._mcp_boxes: list[Any] = []  # connections to config.mcp_servers, open while configured
        for action in actions or []:
            self._add_action(action)
        self._described: dict[str, dict[str, Any]] = {}
        self._refused: set[str] = set()
        self._watch = HealthWatch(self._logger)
        self._dispatcher: Dispatcher | None = None
        self._executor: Executor | None = None
        self._planner = Planner(self._tools, self._call_inference, self._research, self._logger)
        self._task_lock = threading.Lock()
        self._running: GoalHandle | None = None
        self._task_inbox: Subscription | None = None
        #: Tasks finished, by outcome.
        self.tasks = {"succeeded": 0, "aborted": 0, "canceled": 0}

    @classmethod
    def _server_capable(cls) -> bool:
        return True

    # -- tools --------------------------------------------------------------------------------------

    def _add_action(self, action: Action) -> None:
        if not isinstance(action, Action):
            raise WiringError(f"component {self.component_name!r}: actions must be Action objects, got "
                              f"{type(action).__name__}")
        description = getattr(action, "description", None) or _first_paragraph(action.method.__doc__)
        if not description:
            raise ConfigError(f"component {self.component_name!r}: action {action.name!r} needs a description "
                              "(a docstring on its method) for the planner")
        owner = action.owner
        component = getattr(owner, "component_name", None)
        name = f"{component}.{action.name}" if component else action.name
        if not self._tools.add(Tool(name=name, kind="action", description=description, component=component,
                                    action=action)):
            raise WiringError(f"component {self.component_name!r}: two actions are named {name!r}")

    def _inspect_tool(self, components: list[str]) -> Tool:
        known = f" Known components: {', '.join(components)}." if components else ""
        return Tool(name=INSPECT, kind="inspect", planning=True,
                    description="Describe a component: its state, health, input and output topics and actions." + known,
                    parameters={"type": "object", "properties": {"component": {"type": "string"}},
                                "required": ["component"], "additionalProperties": False})

    @property
    def tool_names(self) -> list[str]:
        """The names of every tool the planner is offered now."""
        return self._tools.names()

    def refresh_components(self) -> list[str]:
        """Find the components on the transport, offer their actions and goals, watch their health.

        Called when each task starts; returns the components known. A component that does not
        answer ``describe`` is left out (and tried again next time).
        """
        transport = self.transport
        names: set[str] = set(self.config.action_servers)
        if transport.capabilities.discovery:
            try:
                names.update(transport.discover(self.config.discovery_timeout).components)
            except Exception as exc:  # the task may still use the actions it was given
                self._logger.warning("component discovery failed: %s", exc)
        names.discard(self.component_name)
        for name in sorted(names - set(self._described)):
            if not self._allowed(name):
                if name not in self._refused:
                    self._refused.add(name)
                    self._logger.info("component %r is not in allowed_components (default: this recipe's "
                                      "components); its actions are not offered", name)
                continue
            try:
                self._described[name] = self._describe(name)
            except Exception as exc:
                self._logger.info("component %r does not describe itself (%s); its actions are not offered", name, exc)
                continue
            self._offer(name, self._described[name])
        known = sorted(self._described)
        self._tools.add(self._inspect_tool(known), replace=True)
        self._watch.watch(transport, [*known, *(t.component for t in self._tool_list() if t.component)],
                          self.component_name)
        return known

    def set_recipe_components(self, names: Sequence[str]) -> None:
        """The names of the components of this Cortex's recipe (the Launcher calls it at ``add_pkg``).

        With ``allowed_components`` None they are the components whose actions are offered.
        """
        self.config.recipe_components = [n for n in names if n != self.component_name]

    def _allowed(self, name: str) -> bool:
        owners = {a.component for a in self._tool_list() if a.kind == "action" and a.component}
        return allowed(name, self.config.allowed_components, self.config.recipe_components,
                       always={*self.config.action_servers, *owners})

    def _describe(self, name: str) -> dict[str, Any]:
        """Component ``name``'s describe reply, its shape checked (:func:`~.peers.checked_description`)."""
        return checked_description(name, describe_component(self.transport, name,
                                                            timeout=self.config.discovery_timeout))

    def _tool_list(self) -> list[Tool]:
        return [t for t in (self._tools.get(n) for n in self._tools.names()) if t is not None]

    def _offer(self, name: str, description: dict[str, Any]) -> None:
        for method, raw in description["actions"].items():  # shape checked by checked_description
            function = raw["function"]
            tool_name = f"{name}.{method}"
            phase = raw.get("phase") or function.get("phase")
            parameters = function.get("parameters")
            self._tools.add(Tool(
                name=tool_name, kind="component_action", component=name, target=method,
                description=str(function.get("description") or method),
                parameters=parameters if isinstance(parameters, dict) else {"type": "object", "properties": {}},
                planning=tool_name in self.config.planning_tools or phase in ("planning", "both")))
        type_name = description.get("action_type") or self.config.action_servers.get(name)
        if description.get("run_type") == ComponentRunType.ACTION_SERVER.value or name in self.config.action_servers:
            if not type_name or type_name not in ACTION_TYPES:
                self._logger.info("component %r serves goals of an unknown type %r; not offered (name it in "
                                  "CortexConfig.action_servers)", name, type_name)
                return
            definition = action_type(type_name)
            self._tools.add(Tool(name=f"{name}.send_goal", kind="goal", component=name, target=type_name,
                                 description=f"Send a {type_name} goal to {name!r}; it runs in the background.",
                                 parameters=goal_schema(definition)))

    def _research(self, tool: Tool, arguments: dict[str, Any]) -> str:
        if tool.kind == "inspect":
            return self.inspect_component(str(arguments.get("component", "")))
        if tool.kind == "mcp":
            from .mcp_tools import call_mcp_tool  # noqa: PLC0415

            return call_mcp_tool(tool, arguments)
        assert self._dispatcher is not None and tool.component is not None
        return self._dispatcher.call_component(tool.component, tool.target, arguments)

    def inspect_component(self, component: str) -> str:
        """A text description of ``component`` (from its ``describe`` service) and the tools acting on it."""
        if not self._allowed(component):
            return f"error: component {component!r} is not one this Cortex may use (allowed_components)"
        try:
            info = self._describe(component)
        except DescribeRefused as exc:
            return f"error: {exc}"
        except Exception as exc:
            return f"error: component {component!r} did not answer ({exc}); known: {sorted(self._described)}"
        lines = [f"{info['name']} ({info['component_type']}): {info['state']}, {info['health']}",
                 "inputs: " + ", ".join(f"{t['name']} ({t['msg_type']})" for t in info["inputs"]),
                 "outputs: " + ", ".join(f"{t['name']} ({t['msg_type']})" for t in info["outputs"])]
        tools = self._tools.of_component(component)
        lines.append("tools: " + ("; ".join(f"{t.name}{json.dumps(t.parameters.get('properties', {}))}: "
                                            f"{t.description}" for t in tools) or "none"))
        return "\n".join(lines)

    def component_health(self) -> dict[str, dict[str, str]]:
        """The latest state and health of every component Cortex watches."""
        return self._watch.status()

    @property
    def ui_main_action_input(self) -> Topic:
        """The String topic whose messages become tasks: upstream's UI input for the main action server.

        ``launcher.enable_ui(inputs=[cortex.ui_main_action_input])`` gives the web UI a text box;
        each text published there is sent to this Cortex as a ``VisionLanguageAction`` goal.
        """
        return Topic(name=f"{self.component_name}/task", msg_type="String")

    def _on_task_text(self, msg: Any) -> None:
        task = str(getattr(msg, "data", msg)).strip()[:MAX_TASK_CHARS]
        if not task:
            return

        def send() -> None:
            # Off the subscription's thread: sending waits (bounded) for the server to accept.
            try:
                goal = self.transport.send_goal(self.component_name, self._action_type, {"task": task}, timeout=5.0)
            except Exception as exc:
                self._logger.warning("task %r from %s not sent: %s", task, self.ui_main_action_input.name, exc)
                return
            if not goal.accepted:
                self._logger.warning("task %r from %s was rejected", task, self.ui_main_action_input.name)

        threading.Thread(target=send, name=f"{self.component_name}-task-text", daemon=True).start()

    # -- lifecycle ----------------------------------------------------------------------------------

    def custom_on_configure(self) -> None:
        super().custom_on_configure()
        from .mcp_tools import connect_mcp_servers, disconnect_mcp_servers  # noqa: PLC0415

        disconnect_mcp_servers(self._mcp_boxes, self._tools)  # an earlier configure's
        self._mcp_boxes = connect_mcp_servers(self.config.mcp_servers, self._tools, self.config.planning_tools,
                                              self._logger)

    def custom_on_shutdown(self) -> None:
        from .mcp_tools import disconnect_mcp_servers  # noqa: PLC0415

        boxes, self._mcp_boxes = self._mcp_boxes, []
        disconnect_mcp_servers(boxes, self._tools)
        super().custom_on_shutdown()

    def custom_on_activate(self) -> None:
        super().custom_on_activate()
        self._dispatcher = Dispatcher(self.transport, self.config.dispatch_timeout, self.config.goal_accept_timeout)
        self._executor = Executor(self._tools, self._dispatcher, self._watch, self._call_inference, self.config,
                                  self._logger)
        self._task_inbox = self.transport.create_subscription(self.ui_main_action_input, self._on_task_text,
                                                              owner=self.component_name)

    def custom_on_deactivate(self) -> None:
        if self._task_inbox is not None:
            self._task_inbox.close()
            self._task_inbox = None
        with self._task_lock:
            running = self._running
        if running is not None:
            running.request_cancel()
        if self._dispatcher is not None:
            self._dispatcher.cancel_all()
        self._watch.close()
        super().custom_on_deactivate()
        super().custom_on_deactivate()

    # -- tasks --------------------------------------------------------------------------------------

    def _accept_goal(self, goal: dict[str, Any]) -> bool:
        with self._task_lock:
            busy = self._running is not None
        if busy or self.lifecycle_state != LifecycleState.ACTIVE:
            self._logger.info("task %r rejected: %s", goal.get("task"), "a task is running" if busy else "not active")
            return False
        return bool(str(goal.get("task", "")).strip())

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        """Carry out one task (on the goal's own thread); returns ``{success, message, steps}``."""
        with self._task_lock:
            if self._running is not None:
                goal_handle.abort("a task is running")
                return {"success": False, "message": "a task is running", "steps": 0}
            self._running = goal_handle
        try:
            return self._run_task(goal_handle)
        finally:
            if self._dispatcher is not None:
                self._dispatcher.cancel_all()
            with self._task_lock:
                self._running = None

    def _feedback(self, handle: GoalHandle, steps: list[int]) -> Any:
        def send(text: str) -> None:
            # A goal that has ended (the server is closing) has nobody listening any more.
            with contextlib.suppress(ComponentError):
                handle.publish_feedback({"step": steps[0], "action": [], "status": text[:2000]})

        return send

    def _run_task(self, handle: GoalHandle) -> dict[str, Any]:
        assert self._executor is not None and self._dispatcher is not None
        task = str(handle.goal.get("task", ""))
        count = [0]
        feedback = self._feedback(handle, count)
        deadline = time.monotonic() + self.config.task_timeout
        self._executor.deadline = deadline
        late = f"the task ran past task_timeout={self.config.task_timeout:g} s"
        self._dispatcher.forget()
        self.refresh_components()
        messages = self._planner.start(task, PLANNING_PROMPT, self._rag_context(task))
        feedback(f"planning: {task}")
        for _ in range(self.config.max_execution_steps):
            if handle.cancel_requested:
                return self._end(handle, "canceled", "canceled while planning", count[0])
            if time.monotonic() >= deadline:
                return self._end(handle, "aborted", late, count[0])
            plan = self._planner.plan(messages, self.config._get_inference_params(), self.config.max_planning_steps,
                                      self.config.max_execution_steps, deadline=deadline)
            if plan.error is not None:
                return self._end(handle, "aborted", plan.error, count[0])
            if time.monotonic() >= deadline:
                return self._end(handle, "aborted", late, count[0])
            if plan.steps is None:
                if not plan.text and count[0] == 0:
                    return self._end(handle, "aborted", "the planner returned neither a plan nor an answer", 0)
                if plan.text:
                    self._publish({"output": plan.text})
                return self._end(handle, "succeeded", plan.text or f"done after {count[0]} steps", count[0])
            feedback("plan: " + ", ".join(s.tool.name for s in plan.steps))
            outcome = self._executor.run(plan.steps, handle, feedback, first_step=count[0])
            count[0] += sum(1 for r in outcome.results if r["status"] != "skipped")
            self._planner.add_results(messages, plan, outcome.results)
            if outcome.cancelled:
                return self._end(handle, "canceled", "canceled", count[0])
            if outcome.abort_reason is not None:
                return self._end(handle, "aborted", outcome.abort_reason, count[0])
        return self._end(handle, "aborted", f"the planner had not finished after {self.config.max_execution_steps} "
                                            "plan-execute iterations (max_execution_steps)", count[0])

    def _end(self, handle: GoalHandle, outcome: str, message: str, steps: int) -> dict[str, Any]:
        if outcome != "succeeded":
            stopped = self._dispatcher.cancel_all() if self._dispatcher is not None else []
            if stopped:
                message += f" (goals canceled on {', '.join(stopped)})"
        self.tasks[outcome] += 1
        (self._logger.info if outcome == "succeeded" else self._logger.warning)("task %s: %s", outcome, message)
        # The server may have ended the goal already (it is closing).
        with contextlib.suppress(ComponentError):
            {"succeeded": handle.succeed, "canceled": handle.canceled}.get(outcome, lambda: handle.abort(message))()
        return {"success": outcome == "succeeded", "message": message, "steps": steps}

    def _publish(self, result: Mapping[str, Any], **kwargs: Any) -> None:
        text = str(result["output"])
        for pub in self.publishers_dict.values():
            if issubclass(pub.topic.msg_type, StreamingString):
                from ...messages import StreamingStringMsg  # noqa: PLC0415  (only for StreamingString outputs)

                pub.publish(StreamingStringMsg(data=text, stream=False, done=True))
            else:
                pub.publish(text)

    # -- RAG ----------------------------------------------------------------------------------------

    def _rag_context(self, task: str) -> str | None:
        if not (self.config.enable_rag and self.db_client is not None):
            return None
        self._ensure_db_ready()  # down at configure: it may be back
        collection = self.config.collection_name or self.component_name
        found = self.db_client.query({"collection_name": collection, "query": task, "n_results": self.config.n_results})
        documents = list(found.get("documents") or [])
        # What the database holds came from somewhere (a topic, a peer): data for the planner, never instructions.
        return as_data(f"database:{collection}", "\n".join(f"- {d}" for d in documents)) if documents else None

    # -- ModelComponent hooks -----------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        """Unused: Cortex works in goals (:meth:`main_action_callback`)."""

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        """Unused: the planner and the executor build their own inputs."""
        return None

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        self._call_inference({"query": [{"role": "user", "content": "Hello"}], "max_new_tokens": 4,
                              "temperature": 0.0, "stream": False})
