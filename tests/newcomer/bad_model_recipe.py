"""A recipe whose LLM names a model file that is not there (``models/x.gguf``, relative), as a new user writes it.

``python bad_model_recipe.py [memory|zenoh] [--processes] [--with] [--bug] [--hook]``: the launcher's bringup
(``--with``: a ``with launcher:`` block, as the tutorial writes recipes) must fail with one line. ``--bug``: the
component is instead one whose own ``custom_on_configure`` has a bug (a KeyError), whose traceback must stay;
``--hook``: the script installs its own uncaught-error hook (a crash reporter's) before the launch.
"""

from __future__ import annotations

import sys
from typing import Any

from agents_core import Component, Launcher, Topic
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.supported_types import String


class Buggy(Component):
    """A component of the user's own whose configure step has a bug."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        super().__init__(inputs=[question], trigger=question, component_name="buggy", **kwargs)

    def custom_on_configure(self) -> None:
        super().custom_on_configure()
        settings: dict[str, str] = {}
        print(settings["user_bug_key"])

    def _execution_step(self, **kwargs: Any) -> None:
        pass


def crash_reporter(kind: type[BaseException], value: BaseException, tb: Any, _then: Any = sys.excepthook) -> None:
    print(f"USER HOOK got {kind.__name__}", file=sys.stderr)
    _then(kind, value, tb)


question, answer = Topic("question", "String"), Topic("answer", "String")
if "--hook" in sys.argv:
    sys.excepthook = crash_reporter
if "--bug" in sys.argv:
    component: Component = Buggy()
else:
    component = LLM(inputs=[question], outputs=[answer], trigger=question, component_name="llm",
                    config=LLMConfig(enable_local_model=True, local_model_path="models/x.gguf"))
launcher = Launcher(transport=sys.argv[1] if len(sys.argv) > 1 else None)
launcher.add_pkg(components=[component], multiprocessing="--processes" in sys.argv)
if "--with" in sys.argv:
    with launcher:
        print("started: it should not have")
else:
    launcher.bringup()
