"""XPBD cloth simulator in PyTorch (``xpbd-torch``): the shared kernels of :mod:`pgc.sim.xpbd`, eager."""
