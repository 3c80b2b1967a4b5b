"""Clients for model serving platforms and vector databases."""

from __future__ import annotations

from .chroma import ChromaClient
from .client_base import BaseClient, client_from_spec, client_types
from .db_base import DBClient
from .model_base import ModelClient

__all__ = ["BaseClient", "ChromaClient", "DBClient", "ModelClient", "client_from_spec", "client_types"]
