"""Tests of the rmw_zenoh transport: wire format against independent oracles, pub/sub, services, hostile input."""
