"""``PolicyClient``: the contract of clients that serve robot policies (observation -> action chunk).

A policy client is a :class:`~agents_core.clients.model_base.ModelClient` whose ``inference`` takes
one observation and answers a chunk of future actions. The input names what the policy knows, by
the policy's own feature names (the component maps them from the robot's joints and cameras)::

    {"state": {"shoulder_pan.pos": 0.1, ...},   # one float per state feature name
     "images": {"front": <HxWx3 uint8 array>},   # one image per camera name
     "task": "pick up the red cube",            # the instruction
     "timestep": 12}                            # the control step this observation belongs to

and the result is ``{"output": <float64 array (n_actions, action_dim)>, "timestep": <int>}``, where
``timestep`` is the control step of the chunk's first row (row i is for ``timestep + i``). Checking
the numbers (finite, the right dimension) is the caller's job: a client hands back what the server
sent, in that shape.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import MutableMapping
from typing import Any

import numpy as np

from ..errors import AlgorithmFailure, ConfigError, ProtocolError
from ..models import Model
from .model_base import ModelClient

__all__ = ["ActionChunkError", "PolicyClient", "action_chunk_array", "check_policy_input"]

_INPUT_KEYS = {"state", "images", "task", "timestep"}


def check_policy_input(inference_input: dict[str, Any], owner: str) -> None:
    """Raise :class:`ConfigError` naming ``owner`` when ``inference_input`` does not follow the contract."""
    missing = _INPUT_KEYS - set(inference_input)
    if missing:
        raise ConfigError(f"{owner}: a policy input needs {sorted(_INPUT_KEYS)}; missing {sorted(missing)}")
    state, images = inference_input["state"], inference_input["images"]
    if not isinstance(state, dict) or not all(isinstance(k, str) for k in state):
        raise ConfigError(f"{owner}: 'state' must map feature names to floats")
    if not isinstance(images, dict) or not all(isinstance(k, str) for k in images):
        raise ConfigError(f"{owner}: 'images' must map camera names to arrays")
    if not isinstance(inference_input["task"], str):
        raise ConfigError(f"{owner}: 'task' must be a str")
    step = inference_input["timestep"]
    if isinstance(step, bool) or not isinstance(step, int | np.integer) or step < 0:
        raise ConfigError(f"{owner}: 'timestep' must be an int >= 0, got {step!r}")


class ActionChunkError(ProtocolError, AlgorithmFailure):
    """The policy's action chunk does not fit the declared actions (width, length or size budget).

    Both a :class:`ProtocolError` of the client (the server answered something unusable) and an
    :class:`AlgorithmFailure` of the component that asked (the policy ran; its answer is unusable).
    """


def _row_size(row: Any, index: int, owner: str) -> int:
    """The element count of one action vector, read from its shape (nothing is converted yet)."""
    if isinstance(row, np.ndarray):
        if row.dtype.kind not in "biuf":
            raise ProtocolError(f"{owner}: action {index} of the chunk is not numeric (dtype {row.dtype})")
        return int(row.size)
    if hasattr(row, "detach") and hasattr(row, "numel"):  # a torch tensor (clients other than LeRobot's)
        return int(row.numel())
    if isinstance(row, list | tuple):
        if not all(isinstance(v, int | float | np.integer | np.floating) for v in row):
            raise ProtocolError(f"{owner}: action {index} of the chunk is not a flat list of numbers")
        return len(row)
    if isinstance(row, int | float | np.integer | np.floating):
        return 1
    raise ProtocolError(f"{owner}: action {index} of the chunk is a {type(row).__name__}, not numbers")


def action_chunk_array(rows: list[Any], owner: str, *, width: int | None = None, max_rows: int | None = None,
                       max_elements: int = 1_000_000) -> np.ndarray:
    """Action vectors (numpy arrays, flat lists, or torch tensors) as one float64 array (n, dim).

    The rows' count and sizes are checked *before* anything is converted or stacked: at most
    ``max_rows`` rows, every row ``width`` long (when given), ``max_elements`` in all.

    :raises ActionChunkError: a row of the wrong width, too many rows or elements.
    :raises ProtocolError: an empty chunk, a row that is not numbers, rows of different sizes.
    """
    if not rows:
        raise ProtocolError(f"{owner}: the policy sent an empty action chunk")
    if max_rows is not None and len(rows) > max_rows:
        raise ActionChunkError(f"{owner}: the policy sent {len(rows)} actions in one chunk; at most {max_rows} "
                               "were asked for")
    sizes = [_row_size(row, i, owner) for i, row in enumerate(rows)]
    if len(set(sizes)) != 1:
        raise ProtocolError(f"{owner}: the actions of one chunk have different sizes {sorted(set(sizes))}")
    if width is not None and sizes[0] != width:
        raise ActionChunkError(f"{owner}: the policy sent actions of dimension {sizes[0]}; expected {width}")
    if len(rows) * sizes[0] > max_elements:
        raise ActionChunkError(f"{owner}: an action chunk of {len(rows)} x {sizes[0]} values is over the budget "
                               f"of {max_elements}")
    chunk = np.empty((len(rows), sizes[0]), dtype=np.float64)
    for i, row in enumerate(rows):
        # a torch tensor goes to the CPU, then numpy
        values = row.detach().cpu().numpy() if hasattr(row, "detach") else row
        try:
            chunk[i] = np.asarray(values, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ProtocolError(f"{owner}: action {i} of the chunk is not numeric: {exc}") from exc
    return chunk


def _declared_action_names(actions: Any) -> list[str] | None:
    spec = actions.get("action") if isinstance(actions, dict) else None
    names = spec.get("names") if isinstance(spec, dict) else None
    return [str(n) for n in names] if isinstance(names, list) else None


class PolicyClient(ModelClient):
    """A client for a policy server: :meth:`inference` maps one observation to an action chunk.

    :param action_names: the names of the action vector's entries, in order (default: the model's
        ``actions["action"]["names"]`` when it declares them). Other parameters as
        :class:`~agents_core.clients.model_base.ModelClient`.

    Subclasses implement ``_predict(observation) -> (first_timestep, chunk)``; connecting and
    loading the policy are the usual ``_check_connection`` / ``_initialize`` / ``_deinitialize``.
    """

    def __init__(self, model: Model | dict[str, Any], *args: Any, action_names: list[str] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(model, *args, **kwargs)
        if action_names is None and isinstance(model, Model):
            action_names = _declared_action_names(getattr(model, "actions", None))
        if action_names is not None and not (isinstance(action_names, list)
                                             and all(isinstance(n, str) and n for n in action_names)):
            raise ConfigError(f"{type(self).__name__}: action_names must be a list of non-empty str")
        #: The names of the action vector's entries, in order (from the model's action features), or
        #: None when the model does not declare them.
        self.action_names: list[str] | None = list(action_names) if action_names is not None else None

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec["action_names"] = self.action_names
        return spec

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        check_policy_input(inference_input, type(self).__name__)
        first, chunk = self._predict(inference_input)
        return {"output": chunk, "timestep": int(first)}

    @abstractmethod
    def _predict(self, observation: dict[str, Any]) -> tuple[int, np.ndarray]:
        """The timestep of the chunk's first action, and the chunk (float64, one row per action)."""
