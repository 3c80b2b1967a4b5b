"""Developer entry points: ``nox -s tests``, ``nox -s lint``, ``nox -s types``, ``nox -s demo``.

Sessions install what they need into their own virtual environments, so a machine with only
Python (and ``pip install nox``) can run every one of them.
"""

from __future__ import annotations

import nox

nox.options.sessions = ["tests", "tests_ros2", "install_check", "lint", "types"]
nox.options.reuse_existing_virtualenvs = True

# Sessions use the interpreter that runs nox, so a fresh machine needs no particular version.


@nox.session
def tests(session: nox.Session) -> None:
    """Unit tests and the conformance suite on what this machine has (memory, plus zenoh)."""
    session.install("-e", ".[dev,zenoh]")
    session.run("pytest", *(session.posargs or ["tests"]))


@nox.session
def tests_ros2(session: nox.Session) -> None:
    """The ROS 2 adapter: builds interfaces/ into the session's venv, then conformance + interop tests."""
    session.install("-e", ".[ros2,dev]")
    # The interface package must build against the ROS packages of this very environment.
    session.install("--no-build-isolation", "./interfaces")
    session.run("pytest", "tests/conformance", "tests/ros2", "-k", "ros2", *session.posargs)


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
    session.run("ruff", "check", "src", "tests", "noxfile.py")


@nox.session
def types(session: nox.Session) -> None:
    """mypy --strict on src/."""
    session.install("-e", ".[dev,zenoh]")
    session.run("mypy", "src")


@nox.session
def demo(session: nox.Session) -> None:
    """Run the demo recipe (the README's first command)."""
    session.install("-e", ".")
    session.run("python", "-m", "agents_core.demo", *session.posargs)
