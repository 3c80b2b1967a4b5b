"""A recipe whose LLM names a model file that is not there (``models/x.gguf``, relative), as a new user writes it.

``python bad_model_recipe.py [memory|zenoh] [--processes] [--with]``: the launcher's bringup (``--with``: a
``with launcher:`` block, as the tutorial writes recipes) must fail with one line.
"""

from __future__ import annotations

import sys

from agents_core import Launcher, Topic
from agents_core.components import LLM
from agents_core.config import LLMConfig

question, answer = Topic("question", "String"), Topic("answer", "String")
llm = LLM(inputs=[question], outputs=[answer], trigger=question, component_name="llm",
          config=LLMConfig(enable_local_model=True, local_model_path="models/x.gguf"))
launcher = Launcher(transport=sys.argv[1] if len(sys.argv) > 1 else None)
launcher.add_pkg(components=[llm], multiprocessing="--processes" in sys.argv)
if "--with" in sys.argv:
    with launcher:
        print("started: it should not have")
else:
    launcher.bringup()
