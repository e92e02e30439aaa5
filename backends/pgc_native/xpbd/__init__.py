"""``xpbd-native``: the XPBD cloth frame step of :mod:`pgc.sim.xpbd` as one compiled C++/OpenMP call."""
