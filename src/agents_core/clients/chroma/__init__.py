"""``ChromaClient``: a :class:`~agents_core.clients.db_base.DBClient` speaking Chroma's v2 HTTP API.

Only ``httpx`` is needed on the robot; the ``chromadb`` package is not imported. Chroma stores
and searches vectors but computes none over HTTP, so documents and query texts are embedded by
an ``embedding_client`` (any :class:`~agents_core.clients.model_base.ModelClient` whose
``embed(texts)`` works), unless the caller passes the vectors itself.

The ``db_input`` dicts each operation takes, and what it answers, are described in
:mod:`agents_core.clients.chroma.db_input`. Unknown keys are refused, so a typo such as
``"metadata"`` for ``"metadatas"`` is a :class:`~agents_core.errors.ConfigError` rather than
silently lost data.

The package: :mod:`.client` (the client: connection, embeddings, the operations),
:mod:`.db_input` (the ``db_input`` dicts, checked, and the answers read back), :mod:`.database`
(the tenant, database and collections on the server, and the routes used). Writes larger than the
server's ``max_batch_size`` are sent in several requests.

Authentication: a Chroma server started with token auth (or a proxy in front of it) wants a token
with every request. Give it as ``api_key``; ``auth_header`` says how it is sent:
``"Authorization"`` (default) sends ``Authorization: Bearer <token>``, ``"X-Chroma-Token"`` (or any
other header name a proxy expects) sends the bare token in that header, matching the server's
``chroma_auth_token_transport_header`` setting. The token is part of :meth:`ChromaClient.serialize`
and never appears in ``repr()``, logs, errors or status messages.

Errors: an HTTP error status raises :class:`~agents_core.errors.HTTPStatusError` carrying
Chroma's own message, an unreachable server :class:`~agents_core.errors.ClientConnectionError`,
a slow one :class:`~agents_core.errors.InferenceTimeoutError`, a malformed ``db_input``
:class:`~agents_core.errors.ConfigError` naming the field.

``ChromaClient`` is imported on first use (PEP 562).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...support.lazy import lazy_facade

if TYPE_CHECKING:
    from .client import ChromaClient as ChromaClient
else:
    __getattr__, __dir__ = lazy_facade(__name__)
