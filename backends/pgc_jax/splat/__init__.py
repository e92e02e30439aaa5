"""JAX splat renderer: the fused kernel as a custom VJP, tile-chunk compositing by XLA and the fit's arrays (the
binding, projection and losses are the core's, written once over :mod:`pgc.arrays`)."""
