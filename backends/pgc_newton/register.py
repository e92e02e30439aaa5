"""Entry point of the `pgc_newton` plugin: gathers the specs of every `specs_*.py` module (light imports only)."""

from pgc.registry import spec_plugin_hook

pgc_register_implementations = spec_plugin_hook("pgc_newton")
