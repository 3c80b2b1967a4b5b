"""Fixtures of the ui tests: ``running`` (the Shouter recipe, active on memory) from :mod:`tests.ui.login_parts`."""

from .login_parts import running  # noqa: F401  (a fixture, registered for this folder)
