"""The ``jax`` splat_renderer: rendering contract of :mod:`pgc.roles.splat_renderer` on JAX/XLA."""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.cores import allotted_cores
from pgc.errors import PGCConfigError
from pgc.events import Reporter
from pgc.roles.splat_renderer import FitSplatsSettings, RenderOutput, SplatFit, SplatRenderer
from pgc.splats.fit import fit_splats
from pgc.splats.reference import background_image
from pgc.types import Camera, Capture, Mesh, WorldGaussians
from pgc_jax.specs_splat import JaxSplatOptions


def _float_dtype(precision: str) -> Any:
    """JAX dtype of ``precision``; float64 needs JAX's x64 mode switched on before arrays exist."""
    import jax
    import jax.numpy as jnp

    if precision == "float64":
        if not jax.config.read("jax_enable_x64"):
            raise PGCConfigError("splat_renderer 'jax': precision = 'float64' needs JAX's x64 mode; set the "
                                 "environment variable JAX_ENABLE_X64=1 or use precision = 'float32'")
        return jnp.float64
    return jnp.float32


class JaxSplatRenderer(SplatRenderer):
    """3DGS rasteriser and mesh-embedded splat fit in JAX (see ``docs/splats_jax.md``)."""

    Options = JaxSplatOptions

    def __init__(self, options: JaxSplatOptions | dict[str, Any] | None = None) -> None:
        super().__init__(options)
        self.dtype = _float_dtype(self.options.precision)

    @property
    def compositor(self) -> str:
        """'fused' or 'xla': the rendering path this instance uses."""
        import jax

        from pgc.splats import fused

        return fused.render_path(self.options.compositor, "xla", host=jax.default_backend() == "cpu")

    @property
    def threads(self) -> int:
        """Threads of the fused kernel."""
        return self.options.threads or allotted_cores()

    def render(self, gaussians: WorldGaussians, camera: Camera, background: np.ndarray | None = None,
               sh_degree: int | None = None) -> RenderOutput:
        import jax
        import jax.numpy as jnp

        from pgc_jax.splat.binning import bucket
        from pgc_jax.splat.render import render_view, rotmats_of

        n = len(gaussians.means)
        sh = np.asarray(gaussians.sh)  # shapes and values checked by the role (check_render_inputs)
        degree = int(round(np.sqrt(sh.shape[1]))) - 1 if sh_degree is None else int(sh_degree)
        bg = background_image(background, camera.height, camera.width)
        if self.compositor == "fused":
            return self._render_fused(gaussians, sh, camera, bg, degree)
        m = bucket(n)  # padded with transparent Gaussians: fewer recompilations for varying N
        pad = lambda x, fill=0.0: np.concatenate(  # noqa: E731
            [np.asarray(x, np.float64), np.full((m - n,) + np.shape(x)[1:], fill)], axis=0)
        dt = self.dtype
        means, quats, scales = (jnp.asarray(pad(x), dt) for x in (gaussians.means, gaussians.quats, gaussians.scales))
        opac, shs = jnp.asarray(pad(gaussians.opacities), dt), jnp.asarray(pad(sh), dt)
        o = self.options
        depth64 = pad(gaussians.means) @ camera.R[2] + camera.t[2]  # float64 sort keys, as the reference's
        color, alpha, depth = jax.device_get(render_view(
            means, rotmats_of(quats), scales, opac, shs, camera, jnp.asarray(bg, dt), sh_degree=degree,
            tile=o.tile_size, chunk=o.chunk_size, near=o.near, sort_depth=depth64))
        return RenderOutput(color=np.asarray(color, np.float32), alpha=np.asarray(alpha, np.float32),
                            depth=np.asarray(depth, np.float32))

    def _render_fused(self, gaussians: WorldGaussians, sh: np.ndarray, camera: Camera, bg: np.ndarray,
                      degree: int) -> RenderOutput:
        """The fused kernel's forward on numpy arrays directly (no gradient is asked of ``render``)."""
        from pgc.splats import fused
        from pgc.splats.quaternion import quat_to_rotmat

        dt = np.float64 if self.options.precision == "float64" else np.float32
        arrays = [np.asarray(x, dt) for x in (gaussians.means, quat_to_rotmat(np.asarray(gaussians.quats, np.float64)),
                                              gaussians.scales, gaussians.opacities, sh)]
        out = fused.forward(arrays, fused.camera_vector(camera, self.options.near), bg.astype(dt), camera.height,
                            camera.width, (degree + 1) ** 2, fused.DEFAULT_TILE, self.threads,
                            check_finite=False)  # checked by the role
        return RenderOutput(color=out.color.astype(np.float32), alpha=out.alpha.astype(np.float32),
                            depth=out.depth.astype(np.float32))

    def fit(self, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | None = None,
            reporter: Reporter | None = None) -> SplatFit:
        from pgc_jax.splat.fit import JaxFitBackend

        return fit_splats(JaxFitBackend(self), capture, mesh, settings, reporter)
