"""A fourth transport, the test's own, registered as a third party would: nothing in agents_core names it.

- ``zenloop``: a cross-process transport on the Zenoh driver under another name (``transport.py``);
- ``memloop``: an in-process one wrapping the memory driver.

Both are described in ``descriptor.py`` (no middleware imported there) and registered by an
``agents_core.transports`` entry point that the test writes into a ``.dist-info`` folder put on
``PYTHONPATH`` (:func:`install_entry_points`).
"""
