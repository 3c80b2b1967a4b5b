"""A Zenoh router for the rmw_zenoh tests, in a process of its own: ``python router.py PORT`` (stops on SIGTERM)."""

from __future__ import annotations

import sys

from agents_zenoh.router import serve_router

if __name__ == "__main__":
    serve_router([f"tcp/127.0.0.1:{sys.argv[1]}"], on_ready=lambda _s: print("ready", flush=True))
