"""One VLA recipe, run unchanged on every transport by test_vla_transports.py.

``python -m tests.components.vla_recipe --transport zenoh --listen tcp/127.0.0.1:PORT --policy-port P``
(or ``--transport ros2``) brings up a VLA component whose LeRobotClient talks to the policy server on
127.0.0.1:P: ``joint_states`` (JointState) and ``camera`` (Image) in, ``joint_commands`` (JointState)
out, goals on ``arm_vla``. It prints ``READY`` once active and runs until SIGTERM / SIGINT.
"""

from __future__ import annotations

import argparse

from agents_core import Launcher, Topic
from agents_core.clients.lerobot import LeRobotClient
from agents_core.components import VLA
from agents_core.config import VLAConfig
from agents_core.models import LeRobotPolicy

from .recipe_main import serve, transport_options

JOINTS = ["shoulder", "elbow"]
STATE = Topic(name="joint_states", msg_type="JointState")
CAMERA = Topic(name="camera", msg_type="Image")
COMMANDS = Topic(name="joint_commands", msg_type="JointState")
#: The limits the recipe enforces (the tests check every command against them).
ELBOW_LOWER = -0.3
VELOCITY_LIMIT = 2.0
RATE = 50.0


def build(policy_port: int) -> VLA:
    """The recipe's one component (the part that is the same on every transport)."""
    model = LeRobotPolicy(
        name="arm_policy", policy_type="act", actions_per_chunk=10, policy_device="cpu",
        features={"observation.state": {"dtype": "float32", "shape": [2], "names": JOINTS},
                  "observation.images.front": {"dtype": "image", "shape": [16, 16, 3],
                                               "names": ["height", "width", "channels"]}},
        actions={"action": {"dtype": "float32", "shape": [2], "names": JOINTS}})
    client = LeRobotClient(model, port=policy_port, allow_pickle=True, inference_timeout=2)
    config = VLAConfig(joint_names_map={n: n for n in JOINTS}, camera_inputs_map={"front": CAMERA.name},
                       observation_sending_rate=20.0, action_sending_rate=RATE, state_timeout=1.0,
                       joint_limits={"elbow": {"lower": ELBOW_LOWER, "upper": 1.0, "velocity": VELOCITY_LIMIT},
                                     "shoulder": {"lower": -2.0, "upper": 2.0, "velocity": VELOCITY_LIMIT}})
    return VLA(inputs=[STATE, CAMERA], outputs=[COMMANDS], model_client=client, config=config, trigger=None,
               component_name="arm_vla")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["memory", "zenoh", "ros2", "rmw_zenoh"])
    parser.add_argument("--listen", default=None, help="zenoh: the endpoint to listen on")
    parser.add_argument("--policy-port", type=int, required=True)
    args = parser.parse_args(argv)
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[build(args.policy_port)])
    serve(launcher)


if __name__ == "__main__":
    main()
