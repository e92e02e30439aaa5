"""Specs of the built-in BRDFs (role ``brdf``). numpy evaluation always; torch/JAX/Dr.Jit when installed."""

from pgc.registry import ImplementationSpec

SPECS = [
    ImplementationSpec(role="brdf", name="lambertian", factory="pgc.brdfs.models:LambertianBRDF",
                       description="Lambertian diffuse (base colour only); numpy/torch/jax/drjit evaluation"),
    ImplementationSpec(role="brdf", name="disney", factory="pgc.brdfs.models:DisneyBRDF",
                       description="Disney diffuse + Disney sheen with tint (Burley 2012; specular, metallic, "
                                   "clearcoat 0); parameters roughness, sheen, sheen_tint"),
    ImplementationSpec(role="brdf", name="pgc-sheen", factory="pgc.brdfs.models:PGCSheenBRDF",
                       description="the paper's model: Zeltner 2022 LTC microfiber sheen over H_s-scaled Disney "
                                   "diffuse; parameters roughness, sheen_color, sheen_roughness"),
]
