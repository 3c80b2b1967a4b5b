"""Score a scripted expert on LeRobot's ALOHA transfer-cube task: the right arm picks the cube, hands it to the left.

``world`` (a GymWorld running ``gym_aloha/AlohaTransferCube-v0``: two ViperX arms, 14 joint-position
actions, the ``top`` camera at 640x480: gym-aloha renders its cameras at that size whatever
``observation_width`` says) publishes each step's ``observation``: the arms' joints
(``agent_pos``, 14 values), then the simulation time and the cube's pose (privileged state: a
scripted expert knows where the cube is, as in the ALOHA papers' scripted demonstrations).
``aloha_expert`` (the component below) follows the papers' end-effector script — approach the cube
from above, go down, close the gripper, lift to a meeting point, the left gripper comes and closes,
the right one opens and moves away — turning each gripper pose into joint positions by damped
least squares on a kinematic copy of the arms (MuJoCo). An episode succeeds by the task's own rule
(reward 4: the left gripper holds the cube off the table)::

    python examples/evaluate_aloha.py --episodes 5 --out eval-aloha     # ~2 min an episode on 2 cores

Needs the ``sim`` and ``aloha`` extras (``nox -s sim_aloha`` installs them and runs this).
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
from example_cli import parser

from agents_core import Topic
from agents_core.components import Component
from agents_core.evals import Evaluation, run_evaluation
from agents_core.evals.expect import expect_success_rate
from agents_core.sim import EnvSuccess, GymWorld, GymWorldConfig

#: Seconds per step of the ALOHA scenes (50 Hz).
DT = 0.02
#: The gripper bodies the end-effector scene welds its mocap bodies to (the script moves the mocap poses:
#: a point between the fingers).
GRIPPERS = ("vx300s_left/gripper_link", "vx300s_right/gripper_link")
MOCAPS = ("mocap_left", "mocap_right")
#: Where the two grippers meet to hand the cube over.
MEET = np.array([0.0, 0.5, 0.25])
#: The papers' script spans 400 steps; the task stops at 300, so the same waypoints run this much faster.
TIME_SCALE = 0.8


def aloha_privileged_state(env: Any) -> Any:
    """The simulation time and the cube's pose (x, y, z, quaternion), read from the scene (privileged)."""
    physics = env.unwrapped._env.physics
    return np.concatenate([[float(physics.data.time)], physics.data.qpos[16:23]])


def _axis_angle(axis: tuple[float, float, float], degrees: float) -> np.ndarray[Any, Any]:
    half = np.radians(degrees) / 2
    return np.concatenate([[np.cos(half)], np.sin(half) * np.asarray(axis, dtype=np.float64)])


def _qmul(a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


Pose = tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]


def script(cube: np.ndarray[Any, Any], start: tuple[Pose, Pose]) -> dict[str, list[tuple[float, Any, Any, float]]]:
    """Each arm's waypoints (step, xyz, quaternion, gripper 0 closed .. 1 open) for a cube at ``cube``.

    ``start``: the (left, right) mocap poses the arms start in.
    """
    level = np.array([1.0, 0.0, 0.0, 0.0])
    pick = _qmul(level, _axis_angle((0.0, 1.0, 0.0), -60.0))
    hold = _axis_angle((1.0, 0.0, 0.0), 90.0)
    left = [(0, *start[0], 0.0),
            (100, MEET + np.array([-0.1, 0, -0.02]), hold, 1.0),   # towards the meeting point
            (260, MEET + np.array([0.02, 0, -0.02]), hold, 1.0),   # around the cube
            (310, MEET + np.array([0.02, 0, -0.02]), hold, 0.0),   # close
            (360, MEET + np.array([-0.1, 0, -0.02]), level, 0.0),  # away, holding it
            (400, MEET + np.array([-0.1, 0, -0.02]), level, 0.0)]
    right = [(0, *start[1], 0.0),
             (90, cube + np.array([0, 0, 0.08]), pick, 1.0),     # above the cube, open
             (130, cube + np.array([0, 0, -0.015]), pick, 1.0),  # down
             (170, cube + np.array([0, 0, -0.015]), pick, 0.0),  # close
             (200, MEET + np.array([0.05, 0, 0]), pick, 0.0),    # up, towards the meeting point
             (220, MEET, pick, 0.0),
             (310, MEET, pick, 1.0),                   # let go
             (360, MEET + np.array([0.1, 0, 0]), pick, 1.0),     # away
             (400, MEET + np.array([0.1, 0, 0]), pick, 1.0)]
    return {"left": [(t * TIME_SCALE, np.asarray(p, float), q, g) for t, p, q, g in left],
            "right": [(t * TIME_SCALE, np.asarray(p, float), q, g) for t, p, q, g in right]}


def _at(waypoints: list[tuple[float, Any, Any, float]], t: float) -> tuple[Any, Any, float]:
    """The pose and gripper ``t`` steps in: linear between waypoints (the quaternion normalised)."""
    for (t0, p0, q0, g0), (t1, p1, q1, g1) in itertools.pairwise(waypoints):
        if t <= t1:
            f = 0.0 if t1 == t0 else min(max((t - t0) / (t1 - t0), 0.0), 1.0)
            q = (1 - f) * q0 + f * (q1 if np.dot(q0, q1) >= 0 else -q1)
            return (1 - f) * p0 + f * p1, q / np.linalg.norm(q), (1 - f) * g0 + f * g1
    _, p, q, g = waypoints[-1]
    return p, q, g


class ArmKinematics:
    """Joint positions that put a gripper at a pose: damped least squares on MuJoCo's Jacobians of the scene."""

    def __init__(self, iterations: int = 30, damping: float = 0.05) -> None:
        import gym_aloha  # noqa: PLC0415 - the aloha extra
        import mujoco  # noqa: PLC0415

        self.mujoco = mujoco
        assets = Path(gym_aloha.__file__).parent / "assets"
        self.model = mujoco.MjModel.from_xml_path(str(assets / "bimanual_viperx_transfer_cube.xml"))
        self.data = mujoco.MjData(self.model)
        # Where each gripper body sits relative to its mocap body: the end-effector scene's welds.
        scene = mujoco.MjModel.from_xml_path(str(assets / "bimanual_viperx_end_effector_transfer_cube.xml"))
        self.offsets: list[Pose] = []
        for mocap in MOCAPS:
            body = mujoco.mj_name2id(scene, mujoco.mjtObj.mjOBJ_BODY, mocap)
            weld = next(i for i in range(scene.neq) if scene.eq_obj1id[i] == body)
            self.offsets.append((scene.eq_data[weld][3:6].copy(), scene.eq_data[weld][6:10].copy()))
        self.iterations, self.damping = iterations, damping
        self.bodies = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name) for name in GRIPPERS]
        self.dofs = [np.arange(0, 6), np.arange(8, 14)]  # each arm's six joints (qpos and dof indices alike)
        self.limits = [self.model.jnt_range[d] for d in self.dofs]

    def _rotate(self, quat: np.ndarray[Any, Any], vector: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        out = np.zeros(3)
        self.mujoco.mju_rotVecQuat(out, vector, quat)
        return out

    def mocap_pose(self, arm: int, joints: np.ndarray[Any, Any]) -> Pose:
        """The mocap pose that goes with gripper ``arm`` at ``joints``."""
        mj, data, body = self.mujoco, self.data, self.bodies[arm]
        data.qpos[self.dofs[arm]] = joints
        mj.mj_kinematics(self.model, data)
        offset_xyz, offset_quat = self.offsets[arm]
        inverse = np.zeros(4)
        mj.mju_negQuat(inverse, offset_quat)
        quat = _qmul(data.xquat[body], inverse)
        return data.xpos[body] - self._rotate(quat, offset_xyz), quat

    def solve(self, arm: int, joints: np.ndarray[Any, Any], mocap_xyz: np.ndarray[Any, Any],
              mocap_quat: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        """The six joint positions (from ``joints`` on) that bring arm ``arm`` (0 left, 1 right) to a mocap pose."""
        mj, model, data = self.mujoco, self.model, self.data
        dofs, body = self.dofs[arm], self.bodies[arm]
        offset_xyz, offset_quat = self.offsets[arm]
        xyz = mocap_xyz + self._rotate(mocap_quat, offset_xyz)
        quat = _qmul(mocap_quat, offset_quat)
        q = np.array(joints, dtype=np.float64)
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        error, rotation, conj = np.zeros(6), np.zeros(3), np.zeros(4)
        for _ in range(self.iterations):
            data.qpos[dofs] = q
            mj.mj_kinematics(model, data)
            mj.mj_comPos(model, data)
            error[:3] = xyz - data.xpos[body]
            mj.mju_negQuat(conj, data.xquat[body])
            difference = np.zeros(4)
            mj.mju_mulQuat(difference, quat, conj)
            mj.mju_quat2Vel(rotation, difference, 1.0)
            error[3:] = rotation
            if np.linalg.norm(error[:3]) < 1e-4 and np.linalg.norm(error[3:]) < 1e-3:
                break
            mj.mj_jacBody(model, data, jacp, jacr, body)
            jacobian = np.vstack([jacp[:, dofs], jacr[:, dofs]])
            step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + self.damping ** 2 * np.eye(6), error)
            q = np.clip(q + np.clip(step, -0.2, 0.2), self.limits[arm][:, 0], self.limits[arm][:, 1])
        return q


class AlohaExpert(Component):
    """The papers' transfer-cube script as joint positions, one action per observation (see the module docs)."""

    def __init__(self, *, component_name: str = "aloha_expert", **kwargs: Any) -> None:
        observation = Topic("observation", "Float64MultiArray")
        super().__init__(inputs=[observation], outputs=[Topic("action", "Float64MultiArray")], trigger=observation,
                         component_name=component_name, **kwargs)
        self._kinematics: ArmKinematics | None = None
        self._plan: dict[str, list[Any]] | None = None
        self._solution: list[np.ndarray[Any, Any]] = []

    def act(self, observation: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        """The 14 joint targets for one observation (agent_pos, then time and the cube's pose)."""
        if self._kinematics is None:
            self._kinematics = ArmKinematics()
        joints, now, cube = observation[:14], float(observation[14]), observation[15:18]
        t = round(now / DT)
        if t == 0 or self._plan is None:  # a new episode: plan around where the cube is now
            self._solution = [joints[0:6].copy(), joints[7:13].copy()]
            kinematics = self._kinematics
            start = (kinematics.mocap_pose(0, self._solution[0]), kinematics.mocap_pose(1, self._solution[1]))
            self._plan = script(np.asarray(cube, dtype=np.float64), start)
        action = np.zeros(14)
        for arm, (side, first) in enumerate((("left", 0), ("right", 7))):
            xyz, quat, gripper = _at(self._plan[side], t + 1)
            self._solution[arm] = self._kinematics.solve(arm, self._solution[arm], xyz, quat)
            action[first:first + 6] = self._solution[arm]
            action[first + 6] = gripper
        return action

    def _execution_step(self, **kwargs: Any) -> None:
        observation = self.trig_callbacks["observation"].get_output()
        if observation is not None:
            self.publishers_dict["action"].publish(self.act(np.asarray(observation, dtype=np.float64)))


def aloha_world() -> GymWorld:
    """The transfer-cube world: the top camera (640x480), the task's own success rule, privileged cube pose."""
    return GymWorld("gym_aloha/AlohaTransferCube-v0", success=EnvSuccess(),
                    env_kwargs={"obs_type": "pixels_agent_pos"},
                    cameras={"top": "pixels/top"}, privileged_state=aloha_privileged_state,
                    config=GymWorldConfig(step_timeout=60.0, action_timeout=60.0))


def evaluation(episodes: int = 5, seed: int = 0) -> Evaluation:
    """The scripted expert over ``episodes`` seeded cube positions."""
    return Evaluation(name="aloha-transfer-cube-expert", world=aloha_world, recipe=lambda: [AlohaExpert()],
                      episodes=episodes, seed=seed, recipe_name="ALOHA scripted transfer-cube expert")


def main(argv: list[str] | None = None) -> None:
    """Run the evaluation and print a table of its episodes."""
    p = parser(__doc__)
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("eval-aloha"))
    p.add_argument("--at-least", type=float, default=None, metavar="RATE",
                   help="exit with status 1 when the success rate is under RATE (0-1)")
    args = p.parse_args(argv)
    run = run_evaluation(evaluation(args.episodes, args.seed), args.out, transport=args.transport or "memory")
    print("| episode | seed | success | ended | steps | time to success s | reward sum | max reward | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in run.results:
        tts = "-" if r["time_to_success_s"] is None else f"{r['time_to_success_s']:.2f}"
        print(f"| {r['episode']} | {r['seed']} | {r['success']} | {r['ended']} | {r['steps']} | {tts} | "
              f"{r['reward_sum']:.0f} | {max(r['rewards'] or [0]):.0f} | {r['wall_s']:.0f} |")
    print(f"{run.successes}/{len(run.results)} episodes succeeded; results in {run.out_dir}", flush=True)
    if args.at_least is not None:
        try:
            expect_success_rate(run.out_dir, at_least=args.at_least)
        except AssertionError as exc:
            raise SystemExit(f"FAILED: {exc}") from None


if __name__ == "__main__":
    main()
