"""Newton backend: roles implemented on NVIDIA Warp's Newton physics engine (PyPI ``newton``). Keep this file
light: registration must not import Warp or Newton.
"""
