"""Real spherical harmonics up to degree 3 in the 3DGS convention (constants and signs of 3DGS).

``colour = sum_k sh[k] * basis[k](d) + 0.5``, clamped at 0, with ``d`` the unit direction from the camera
centre to the Gaussian. :func:`sh_basis_terms` uses only arithmetic, so numpy, torch and JAX arrays share it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
         0.5462742152960396)
SH_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
         -0.4570457994644658, 1.445305721320277, -0.5900435899266435)
MAX_SH_DEGREE = 3


def num_sh_coeffs(degree: int) -> int:
    return (degree + 1) ** 2


def sh_basis_terms(x: Any, y: Any, z: Any, degree: int) -> list[Any]:
    """The (degree+1)^2 basis functions at unit direction components x, y, z (arrays of any library)."""
    if not 0 <= degree <= MAX_SH_DEGREE:
        raise ValueError(f"SH degree must be in [0, {MAX_SH_DEGREE}], got {degree}")
    terms = [SH_C0 + 0 * x]
    if degree >= 1:
        terms += [-SH_C1 * y, SH_C1 * z, -SH_C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        terms += [SH_C2[0] * x * y, SH_C2[1] * y * z, SH_C2[2] * (2 * zz - xx - yy), SH_C2[3] * x * z,
                  SH_C2[4] * (xx - yy)]
    if degree >= 3:
        terms += [SH_C3[0] * y * (3 * xx - yy), SH_C3[1] * x * y * z, SH_C3[2] * y * (4 * zz - xx - yy),
                  SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy), SH_C3[4] * x * (4 * zz - xx - yy),
                  SH_C3[5] * z * (xx - yy), SH_C3[6] * x * (xx - 3 * yy)]
    return terms


def sh_basis(dirs: np.ndarray, degree: int) -> np.ndarray:
    """(..., 3) unit directions -> (..., (degree+1)^2) basis values (numpy)."""
    d = np.asarray(dirs)
    return np.stack(sh_basis_terms(d[..., 0], d[..., 1], d[..., 2], degree), -1)


def rgb_to_sh_dc(rgb: np.ndarray) -> np.ndarray:
    """The DC coefficient whose colour (viewed from anywhere) is ``rgb``."""
    return (np.asarray(rgb) - 0.5) / SH_C0


def sh_to_rgb_dc(dc: np.ndarray) -> np.ndarray:
    return np.asarray(dc) * SH_C0 + 0.5
