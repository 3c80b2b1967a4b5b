"""``SemanticRouter``: sends each text to the output topic whose meaning it matches.

Two modes, chosen by what the router is given:

- **vector mode** (``db_client``): each route's sample sentences are stored in the vector
  database at configure; a query goes to the route of its nearest sample, or to the default route
  when even the nearest is farther than ``config.maximum_distance``.
- **LLM mode** (``model_client``, or ``config.enable_local_model``): the model is offered one tool
  per route and picks one; no tool call means the default route.

The text is published unchanged on the chosen route's topic. Without a ``default_route``, the
first route is the default (a text is never dropped silently).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from typing import Any

from attrs import define, field

from ..clients.db_base import DBClient
from ..clients.model_base import ModelClient
from ..config import BaseAttrs
from ..errors import ConfigError, ModelClientError, ProtocolError, WiringError
from ..status import HealthStatus
from ..supported_types import String
from ..topics import Topic
from .component_base import TriggerType
from .model_component import ModelComponent
from .semantic_router_config import SemanticRouterConfig

__all__ = ["Route", "SemanticRouter"]


def _check_samples(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, list) or not value or not all(isinstance(s, str) and s.strip() for s in value):
        raise ConfigError(f"Route.samples must be a non-empty list of non-empty str, got {value!r}")


def _as_list(value: Iterable[str]) -> list[str]:
    # A typed stand-in for ``converter=list``: mypy cannot solve list's type variable in a converter.
    return list(value)


def _check_topic(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, Topic) or not issubclass(value.msg_type, String):
        raise ConfigError(f"Route.routes_to must be a String Topic, got {value!r}")


@define(kw_only=True)
class Route(BaseAttrs):  # BaseAttrs: a route can be sent to the router's own process
    """A destination for the router.

    :param routes_to: the String topic texts of this kind are published on.
    :param samples: example texts of this kind (what the router compares queries with).
    """

    routes_to: Topic = field(validator=_check_topic)
    samples: list[str] = field(converter=_as_list, validator=_check_samples)

    @property
    def name(self) -> str:
        return self.routes_to.name


def _nearest(result: dict[str, Any]) -> tuple[dict[str, Any] | None, float | None]:
    """The metadata and distance of the best hit of a DB query (the DBClient result shape)."""
    metadatas, distances = result.get("metadatas") or [], result.get("distances") or []
    if not metadatas:
        return None, None
    return metadatas[0], float(distances[0]) if distances else None


class SemanticRouter(ModelComponent):
    """Routes String messages to one of several topics by meaning.

    :param inputs: the String topics to route (each message is routed on arrival by default).
    :param routes: the :class:`Route` list; their topics are the router's outputs.
    :param default_route: where texts that match no route go (default: the first route).
    :param config: a :class:`~agents_core.config.SemanticRouterConfig`.
    :param db_client: a vector database client: vector mode.
    :param model_client: a chat model client that supports tool calls: LLM mode.
    """

    config_class = SemanticRouterConfig

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        routes: Sequence[Route] | None = None,
        default_route: Route | None = None,
        config: SemanticRouterConfig | None = None,
        db_client: DBClient | None = None,
        model_client: ModelClient | None = None,
        trigger: TriggerType | None = None,
        component_name: str = "router",
        **kwargs: Any,
    ) -> None:
        routes = list(routes or [])
        if not routes or not all(isinstance(r, Route) for r in routes):
            raise WiringError(f"component {component_name!r}: routes must be a non-empty list of Route")
        names = [r.name for r in routes]
        if len(set(names)) != len(names):
            raise WiringError(f"component {component_name!r}: two routes publish on the same topic ({names})")
        if default_route is not None and default_route.name not in names:
            routes.append(default_route)
        if db_client is not None and model_client is not None:
            raise WiringError(f"component {component_name!r}: give a db_client (vector mode) or a model_client "
                              "(LLM mode), not both")
        if db_client is not None and not isinstance(db_client, DBClient):
            raise WiringError(f"component {component_name!r}: db_client must be a DBClient")
        # Set before super().__init__, which asks _runs_without_model (vector mode needs no model).
        self.db_client = db_client
        self.routes = routes
        self.default_route = default_route or routes[0]
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        self.handled_outputs = [String]
        inputs = list(inputs or [])
        super().__init__(inputs=inputs, outputs=[r.routes_to for r in routes], model_client=model_client,
                         config=config, trigger=inputs if trigger is None else trigger,
                         component_name=component_name, db_client=db_client, **kwargs)
        self.config: SemanticRouterConfig
        self._tool_routes = {self._tool_name(r): r for r in self.routes}
        #: How many texts went to each route (by topic name), for monitoring.
        self.routed: dict[str, int] = dict.fromkeys([*names, self.default_route.name], 0)

    def _runs_without_model(self) -> bool:
        return self.db_client is not None

    @property
    def mode(self) -> str:
        """``"vector"`` or ``"llm"``."""
        return "vector" if self.db_client is not None else "llm"

    @staticmethod
    def _tool_name(route: Route) -> str:
        return "route_to_" + re.sub(r"\W", "_", route.name)

    # -- lifecycle ------------------------------------------------------------------------------

    def custom_on_configure(self) -> None:
        if self.db_client is None:
            super().custom_on_configure()
            return
        # As an LLM whose database is down: a database that cannot be reached at configure leaves the router up
        # and unhealthy (COMPONENT_FAILURE; no fallback runs, they are the model's), and each step tries to store
        # the samples again.
        self._check_outputs_converted()
        self._set_up_model()
        self._samples_stored = False
        try:
            self._store_samples()
        except ModelClientError as exc:
            self.runtime.health.mark_failed(HealthStatus.COMPONENT_FAILURE, exc,
                                            "storing the route samples at configure")
            self._logger.warning("component %r comes up unhealthy: its database is not reachable (%s); each step "
                                 "tries again", self.component_name, exc)

    def _store_samples(self) -> None:
        """Connect the database and (re)build the route collection from the routes' samples."""
        assert self.db_client is not None
        self._ensure_db_ready()
        ids, documents, metadatas = [], [], []
        for route in self.routes:
            for i, sample in enumerate(route.samples):
                ids.append(f"{route.name}:{i}")
                documents.append(sample)
                metadatas.append({"route_name": route.name})
        # The collection is rebuilt: samples of routes a previous run had (or of another recipe using the
        # same router_name) would otherwise still match, and route to a topic this router does not have.
        self.db_client.add({"collection_name": self.config.router_name, "distance_func": self.config.distance_func,
                            "ids": ids, "documents": documents, "metadatas": metadatas, "reset_collection": True})
        self._samples_stored = True
        self._logger.info("stored %d samples of %d routes in %r", len(ids), len(self.routes), self.config.router_name)

    # -- routing --------------------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        topic = kwargs.get("topic")
        sources = [topic] if topic is not None else self.inputs
        for source in sources:
            text = {**self.callbacks, **self.trig_callbacks}[source.name].get_output()
            if not isinstance(text, str) or not text.strip():
                continue
            route = self.choose_route(text)
            self.routed[route.name] += 1
            self._logger.debug("routing %r to %s", text[:80], route.name)
            self.publishers_dict[route.name].publish(text)

    def choose_route(self, text: str) -> Route:
        """The route for ``text`` (vector or LLM mode); may raise a typed client error."""
        if self.db_client is not None:
            return self._route_by_vector(text)
        return self._route_by_llm(text)

    def _route_by_vector(self, text: str) -> Route:
        assert self.db_client is not None
        if not getattr(self, "_samples_stored", True):
            self._store_samples()  # the database was down at configure (a ModelClientError fails the step)
        result = self.db_client.query({"collection_name": self.config.router_name, "query": text, "n_results": 1})
        metadata, distance = _nearest(result)
        if metadata is None:
            return self.default_route
        if distance is not None and distance > self.config.maximum_distance:
            return self.default_route
        name = metadata.get("route_name")
        for route in self.routes:
            if route.name == name:
                return route
        raise ProtocolError(f"component {self.component_name!r}: the database returned unknown route {name!r}")

    def _route_by_llm(self, text: str) -> Route:
        result = self._call_inference(self._create_input(text))
        for call in result.get("tool_calls") or []:
            route = self._tool_routes.get(call["function"]["name"])
            if route is not None:
                return route
        return self.default_route

    def _create_input(self, text: str, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """The LLM-mode inference input for ``text``: one tool per route, the model calls the one that fits."""
        tools = [{"type": "function", "function": {
            "name": self._tool_name(r),
            "description": "Choose this route for messages like: " + "; ".join(r.samples),
            "parameters": {"type": "object", "properties": {}, "required": []}}} for r in self.routes]
        return {
            "query": [{"role": "system", "content": "You route robot requests. Call exactly one tool: the route "
                                                    "that fits the user's message best."},
                      {"role": "user", "content": text}],
            "tools": tools, "stream": False, "temperature": 0.0, "max_new_tokens": 64}

    def _deploy_local_model(self) -> None:
        from ..engines.local_llm import LocalLLM  # noqa: PLC0415  (llama-cpp-python is optional)

        self.local_model = LocalLLM(model_path=self.config.local_model_path, device=self.config.device_local_model,
                                    ncpu=self.config.ncpu_local_model)

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        self.choose_route("hello")
