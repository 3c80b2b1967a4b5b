"""A recipe holding only an episode recorder, run in its own process by test_episodes_across_processes.py.

``python -m tests.episodes.episodes_recipe --transport zenoh --listen tcp/127.0.0.1:PORT --directory DIR``
(or ``--transport ros2``): an :class:`~agents_core.episodes.EpisodeRecorderComponent` named ``episodes``
recording ``joints`` (JointState) and ``camera`` (Image) into DIR. Prints ``READY`` once active.
"""

from __future__ import annotations

import argparse

from agents_core import Launcher, Topic
from agents_core.episodes import EpisodeRecorderComponent, EpisodeRecorderConfig

from ..components.recipe_main import serve, transport_options

JOINTS = Topic("joints", "JointState")
CAMERA = Topic("camera", "Image")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["zenoh", "ros2", "rmw_zenoh"])
    parser.add_argument("--listen", default=None)
    parser.add_argument("--directory", required=True)
    args = parser.parse_args(argv)
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[EpisodeRecorderComponent(
        inputs=[JOINTS, CAMERA], component_name="episodes",
        config=EpisodeRecorderConfig(directory=args.directory, buffer_s=5.0))])
    serve(launcher)


if __name__ == "__main__":
    main()
