"""Parameter tables of the built-in BRDFs: names, bounds, the paper's initial values (light module).

Initial values follow the paper's supplement (Table "PBR Parameter Initialization"): roughness 0.8,
sheen 1.4, sheen colour (0.75, 0.73, 0.27), sheen roughness 0.5 (specular 0, metallic 0, clearcoat 0 are
fixed, not parameters). Disney's ``sheen_tint`` is not listed there; Mitsuba's default 0 is used.
"""

from __future__ import annotations

from pgc.roles.brdf import BRDFParameter

ROUGHNESS = BRDFParameter("roughness", 1, 0.0, 1.0, (0.8,), "Disney diffuse roughness (retro-reflection)")

PARAMETERS: dict[str, tuple[BRDFParameter, ...]] = {
    "lambertian": (),
    "disney": (
        ROUGHNESS,
        BRDFParameter("sheen", 1, 0.0, 5.0, (1.4,),
                      "Disney sheen weight (the paper's fits reach 4.5, so the bound is above Disney's 1)"),
        BRDFParameter("sheen_tint", 1, 0.0, 1.0, (0.0,), "mix of white and the base-colour hue in the sheen"),
    ),
    "pgc-sheen": (
        ROUGHNESS,
        BRDFParameter("sheen_color", 3, 0.0, 1.0, (0.75, 0.73, 0.27), "sheen colour sigma_s (linear RGB)"),
        BRDFParameter("sheen_roughness", 1, 0.01, 1.0, (0.5,), "Zeltner sheen roughness alpha_s"),
    ),
}
"""BRDF name -> its parameters, in a fixed order (the order of fitted parameter vectors)."""

SIMPLICITY = ("lambertian", "disney", "pgc-sheen")
"""Models from simplest to richest (fewest parameters first): the order model selection prefers."""
