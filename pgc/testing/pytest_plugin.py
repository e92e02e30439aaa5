"""pytest plugin (entry point ``pytest11``, active wherever PGC is installed): fixtures for plugin authors.

- ``pgc_registry``: an isolated, empty :class:`pgc.registry.Registry` (no entry points loaded, nothing
  blocked) to register implementations into by hand.
- The per-role conformance suites live in :mod:`pgc.testing.conformance`: subclass one in a ``Test*`` class
  and override its ``implementation`` fixture (docs/writing-a-plugin.md).
"""

from __future__ import annotations

import pytest


@pytest.fixture
def pgc_registry():
    """An isolated, empty :class:`pgc.registry.Registry` to register implementations into."""
    from pgc.registry import Registry

    return Registry()
