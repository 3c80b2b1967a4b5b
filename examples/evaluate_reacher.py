"""Score a Reacher-v5 agent over seeded episodes: a scripted expert against a random agent.

``world`` (a GymWorld running Gymnasium's MuJoCo ``Reacher-v5``, lock-step) publishes the arm's
``observation`` (Float64MultiArray), ``joint_states`` and a 160x120 ``camera`` frame each step and
takes the torques on ``action``. ``reacher_expert`` (the component below) answers each
observation with a damped-least-squares step towards the target; ``random_agent`` with random
torques. An episode succeeds when the fingertip is within 2 cm of the target at its end (50
steps)::

    python examples/evaluate_reacher.py --episodes 20 --out eval-reacher          # both agents
    python examples/evaluate_reacher.py --agent expert --transport zenoh

Each agent's results go to ``OUT/<agent>/`` (results.jsonl, evaluation.json, frames/, report.html).
Needs the ``sim`` extra (``pip install agents-core[sim]``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from example_cli import parser

from agents_core import Topic
from agents_core.components import Component
from agents_core.evals import Evaluation, run_evaluation
from agents_core.sim import GymWorld, RandomAgent, reacher_success

#: Reacher-v5's links (m): the upper arm, and the forearm to the fingertip.
LINKS = (0.1, 0.11)


class ReacherExpert(Component):
    """Torques that move the fingertip onto the target: damped least squares on the arm's Jacobian, plus damping.

    From the observation (cos and sin of both joints, joint velocities, fingertip minus target) it
    takes the joint step ``J^T (J J^T + lambda^2 I)^-1 (-error)`` and sends ``gain * step - damping * velocity``,
    clipped to the motors' range [-1, 1].
    """

    def __init__(self, *, gain: float = 5.0, damping: float = 0.2, regularisation: float = 0.05,
                 component_name: str = "reacher_expert", **kwargs: Any) -> None:
        self.gain, self.damping, self.regularisation = gain, damping, regularisation
        observation = Topic("observation", "Float64MultiArray")
        super().__init__(inputs=[observation], outputs=[Topic("action", "Float64MultiArray")], trigger=observation,
                         component_name=component_name, **kwargs)

    def act(self, observation: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        """The torques for one observation."""
        q = np.arctan2(observation[2:4], observation[0:2])
        velocity, error = observation[6:8], observation[8:10]
        (l1, l2), q12 = LINKS, q[0] + q[1]
        jacobian = np.array([[-l1 * np.sin(q[0]) - l2 * np.sin(q12), -l2 * np.sin(q12)],
                             [l1 * np.cos(q[0]) + l2 * np.cos(q12), l2 * np.cos(q12)]])
        damped = jacobian @ jacobian.T + self.regularisation ** 2 * np.eye(2)
        step = jacobian.T @ np.linalg.solve(damped, -error)
        return np.clip(self.gain * step - self.damping * velocity, -1.0, 1.0)

    def _execution_step(self, **kwargs: Any) -> None:
        observation = self.trig_callbacks["observation"].get_output()
        if observation is not None:
            self.publishers_dict["action"].publish(self.act(np.asarray(observation, dtype=np.float64)))


def reacher_world() -> GymWorld:
    """The Reacher-v5 world, scored by the fingertip's distance to the target at the end."""
    return GymWorld("Reacher-v5", success=reacher_success(0.02))


def evaluation(agent: str = "expert", episodes: int = 20, seed: int = 1000) -> Evaluation:
    """The evaluation of ``agent`` ("expert" or "random").

    ``agentsctl eval run examples/evaluate_reacher.py`` runs the expert's.
    """
    def recipe() -> list[Component]:
        if agent == "expert":
            return [ReacherExpert()]
        return [RandomAgent([-1.0, -1.0], [1.0, 1.0], seed=seed)]

    return Evaluation(name=f"reacher-{agent}", world=reacher_world, recipe=recipe, episodes=episodes, seed=seed,
                      max_steps=50, recipe_name=f"Reacher {agent}")


def main(argv: list[str] | None = None) -> None:
    """Run the chosen agents' evaluations and print each one's success rate and where its report is."""
    p = parser(__doc__)
    p.add_argument("--agent", choices=["expert", "random", "both"], default="both")
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--seed", type=int, default=1000, help="episode i resets with seed + i")
    p.add_argument("--out", type=Path, default=Path("eval-reacher"))
    args = p.parse_args(argv)
    options = {"listen": args.listen or [], "connect": args.connect or []} \
        if args.transport == "zenoh" and (args.listen or args.connect) else None
    for agent in (["expert", "random"] if args.agent == "both" else [args.agent]):
        run = run_evaluation(evaluation(agent, args.episodes, args.seed), args.out / agent,
                             transport=args.transport, transport_options=options)
        print(f"{agent}: {run.successes}/{len(run.results)} episodes succeeded "
              f"({100 * run.success_rate:.0f} %); results in {run.out_dir}"
              + (f", report {run.report}" if run.report else ""), flush=True)
        if run.interrupted:
            break


if __name__ == "__main__":
    main()
