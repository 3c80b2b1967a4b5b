"""Tests of the Zenoh adapter: codecs, transport specifics, and multi-process recipes driven by a plain Zenoh client."""
