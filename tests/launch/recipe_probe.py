"""``python tests/launch/recipe_probe.py RECIPE.py [ARGS...]``: the recipe file's Recipe, and what its live objects say.

Prints one JSON document: ``recipe`` (``Recipe.to_dict()``, what ``agentsctl recipe show`` prints)
and ``live``, read from the captured component and event objects themselves (not from the
recipe's data), for the test to check one against the other.
"""

from __future__ import annotations

import contextlib
import json
import sys
from typing import Any

from agents_core.events import Event
from agents_core.launch.recipe import capture_recipe
from agents_core.topics import Topic


def _trigger(trigger: Any) -> Any:
    if isinstance(trigger, Topic):
        return ["topic", trigger.name]
    if isinstance(trigger, Event):
        return ["event", trigger.name]
    if isinstance(trigger, list):
        return ["topics", [t.name for t in trigger]]
    return ["value", trigger]


def main() -> None:
    with contextlib.redirect_stdout(sys.stderr):
        recipe = capture_recipe(sys.argv[1], sys.argv[2:])
        again = capture_recipe(sys.argv[1], sys.argv[2:])  # the same file builds an equal recipe
    live = {
        "components": [{"name": c.component_name, "class": f"{type(c).__module__}:{type(c).__qualname__}",
                        "inputs": [[t.name, t.type_name] for t in c.inputs],
                        "outputs": [[t.name, t.type_name] for t in c.outputs],
                        "trigger": _trigger(c.trigger)} for c in recipe.components],
        "events": [[event.name, [a.name for a in actions]] for event, actions in recipe.events_actions.items()],
        "multiprocessing": recipe.settings.multiprocessing,
        "attachments": sorted(recipe.attachments),
        "equal_when_captured_twice": recipe == again and recipe is not again,
    }
    print(json.dumps({"recipe": recipe.to_dict(), "live": live}))


if __name__ == "__main__":
    main()
