"""``python -m agents_zenoh.codecs DOC.md ...``: rewrite each wire-format document's schema list from the registry."""

from __future__ import annotations

import sys

from .schema_doc import update_schema_doc


def main(paths: list[str]) -> None:
    """Update the schema list of each document in ``paths`` and say which changed."""
    for doc_path in paths:
        print(f"{doc_path}: {'updated' if update_schema_doc(doc_path) else 'up to date'}")


if __name__ == "__main__":  # pragma: no cover - a maintenance command
    main(sys.argv[1:])
