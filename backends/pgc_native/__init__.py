"""Native backend: roles implemented as compiled C++/OpenMP kernels (built through :mod:`pgc.native`), no array
framework needed. Keep this file light: registration must not build or load a kernel.
"""
