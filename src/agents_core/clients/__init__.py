"""Clients for model serving platforms and vector databases."""

from __future__ import annotations

from .chroma import ChromaClient
from .client_base import BaseClient, client_from_spec, client_types
from .db_base import DBClient
from .generic import GenericHTTPClient
from .model_base import ModelClient
from .ollama import OllamaClient

__all__ = ["BaseClient", "ChromaClient", "DBClient", "GenericHTTPClient", "ModelClient", "OllamaClient",
           "client_from_spec", "client_types"]
