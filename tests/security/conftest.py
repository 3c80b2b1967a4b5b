"""Fixtures of the security tests: ``running`` (the Shouter recipe on memory), from :mod:`tests.ui.login_parts`."""

from ..ui.login_parts import running  # noqa: F401  (a fixture, registered for this folder)
