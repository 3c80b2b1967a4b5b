"""The error every codec raises: a value that does not encode, or a payload that does not decode."""

from __future__ import annotations

from agents_core.errors import TypeValidationError

__all__ = ["CodecError"]


class CodecError(TypeValidationError):
    """A value cannot be encoded as, or a payload decoded into, its message type.

    Also raised when a publisher or subscription is created for a type that has no codec.
    """
