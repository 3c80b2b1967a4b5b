"""Cortex framework overhead: from the planner's answer to the first dispatched action, LLM time excluded.

One child process launches, on the memory transport, a Cortex and an arm component with one
``@component_action``. The planner model is an in-process client answering at once from a script
(a plan of one ``arm.grasp`` step, then the confirmation ``EXECUTE``, then the closing text), and it
clocks the time spent inside its ``_inference`` (the model's own time; the client's wrapper around it
is framework code and counted). Per task:

    overhead = (arm.grasp starts - the planner's plan is answered) - model time in between

so what remains is Cortex's own work for a step: checking the plan against the tool schemas,
building the confirmation prompt, the client's call path, parsing the decision, dispatching through
``execute_method`` and the arm's worker. Reported as milliseconds (p50, p99).
``python -m benchmarks.cortex --reps N`` is the child; :func:`run_suite` runs it.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable, MutableMapping
from typing import Any

from .common import Children, child_main, emit, run_memory_child


def run_child(reps: int, warmup: int) -> None:
    import numpy as np  # noqa: PLC0415

    from agents_core.actions import component_action  # noqa: PLC0415
    from agents_core.clients import ModelClient  # noqa: PLC0415
    from agents_core.components import Component, Cortex  # noqa: PLC0415
    from agents_core.config import CortexConfig  # noqa: PLC0415
    from agents_core.launch.launcher import Launcher  # noqa: PLC0415
    from agents_core.models import GenericLLM  # noqa: PLC0415

    marks: dict[str, float] = {}

    class InstantPlanner(ModelClient):
        """Answers at once: plan, EXECUTE, done (per task); clocks its own calls."""

        supports_tool_calls = True

        def __init__(self) -> None:
            super().__init__(model=GenericLLM(name="bench", checkpoint="bench"))
            self.model_time = 0.0

        def _check_connection(self) -> None:
            pass

        def _initialize(self) -> None:
            pass

        def _deinitialize(self) -> None:
            pass

        def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
            started = time.perf_counter()
            system = inference_input["query"][0]["content"]
            if system.startswith("You supervise"):
                answer = {"output": "EXECUTE", "tool_calls": []}
            elif any(m.get("role") == "tool" for m in inference_input["query"]):
                answer = {"output": "done", "tool_calls": []}
            else:
                answer = {"output": "", "tool_calls": [{"id": "c1", "type": "function", "function": {
                    "name": "arm.grasp", "arguments": {"object": "cup"}}}]}
            ended = time.perf_counter()
            self.model_time += ended - started
            if answer.get("tool_calls"):
                marks["planned"], marks["model_at_plan"] = ended, self.model_time
            return answer

    class Arm(Component):
        def __init__(self) -> None:
            super().__init__(trigger=0.1, component_name="arm")

        @component_action(description={"description": "Grasp an object.", "parameters": {
            "type": "object", "properties": {"object": {"type": "string"}}, "required": ["object"]}})
        def grasp(self, object: str) -> str:
            marks["dispatched"], marks["model_at_dispatch"] = time.perf_counter(), client.model_time
            return f"holding {object}"

        def _execution_step(self, **kwargs: Any) -> None:
            pass

    client = InstantPlanner()
    cortex = Cortex(model_client=client, config=CortexConfig(max_planning_steps=3, max_execution_steps=3),
                    component_name="cortex")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[Arm(), cortex])
    overheads: list[float] = []
    with launcher:
        for rep in range(warmup + reps):
            marks.clear()
            goal = launcher.transport.send_goal("cortex", "VisionLanguageAction", {"task": "grasp the cup"},
                                                timeout=5.0)
            status, result = goal.result(30.0)
            if not result.get("success"):
                raise RuntimeError(f"task failed: {status.name} {result}")
            if rep >= warmup:
                model = marks["model_at_dispatch"] - marks["model_at_plan"]
                overheads.append((marks["dispatched"] - marks["planned"] - model) * 1000.0)
    emit({"suite": "cortex", "transport": "memory", "payload": "one_step_plan", "mode": "framework",
          "latency_ms": {"p50": statistics.median(overheads), "p99": float(np.percentile(overheads, 99))},
          "reps": reps})


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The cortex child; (records, skipped)."""
    return run_memory_child("cortex", settings, children, progress, reps=50, warmup=5,
                            what="plan -> first dispatch")


def main(argv: list[str] | None = None) -> int:
    return child_main(argv, __doc__, run_child, name="cortex", reps=50, warmup=5)


if __name__ == "__main__":
    sys.exit(main())
