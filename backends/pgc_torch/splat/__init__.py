"""Torch splat renderer: mesh binding, EWA projection, tile binning, compiled or pure-torch compositing, fit."""
