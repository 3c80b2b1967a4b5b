"""A VLA (vision-language-action) policy driving a simulated two-joint arm.

``arm_vla`` (a VLA component) reads ``joint_states`` (JointState) and ``camera`` (Image), sends
observations to a LeRobot async-inference policy server over gRPC (``LeRobotClient``, the ``vla``
extra) and publishes the actions it answers on ``joint_commands``, clipped to the joint limits
given below. ``SimulatedArm`` stands in for the robot's driver: it follows the commands and
publishes its state and a camera frame. Start a policy server first (LeRobot's
``python -m lerobot.async_inference.policy_server --host 127.0.0.1 --port 8080``), then::

    python examples/vla_sim_arm.py --policy-port 8080 --task "reach" --once
    python examples/vla_sim_arm.py --policy-port 8080 --transport zenoh    # serve goals until Ctrl-C

A task is a ``VisionLanguageAction`` goal on ``arm_vla``; ``--task`` sends one and prints the
result and where the arm ended; without it the example serves goals sent from elsewhere
(``transport.send_goal("arm_vla", "VisionLanguageAction", {"task": ..., "max_steps": ...})``).
LeRobot's protocol sends pickles: point the client only at a policy server you run.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
from example_cli import make_launcher, parser, run

from agents_core import Launcher, Topic
from agents_core.clients import LeRobotClient
from agents_core.components import VLA
from agents_core.config import VLAConfig
from agents_core.messages import JointStateMsg
from agents_core.models import LeRobotPolicy
from agents_core.transport.contract import Transport

JOINTS = ["shoulder", "elbow"]
STATE = Topic("joint_states", "JointState")
CAMERA = Topic("camera", "Image")
COMMANDS = Topic("joint_commands", "JointState")
#: The safety limits every command is clipped to (a real arm reads them from its URDF: robot_urdf_file).
LIMITS = {"shoulder": {"lower": -2.0, "upper": 2.0, "velocity": 2.0},
          "elbow": {"lower": -0.3, "upper": 1.0, "velocity": 2.0}}


class SimulatedArm:
    """Joints that jump to each commanded position; publishes JointState at 50 Hz and a camera frame at 10 Hz."""

    def __init__(self, transport: Transport) -> None:
        self.positions = dict.fromkeys(JOINTS, 0.0)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._state = transport.create_publisher(STATE)
        self._camera = transport.create_publisher(CAMERA)
        self._commands = transport.create_subscription(COMMANDS, self._on_command)
        self._thread = threading.Thread(target=self._run, name="simulated-arm", daemon=True)
        self._thread.start()

    def _on_command(self, command: JointStateMsg) -> None:
        with self._lock:
            for name, position in zip(command.name, command.position, strict=True):
                self.positions[name] = float(position)

    def _run(self) -> None:
        frame = np.zeros((16, 16, 3), np.uint8)  # a real camera's image goes here
        tick = 0
        while not self._stop.wait(0.02):
            with self._lock:
                state = JointStateMsg(name=list(self.positions), position=list(self.positions.values()))
            self._state.publish(state)
            tick += 1
            if tick % 5 == 0:
                self._camera.publish(frame)

    def snapshot(self) -> dict[str, float]:
        """The joints' positions now."""
        with self._lock:
            return dict(self.positions)

    def close(self) -> None:
        """Stop publishing."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._commands.close()
        self._state.close()
        self._camera.close()


def build(policy_host: str, policy_port: int) -> VLA:
    """The VLA component and its policy client."""
    # What the policy reads and answers: LeRobot's feature description (or policy.load_dataset_info()
    # with a dataset's info.json). A real policy names its checkpoint: checkpoint="me/so100-pick".
    policy = LeRobotPolicy(
        name="arm_policy", policy_type="act", actions_per_chunk=10, policy_device="cpu",
        features={"observation.state": {"dtype": "float32", "shape": [2], "names": JOINTS},
                  "observation.images.front": {"dtype": "image", "shape": [16, 16, 3],
                                               "names": ["height", "width", "channels"]}},
        actions={"action": {"dtype": "float32", "shape": [2], "names": JOINTS}})
    client = LeRobotClient(policy, host=policy_host, port=policy_port, allow_pickle=True, inference_timeout=5)
    config = VLAConfig(joint_names_map={name: name for name in JOINTS}, camera_inputs_map={"front": CAMERA.name},
                       observation_sending_rate=20.0, action_sending_rate=50.0, state_timeout=1.0,
                       joint_limits=LIMITS)
    # trigger=None: an action server, run by goals rather than by topics or a timer.
    return VLA(inputs=[STATE, CAMERA], outputs=[COMMANDS], model_client=client, config=config, trigger=None,
               component_name="arm_vla")


def main(argv: list[str] | None = None) -> None:
    """Run the arm and its VLA (and send one task with ``--task``)."""
    p = parser(__doc__)
    p.add_argument("--policy-host", default="127.0.0.1", help="the policy server's host")
    p.add_argument("--policy-port", type=int, default=8080, help="the policy server's port")
    p.add_argument("--task", default=None, help="send this task once the arm is up, and print the result")
    p.add_argument("--max-steps", type=int, default=80, help="commands the task runs for")
    args = p.parse_args(argv)
    launcher = make_launcher(args)
    launcher.add_pkg(components=[build(args.policy_host, args.policy_port)])
    finished = threading.Event()
    arms: list[SimulatedArm] = []

    def drive(running: Launcher) -> None:
        arm = SimulatedArm(running.transport)
        arms.append(arm)
        if args.task is None:
            return
        finished.wait(0.5)  # the VLA sees the arm's state before the goal's first observation
        steps: list[Any] = []
        goal = running.transport.send_goal("arm_vla", "VisionLanguageAction",
                                           {"task": args.task, "max_steps": args.max_steps}, feedback=steps.append)
        status, result = goal.result(timeout=120.0)
        print(f"result: {status.name} after {len(steps)} steps: {result['message'] or 'done'}", flush=True)
        print(f"arm at: {', '.join(f'{n}={p:.3f}' for n, p in arm.snapshot().items())}", flush=True)
        finished.set()

    try:
        run(launcher, args, on_ready=drive, done=finished)
    finally:
        for arm in arms:
            arm.close()


if __name__ == "__main__":
    main()
