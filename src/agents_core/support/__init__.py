"""The base floor's machinery: helpers with no framework vocabulary, imported by every layer above.

- :mod:`.lazy`: the façades' lazy re-exports (each name written once) and the old paths of moved modules;
- :mod:`.lazy_numpy`: numpy, imported at its first use;
- :mod:`.version`: the package version, read from pyproject.toml;
- :mod:`.registry`: the one rule of every name-keyed table (types, codecs, clients, transports);
- :mod:`.bounded_json`: JSON decoding bounded in size and depth (network input);
- :mod:`.checked_attrs`: attrs classes whose fields are checked against their annotations;
- :mod:`.concurrency`: the bounded queue drained by a thread of its own, and close-once;
- :mod:`.console`: the status lines for the person running a recipe;
- :mod:`.install_hint`: the pip command that installs a missing extra.

Importing this package imports none of them.
"""

from __future__ import annotations
