"""Text: :class:`String` (a ``str``) and :class:`StreamingString` (chunks of streamed text)."""

from __future__ import annotations

from typing import Any, ClassVar

from attrs import define, field

from ..callbacks import StreamingStringCallback
from ..errors import TypeValidationError
from .base import SupportedType
from .fields import Header, Message, header_field, is_bool, is_str, named

__all__ = ["StreamingString", "StreamingStringMsg", "String"]


@named
@define(eq=False)
class StreamingStringMsg(Message):
    """A chunk of streamed text: ``stream`` is True while chunks flow, ``done`` on the last one."""

    data: str = field(validator=is_str)
    stream: bool = field(default=False, validator=is_bool)
    done: bool = field(default=True, validator=is_bool)
    header: Header = header_field()


class String(SupportedType):
    """Text, as ``str``."""

    value_class: ClassVar[type[Any]] = str

    @classmethod
    def example(cls) -> Any:
        return "hello robot"


class StreamingString(String):
    """Streamed text chunks (:class:`~agents_core.messages.StreamingStringMsg`); a ``str`` is one final chunk.

    Published with ``stream=`` / ``done=`` (``publisher.publish(text, stream=True, done=False)``,
    ``component._publish(result, stream=True, done=False)``), a ``str`` becomes a chunk with those
    flags, as upstream. Inputs get a :class:`~agents_core.callbacks.StreamingStringCallback`.
    """

    value_class = StreamingStringMsg
    callback = StreamingStringCallback

    @classmethod
    def convert(cls, output: Any, stream: bool = False, done: bool = True, **_: Any) -> Any:
        """A chunk holding ``output`` (a ``str``) with the ``stream`` and ``done`` flags given."""
        if isinstance(output, StreamingStringMsg):
            return output
        if not isinstance(output, str):
            raise TypeValidationError(f"StreamingString expects a str or StreamingStringMsg, "
                                      f"got {type(output).__name__}")
        return StreamingStringMsg(data=output, stream=bool(stream), done=bool(done))

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, str):
            return StreamingStringMsg(data=value)
        return super().validate(value)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        return value.data

    @classmethod
    def example(cls) -> Any:
        return StreamingStringMsg(data="partial", stream=True, done=False)
