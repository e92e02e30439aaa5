"""Entry point module (``[project.entry-points.pgc] example = "pgc_example_plugin.register"``).

PGC calls the ``pgc_register_implementations`` hook to learn what this plugin provides. Declaring an
implementation is cheap: the factory is a ``"module:attr"`` string that PGC imports only when a run
selects it, and ``requires`` names modules checked without importing them.
"""

from __future__ import annotations

from pgc.registry import ImplementationSpec, hookimpl


@hookimpl
def pgc_register_implementations() -> list[ImplementationSpec]:
    return [
        ImplementationSpec(
            role="filter", name="box", factory="pgc_example_plugin.box_blur:BoxBlurFilter",
            description="alpha-aware separable box blur in numpy (example third-party plugin)",
            options="pgc_example_plugin.box_blur:BoxBlurOptions", requires=("numpy",)),
    ]
