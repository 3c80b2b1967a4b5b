"""``ComponentMethod``: a ``@component_action`` of a component that runs in another process, as a tool.

A recipe may give a language model another component's action as a tool
(``memory.register_tools_on(llm)``, ``llm.register_tool(memory.locate, ...)``). In one process the
model's component calls the bound method itself. With ``add_pkg(multiprocessing=True)`` the
model's process holds no such object: the launcher sends the bound method across as this
reference (the component's name and the action's name, see :mod:`agents_core.transport.process_values`), and
the model's component calls it through the owner's ``<component>/execute_method`` service with
:meth:`ComponentMethod.call`, as upstream does for component tools.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import attrs

from ..errors import ComponentError

__all__ = ["ComponentMethod", "Requester"]


class Requester(Protocol):
    """What :meth:`ComponentMethod.call` needs of a transport (any :class:`~agents_core.transport.Transport`)."""

    def request(self, name: str, payload: dict[str, Any], *, timeout: float = ...) -> dict[str, Any]:
        """Call service ``name`` with ``payload``; its reply."""
        ...


@attrs.frozen
class ComponentMethod:
    """The action ``method`` of the component ``component_name``, reached through the transport.

    :param timeout: seconds the action may take (the request waits one more for the reply).
    """

    component_name: str
    method: str
    timeout: float = 30.0

    @property
    def __name__(self) -> str:
        """The action's name, as a function's ``__name__`` (a tool is registered under it)."""
        return self.method

    def __call__(self, **kwargs: Any) -> Any:
        """Refused: the action runs in another process; :meth:`call` it through a transport."""
        raise ComponentError(f"{self.component_name}.{self.method} runs in another process: call it through "
                             "a transport (ComponentMethod.call)")

    def call(self, transport: Requester, kwargs: Mapping[str, Any]) -> Any:
        """Run the action with ``kwargs`` on its component's worker; its result (a plain value, else its repr)."""
        reply = transport.request(f"{self.component_name}/execute_method",
                                  {"method": self.method, "args": [], "kwargs": dict(kwargs),
                                   "timeout": self.timeout}, timeout=self.timeout + 1.0)
        return reply.get("result")
