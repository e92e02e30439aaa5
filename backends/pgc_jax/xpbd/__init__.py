"""XPBD cloth simulator in JAX (``xpbd-jax``): the shared kernels of :mod:`pgc.sim.xpbd`, one jitted frame."""
