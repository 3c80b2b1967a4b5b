"""The base floor's helpers: no framework vocabulary, imported by every layer above."""

from __future__ import annotations
