"""Backend-independent pieces of the XPBD cloth simulators (numpy, and the XPBD maths over pgc.arrays).

- :mod:`pgc.sim.options`: the options shared by ``xpbd-torch`` and ``xpbd-jax`` (light module);
- :mod:`pgc.sim.model`: constraint topology, rest lengths, masses, graph colouring;
- :mod:`pgc.sim.xpbd`: the XPBD projection and collision maths, written once for numpy, torch and JAX;
- :mod:`pgc.sim.collision`: per-frame candidate search and signed distances to the body;
- :mod:`pgc.sim.schedule`: the body sequence with settle frames and the blend-in from the capture pose;
- :mod:`pgc.sim.driver`: the frame loop shared by the backends;
- :mod:`pgc.sim.sagfree`: the sag-free rest shape (inverse statics on rest lengths).
"""
