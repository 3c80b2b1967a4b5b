"""The exceptions raised by agents_core and its transport adapters.

Every exception the framework raises on purpose derives from :class:`AgentsError`, so
``except AgentsError`` catches all of them. Where the meaning matches a builtin, the class
also derives from it (a bad configuration is a ``ValueError``, a timeout a ``TimeoutError``)
so code that does not know this module still handles them sensibly::

    AgentsError
    ├── ConfigError (ValueError)            a value given by the user is invalid
    │   ├── TypeValidationError (TypeError) a value does not fit its message type
    │   │   └── InvalidJsonError            JSON from outside is malformed or over its limits
    │   │       └── JsonLimitError          (both in agents_core.support.bounded_json)
    │   ├── UnknownTypeError (LookupError)  a msg_type name is not registered
    │   ├── TopicNameError                  a topic or service name no transport can carry
    │   ├── PositionalArgumentsError (TypeError)
    │   │                                   a config or model built with positional arguments
    │   └── WiringError                     inputs / outputs / trigger do not fit a component
    ├── TransportError                      the middleware failed
    │   ├── TransportNotAvailableError (ImportError)
    │   │                                   unknown transport name, or its extra is not installed
    │   ├── TransportClosedError            the transport was used after close()
    │   ├── ServiceUnavailableError         no one serves a requested service
    │   ├── RequestTimeoutError (TimeoutError)
    │   │                                   a request got no reply in time
    │   └── RemoteError                     the service handler raised; carries its message
    ├── ComponentError                      a component cannot do what was asked
    │   ├── LifecycleError                  a transition that is not allowed from the state
    │   └── AlgorithmFailure                a step ran but its result is unusable
    └── ModelClientError                    talking to a model / database server failed
        ├── ClientConnectionError (ConnectionError)
        │   └── InferenceConnectionError    the server went away under a run-time inference
        ├── InferenceTimeoutError (TimeoutError)
        ├── HTTPStatusError                 the server answered with an error status
        ├── ProtocolError                   the server answered something the client cannot read
        └── InferenceError                  the inference ran and failed / returned nothing
"""

from __future__ import annotations

__all__ = [
    "AgentsError",
    "AlgorithmFailure",
    "ClientConnectionError",
    "ComponentError",
    "ConfigError",
    "HTTPStatusError",
    "InferenceConnectionError",
    "InferenceError",
    "InferenceTimeoutError",
    "LifecycleError",
    "ModelClientError",
    "PositionalArgumentsError",
    "ProtocolError",
    "RemoteError",
    "RequestTimeoutError",
    "ServiceUnavailableError",
    "TopicNameError",
    "TransportClosedError",
    "TransportError",
    "TransportNotAvailableError",
    "TypeValidationError",
    "UnknownTypeError",
    "WiringError",
]


class AgentsError(Exception):
    """Root of every exception raised on purpose by agents_core and its adapters."""


class ConfigError(AgentsError, ValueError):
    """A value given by the user (config field, argument, file) is invalid."""


class TypeValidationError(ConfigError, TypeError):
    """A value does not fit the message type it is published or declared as."""


class UnknownTypeError(ConfigError, LookupError):
    """A message type name is not in the SupportedType registry."""


class PositionalArgumentsError(ConfigError, TypeError):
    """A config or model was built with positional (or missing required) arguments.

    Also a ``TypeError``: what attrs' ``@define(kw_only=True)`` raises there, so
    ``except TypeError`` (the spec's promise) still catches it.
    """


class TopicNameError(ConfigError):
    """A topic or service name that no transport could carry."""


class WiringError(ConfigError):
    """A component's inputs, outputs or trigger do not match what it accepts."""


class TransportError(AgentsError):
    """The middleware (memory, Zenoh, ROS 2) failed to do what was asked."""


class TransportNotAvailableError(TransportError, ImportError):
    """The transport name is unknown, or the extra it needs is not installed."""


class TransportClosedError(TransportError):
    """The transport, publisher or subscription was used after being closed."""


class ServiceUnavailableError(TransportError):
    """Nobody serves the requested service name."""


class RequestTimeoutError(TransportError, TimeoutError):
    """A request got no reply within its timeout."""


class RemoteError(TransportError):
    """The service handler on the other side raised; the message is the remote error's."""


class ComponentError(AgentsError):
    """A component cannot do what was asked of it."""


class LifecycleError(ComponentError):
    """A lifecycle transition that is not allowed from the component's current state."""


class AlgorithmFailure(ComponentError):
    """Raised by a step whose computation ran but produced an unusable result.

    The runtime maps it to the ``ALGORITHM_FAILURE`` health status (other exceptions from a
    step map to ``COMPONENT_FAILURE``).
    """


class ModelClientError(AgentsError):
    """Talking to a model or database server failed."""


class ClientConnectionError(ModelClientError, ConnectionError):
    """The server cannot be reached (refused, DNS, closed mid-stream)."""


class InferenceConnectionError(ClientConnectionError):
    """The server went away during an inference (refused, reset, closed mid-stream) at run time.

    A step that raises it is an ALGORITHM_FAILURE, as upstream marks every failed inference
    (``on_algorithm_fail`` fallbacks run); a server unreachable while the component configures
    stays a COMPONENT_FAILURE. Still a :class:`ClientConnectionError`, for code that catches that.
    """

    @classmethod
    def from_connection_error(cls, exc: ClientConnectionError) -> InferenceConnectionError:
        """The same error, marked as an inference's (``exc`` itself when it already is one)."""
        if isinstance(exc, InferenceConnectionError):
            return exc
        error = cls(*exc.args)
        error.__cause__ = exc.__cause__ or exc
        error.__suppress_context__ = True
        return error


class InferenceTimeoutError(ModelClientError, TimeoutError):
    """The server did not answer within the client's timeout."""


class HTTPStatusError(ModelClientError):
    """The server answered with an error status; ``status`` and the server's message are kept."""

    def __init__(self, message: str, *, status: int) -> None:
        super().__init__(message)
        self.status = status


class ProtocolError(ModelClientError):
    """The server's answer does not follow the protocol the client speaks."""


class InferenceError(ModelClientError):
    """The inference ran and failed, or returned nothing usable."""
