"""Built-in implementations of the core package, registered through the entry point ``core`` exactly like
third-party plugins. Each area declares its specs in a light ``specs_*.py`` module, with the optional modules
an implementation needs in its ``requires`` (the reconstructors: pymeshlab and xatlas, ``pgc[meshlab]``); the
implementations that are only role glue sit beside them (``reconstructors.py``, ``metrics.py``), those that are
the area's maths stay in it (``pgc.brdfs.models``, ``pgc.albedo.shading_ratio``)."""

from pgc.registry import spec_plugin_hook

pgc_register_implementations = spec_plugin_hook(__name__)
