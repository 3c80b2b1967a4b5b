"""Clients for model serving platforms and vector databases."""

from __future__ import annotations

from .chroma import ChromaClient
from .client_base import BaseClient, client_from_spec, client_types
from .db_base import DBClient
from .generic import GenericHTTPClient
from .model_base import ModelClient
from .ollama import OllamaClient
from .roboml_http import RoboMLHTTPClient
from .roboml_resp import RoboMLRESPClient
from .roboml_ws import RoboMLWSClient

__all__ = ["BaseClient", "ChromaClient", "DBClient", "GenericHTTPClient", "ModelClient", "OllamaClient",
           "RoboMLHTTPClient", "RoboMLRESPClient", "RoboMLWSClient", "client_from_spec", "client_types"]
