"""Text: :class:`String` (a ``str``) and :class:`StreamingString` (chunks of streamed text)."""

from __future__ import annotations

from typing import Any, ClassVar

from attrs import define, field

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
    """Streamed text chunks (:class:`~agents_core.messages.StreamingStringMsg`); a ``str`` is one final chunk."""

    value_class = StreamingStringMsg

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
