"""Built-in implementations that need only numpy/scipy, registered through the entry point ``core``
exactly like third-party plugins. Each area declares its specs in a ``specs_*.py`` module."""

from pgc.registry import spec_plugin_hook

pgc_register_implementations = spec_plugin_hook(__name__)
