"""The Zenoh adapter for agents_core (install with ``pip install 'agents-core[zenoh]'``).

Importing this package does not import ``zenoh``; :mod:`agents_zenoh.transport` does.
"""
