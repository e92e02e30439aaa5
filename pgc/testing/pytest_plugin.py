"""pytest plugin (entry point ``pytest11``): fixtures for PGC plugin authors."""

from __future__ import annotations

import pytest


@pytest.fixture
def pgc_registry():
    """An isolated, empty :class:`pgc.registry.Registry` to register implementations into."""
    from pgc.registry import Registry

    return Registry()
