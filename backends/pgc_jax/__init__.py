"""JAX backend: the same compute roles as pgc_torch. Keep this file light (no jax import)."""
