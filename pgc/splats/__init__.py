"""Backend-independent maths of mesh-embedded Gaussian splatting (numpy, float64-capable).

``binding``: triangle frames and the local-to-world transform; ``sh``: real spherical harmonics (3DGS
convention); ``init``: initial Gaussians on a mesh; ``reference``: the per-pixel float64 test-oracle
rasteriser; ``quaternion``: (w, x, y, z) quaternion helpers.
"""
