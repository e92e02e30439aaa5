"""Cloth reflectance models (role ``brdf``): Lambertian, Disney (diffuse + sheen), PGC sheen (Zeltner LTC sheen
over H_s-scaled Disney diffuse). The maths lives once in :mod:`pgc.brdfs.maths`, evaluated on numpy, torch,
JAX or Dr.Jit arrays through :mod:`pgc.arrays`. Importing this package imports no array library."""
