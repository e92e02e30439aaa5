"""The maths of mesh-embedded Gaussian splatting, written once over :mod:`pgc.arrays` (numpy float64, torch, JAX).

``quaternion``: (w, x, y, z) quaternion helpers; ``binding``: triangle frames and the local-to-world transform;
``projection``: the EWA projection with the 2D pixel filter, SH colour and the contract's constants; ``sh``: real
spherical harmonics (3DGS convention); ``reference``: the per-pixel float64 test-oracle rasteriser; ``fused``: the
compiled fast path (``fused.cpp``) tested against it; ``init``: initial Gaussians on a mesh; ``fit``/``fitplan``:
the one fit loop.
"""
