"""JAX splat renderer: binding, SH, EWA projection, tile-chunk compositing and the mesh-embedded fit."""
