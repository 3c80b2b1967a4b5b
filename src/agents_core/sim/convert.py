"""Between Gymnasium values and the framework's messages: observations out, actions in.

- An observation vector (a ``Box``; or the non-image entries of a ``Dict``, flattened in key order)
  is one ``Float64MultiArray``.
- A camera frame (``render()``, or an image entry of a ``Dict`` observation such as ALOHA's
  ``pixels/top``) is an ``Image`` (rgb8).
- Joint positions and velocities (the hinge and slide joints of a MuJoCo model, or an
  ``agent_pos`` entry) are a ``JointState``.
- An action arrives as a ``Float64MultiArray`` / ``Float32MultiArray`` (the action vector), a
  ``JointState`` (its positions, in the world's joint order when names are given) or a ``Twist``
  (linear x, y, z then angular x, y, z, as many as the action has).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import AlgorithmFailure
from ..messages import JointStateMsg, TwistMsg

__all__ = ["ACTION_TYPES", "action_vector", "find_nonfinite", "image_at", "is_image", "mujoco_joints",
           "observation_vector"]

#: The message types a world takes its action as.
ACTION_TYPES = ("Float64MultiArray", "Float32MultiArray", "JointState", "Twist")


def is_image(value: Any) -> bool:
    """True for an HxWx3 (or HxWx1) uint8 array."""
    return isinstance(value, np.ndarray) and value.dtype == np.uint8 and value.ndim == 3 and value.shape[2] in (1, 3)


def _leaves(value: Any, prefix: str = "") -> list[tuple[str, Any]]:
    if isinstance(value, Mapping):
        found: list[tuple[str, Any]] = []
        for key in sorted(value):
            found += _leaves(value[key], f"{prefix}{key}/")
        return found
    return [(prefix.rstrip("/"), value)]


def observation_vector(observation: Any) -> npt.NDArray[np.float64]:
    """The observation's numbers as one float64 vector (images left out)."""
    parts = [np.asarray(v, dtype=np.float64).reshape(-1) for _, v in _leaves(observation) if not is_image(v)]
    return np.concatenate(parts) if parts else np.zeros(0)


def image_at(observation: Any, path: str) -> npt.NDArray[np.uint8] | None:
    """The image at ``path`` ("pixels/top") in a dict observation, or None."""
    value = observation
    for key in path.split("/"):
        if not isinstance(value, Mapping) or key not in value:
            return None
        value = value[key]
    return value if is_image(value) else None


def find_nonfinite(observation: Any) -> str | None:
    """Where the observation holds a NaN or an infinity ("observation[3]", "observation/agent_pos[0]"), or None."""
    for path, value in _leaves(observation):
        array = np.asarray(value)
        if array.dtype.kind not in "fc":
            continue
        bad = np.flatnonzero(~np.isfinite(array.reshape(-1)))
        if bad.size:
            where = f"observation/{path}" if path else "observation"
            return f"{where}[{int(bad[0])}] is {array.reshape(-1)[bad[0]]}"
    return None


def mujoco_joints(env: Any) -> list[tuple[str, int, int]]:
    """(name, qpos index, qvel index) of each hinge and slide joint of a Gymnasium MuJoCo env (else [])."""
    model = getattr(env.unwrapped, "model", None)
    if model is None or not hasattr(model, "njnt") or not hasattr(model, "jnt_type"):
        return []
    joints = []
    for i in range(int(model.njnt)):
        if int(model.jnt_type[i]) in (2, 3):  # mjJNT_SLIDE, mjJNT_HINGE: one coordinate each
            joints.append((str(model.joint(i).name) or f"joint{i}", int(model.jnt_qposadr[i]),
                           int(model.jnt_dofadr[i])))
    return joints


def action_vector(value: Any, shape: Sequence[int], *, topic: str, world: str,
                  joint_names: Sequence[str] | None = None) -> npt.NDArray[np.float64]:
    """The env action from a message on ``topic``.

    :class:`AlgorithmFailure` (naming the world and the topic) when it does not fit the action's shape.
    """
    size = int(np.prod(shape)) if len(shape) else 1
    if isinstance(value, JointStateMsg):
        if joint_names:
            by_name = dict(zip(value.name, value.position, strict=False))
            missing = [n for n in joint_names if n not in by_name]
            if missing:
                raise AlgorithmFailure(f"world {world!r}: the action on {topic!r} has no position for "
                                       f"joint(s) {missing}")
            array = np.array([by_name[n] for n in joint_names], dtype=np.float64)
        else:
            array = np.asarray(value.position, dtype=np.float64)
    elif isinstance(value, TwistMsg):
        array = np.concatenate([value.linear, value.angular]).astype(np.float64)[:size]
    else:
        array = np.asarray(value, dtype=np.float64)
    if array.size != size:
        raise AlgorithmFailure(f"world {world!r}: the action on {topic!r} has {array.size} value(s), "
                               f"the environment takes {size}")
    if not np.all(np.isfinite(array)):
        raise AlgorithmFailure(f"world {world!r}: the action on {topic!r} holds NaN or infinity: {array.tolist()}")
    return array.reshape(tuple(shape))
