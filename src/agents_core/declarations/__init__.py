"""What components and recipes declare, held as data (so that it can cross to a component's process).

- :mod:`.action_schema`: a ``@component_action``'s parameters as a JSON Schema;
- :mod:`.setup_calls`: the setup calls (``@setup_method``) and assignments made after construction;
- :mod:`.event_transfer`: events as data, for a component process that watches one;
- :mod:`.component_method`: a ``@component_action`` of a component in another process, as a tool.

Importing this package imports none of them.
"""

from __future__ import annotations
