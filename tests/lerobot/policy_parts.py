"""A LeRobot ACT policy with random weights, built from an exported dataset's features, and LeRobot's server.

:func:`build_act_checkpoint` reads the dataset's metadata (``LeRobotDatasetMetadata``), turns its
features into the policy's inputs and outputs (LeRobot's ``dataset_to_policy_features``), builds a
small ACT (no pretrained backbone: nothing is downloaded) and saves it with its pre- and
post-processors (normalisation from the dataset's ``stats.json``), which is what
``python -m lerobot.async_inference.policy_server`` loads. :func:`policy_server` runs that server.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path


def build_act_checkpoint(dataset_root: Path, repo_id: str, out: Path, chunk_size: int = 10) -> Path:
    """Save a random-weight ACT for the dataset at ``dataset_root`` into ``out``; returns ``out``."""
    import torch  # noqa: PLC0415
    from lerobot.configs.types import FeatureType  # noqa: PLC0415
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata  # noqa: PLC0415
    from lerobot.datasets.utils import dataset_to_policy_features  # noqa: PLC0415
    from lerobot.policies.act.configuration_act import ACTConfig  # noqa: PLC0415
    from lerobot.policies.act.modeling_act import ACTPolicy  # noqa: PLC0415
    from lerobot.policies.factory import make_pre_post_processors  # noqa: PLC0415

    torch.manual_seed(0)
    meta = LeRobotDatasetMetadata(repo_id, root=dataset_root)
    features = dataset_to_policy_features(meta.features)
    outputs = {k: f for k, f in features.items() if f.type is FeatureType.ACTION}
    inputs = {k: f for k, f in features.items() if k not in outputs}
    config = ACTConfig(input_features=inputs, output_features=outputs, device="cpu", chunk_size=chunk_size,
                       n_action_steps=chunk_size, pretrained_backbone_weights=None, dim_model=64, n_heads=2,
                       dim_feedforward=128, n_encoder_layers=1, n_decoder_layers=1, use_vae=False)
    policy = ACTPolicy(config)
    preprocessor, postprocessor = make_pre_post_processors(config, dataset_stats=meta.stats)
    policy.save_pretrained(out)
    preprocessor.save_pretrained(out)
    postprocessor.save_pretrained(out)
    return out


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def policy_server(log: Path, port: int, timeout: float = 120.0) -> Iterator[subprocess.Popen[bytes]]:
    """LeRobot's policy server on 127.0.0.1:``port``, stopped by PID on exit."""
    with open(log, "wb") as out:
        proc = subprocess.Popen([sys.executable, "-m", "lerobot.async_inference.policy_server",
                                 "--host=127.0.0.1", f"--port={port}"], stdout=out, stderr=subprocess.STDOUT,
                                cwd=log.parent, env={**os.environ, "HF_HUB_OFFLINE": "1"})
        try:
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                if proc.poll() is not None:
                    raise RuntimeError(f"the policy server exited: {log.read_text()[-3000:]}")
                with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=0.5):
                    break
                time.sleep(0.2)
            else:
                raise RuntimeError(f"the policy server did not listen within {timeout} s: {log.read_text()[-3000:]}")
            yield proc
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
