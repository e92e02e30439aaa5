"""``xpbd-native``: the XPBD cloth frame step of :mod:`pgc.sim.kernels` as one compiled C++/OpenMP call."""
