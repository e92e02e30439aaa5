"""Torch splat renderer: the fused kernel as an autograd function, pure-torch compositing and the fit's tensors
(the binding, projection and losses are the core's, written once over :mod:`pgc.arrays`)."""
