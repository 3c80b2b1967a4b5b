"""The schema list of the wire-format document, generated from the codec registry.

Every codec says in words what its msgpack document holds (its *schema*);
``docs/zenoh-wire-format.md`` lists them for third-party clients. After adding a type, run
``python -m agents_zenoh.codecs docs/zenoh-wire-format.md`` to rewrite that list.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterable

from agents_core.supported_types import registered_types
from agents_core.types import is_builtin_type

from .errors import CodecError
from .registry import codec_for, registered_codecs

__all__ = ["builtin_schema_names", "describe_schemas", "schema_list", "update_schema_doc"]


def describe_schemas() -> dict[str, str]:
    """Type name -> the msgpack document of that type, in words (the wire-format reference).

    Every registered type whose codec can be derived is listed, with ``Header`` and the codecs
    registered with :func:`register_codec`.
    """
    for msg_type in registered_types().values():
        with contextlib.suppress(CodecError):
            codec_for(msg_type)
    return {name: codec.schema for name, codec in sorted(registered_codecs().items())}


def schema_list(names: Iterable[str] | None = None) -> str:
    """The Markdown list of schemas in ``docs/zenoh-wire-format.md`` ("- **Name**: `schema`" lines)."""
    schemas = describe_schemas()
    chosen = sorted(schemas) if names is None else sorted(names)
    # Header first: most schemas refer to it.
    chosen = ["Header", *(n for n in chosen if n != "Header")] if "Header" in chosen else chosen
    return "".join(f"- **{name}**: `{schemas[name]}`\n" for name in chosen)


def builtin_schema_names() -> list[str]:
    """The schemas the wire-format document lists: Header and every framework type."""
    return ["Header", *(n for n, t in registered_types().items() if is_builtin_type(t))]


def update_schema_doc(path: str) -> bool:
    """Rewrite the schema list of the wire-format document at ``path`` from the registry; True if it changed.

    Run ``python -m agents_zenoh.codecs docs/zenoh-wire-format.md`` after adding a type.
    """
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    match = _SCHEMA_LIST.search(text)
    if match is None:
        raise ValueError(f"{path} has no schema list (lines '- **Name**: `...`' starting with Header)")
    new = text[:match.start()] + schema_list(builtin_schema_names()) + text[match.end():]
    if new != text:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(new)
    return new != text


#: The schema list in the wire-format document: consecutive "- **Name**: `...`" lines from Header on.
_SCHEMA_LIST = re.compile(r"^- \*\*Header\*\*: `.*?\n(?:- \*\*\w+\*\*: `.*\n)*", re.M)
