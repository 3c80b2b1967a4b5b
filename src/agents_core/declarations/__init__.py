"""What components and recipes declare, held as data."""

from __future__ import annotations
