"""Benchmarks: the framework against the raw middleware, on one machine, in one run.

``python -m benchmarks.run [--quick]`` (or ``nox -s bench``) measures one-hop latency and throughput
through a relay component (memory, Zenoh, ROS 2), recipe start-up, and the LLM component against a
direct llama-cpp-python call, and writes a JSON file and a PNG plot. See ``benchmarks/README.md``.
"""
