"""The ``torch`` PBR renderer: fast shading of a mesh under an environment, screen and texture space.

Radiance toward the viewer at a surface point x with normal n (turned toward the viewer: two-sided cloth):
``L(x, v) = (4 pi / n_dirs) sum_k f(l_k, v) cos(l_k) [vis_k(x) E_k + (1 - vis_k(x)) E_bounce]``
over a Fibonacci direction set l_k (:mod:`.lighting`), with visibility ray cast per vertex and
interpolated (or per point), E_k the environment averaged over each direction's cell, and
``E_bounce = mean(base colour) * mean_k(vis E_k)`` (the radiance of a diffuse occluder lit by the
unoccluded environment; zero with ``indirect = False``). The BRDF is :mod:`pgc.brdfs.maths` on torch.
Its error against the path tracer is measured in benchmarks/bench_pbr.py. No material fitting.
"""

from __future__ import annotations

import math

import numpy as np

from pgc.arrays import array_ops
from pgc.brdfs.maths import EVALUATORS, tangent_frame
from pgc.brdfs.parameters import PARAMETERS
from pgc.errors import PGCDataError
from pgc.roles.pbr_renderer import PBRRenderer
from pgc.roles.splat_renderer import RenderOutput
from pgc.sampling import fibonacci_sphere
from pgc.types import Camera, Light, Material, Mesh
from pgc_torch.pbr.lighting import direction_radiance
from pgc_torch.pbr.visibility import visibility
from pgc_torch.specs_pbr import TorchPBROptions
from pgc_torch.threads import torch_threads


class TorchPBRRenderer(PBRRenderer):
    """Environment lighting with ray-cast visibility and analytic BRDF shading (see module docstring)."""

    Options = TorchPBROptions
    options: TorchPBROptions

    def __init__(self, options=None) -> None:
        super().__init__(options)
        self._vis_cache: tuple[bytes, np.ndarray] | None = None

    # -- geometry -----------------------------------------------------------------------------------------
    def _offset(self, mesh: Mesh) -> float:
        return self.options.ray_offset * (float(np.linalg.norm(np.ptp(mesh.vertices, axis=0))) or 1.0)

    def _vertex_visibility(self, mesh: Mesh, directions: np.ndarray, scene: Mesh) -> np.ndarray:
        """Per-vertex visibility against ``scene`` (the mesh and any occluder), cached for the last geometry
        (views of one frame share it)."""
        key = mesh.vertices.tobytes() + scene.vertices.tobytes() + scene.faces.tobytes() + directions.tobytes()
        if self._vis_cache is None or self._vis_cache[0] != key:
            vis = visibility(scene, mesh.vertices, mesh.vertex_normals(), directions, self._offset(mesh))
            self._vis_cache = (key, vis)
        return self._vis_cache[1]

    def _surface(self, mesh: Mesh, face: np.ndarray, bary: np.ndarray, directions: np.ndarray,
                 occluder: Mesh | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, unit shading normals and visibility (P, n) at barycentric points of faces; visibility
        is ray cast against the mesh and ``occluder``."""
        scene = mesh if occluder is None else _merged(mesh, occluder)
        corners = mesh.faces[face]
        points = np.einsum("pk,pkc->pc", bary, mesh.vertices[corners])
        if self.options.smooth_normals:
            normals = np.einsum("pk,pkc->pc", bary, mesh.vertex_normals()[corners])
        else:
            normals = mesh.face_normals()[face]
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        if self.options.visibility_at == "vertex":
            vis = np.einsum("pk,pkn->pn", bary, self._vertex_visibility(mesh, directions, scene)[corners])
        else:
            vis = visibility(scene, points, mesh.face_normals()[face], directions, self._offset(mesh))
        return points, normals, vis

    # -- shading ------------------------------------------------------------------------------------------
    def _shade(self, material: Material, light: Light, points: np.ndarray, normals: np.ndarray,
               view_from: np.ndarray, base: np.ndarray, vis: np.ndarray, directions: np.ndarray) -> np.ndarray:
        import torch

        if material.brdf not in EVALUATORS:
            raise PGCDataError(f"material.brdf '{material.brdf}' is not one of {sorted(EVALUATORS)}")
        ops = array_ops("torch")
        evaluate = EVALUATORS[material.brdf]
        params = {p.name: material.params.get(p.name, p.init[0] if p.size == 1 else list(p.init))
                  for p in PARAMETERS[material.brdf]}
        env = direction_radiance(light, directions)
        bounce = np.zeros(3)
        if self.options.indirect and len(points):
            bounce = np.mean(base, axis=0) * np.mean(vis[..., None] * env[None], axis=(0, 1))
        weight = 4.0 * math.pi / len(directions)
        dirs = torch.as_tensor(directions, dtype=torch.float32)
        env_t = torch.as_tensor(env, dtype=torch.float32)
        bounce_t = torch.as_tensor(bounce, dtype=torch.float32)
        out = np.zeros((len(points), 3), dtype=np.float32)
        with torch_threads(self.options.threads), torch.no_grad():
            for s in range(0, len(points), self.options.chunk):
                sl = slice(s, s + self.options.chunk)
                n = torch.as_tensor(normals[sl], dtype=torch.float32)
                v = torch.as_tensor(view_from[sl] - points[sl], dtype=torch.float32)
                v = v / v.norm(dim=1, keepdim=True).clamp_min(1e-12)
                n = torch.where((n * v).sum(1, keepdim=True) < 0, -n, n)  # two-sided: face the viewer
                t, b = tangent_frame(ops, n)
                to_local = lambda d: torch.stack([(d * t).sum(-1), (d * b).sum(-1), (d * n).sum(-1)], -1)  # noqa: E731
                v_loc = to_local(v)  # (p, 3)
                l_loc = torch.stack([dirs @ t.T, dirs @ b.T, dirs @ n.T], -1).transpose(0, 1)  # (p, k, 3)
                f_cos = evaluate(ops, l_loc, v_loc[:, None, :],  # V broadcasts: its terms cost (p, 1)
                                 torch.tensor(base[sl], dtype=torch.float32)[:, None, :], params)
                vis_t = torch.as_tensor(vis[sl], dtype=torch.float32)[..., None]
                incoming = vis_t * env_t[None] + (1.0 - vis_t) * bounce_t
                out[sl] = (weight * (f_cos * incoming).sum(1)).numpy()
        return out

    # -- role interface -----------------------------------------------------------------------------------
    def render(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
               occluder: Mesh | None = None) -> RenderOutput:
        from pgc.texture.sample import sample_uv
        from pgc.texture.visibility import render_faces

        directions = fibonacci_sphere(self.options.directions)
        raster = render_faces(mesh, camera, occluder=occluder)
        covered = raster.face_id >= 0
        face, bary = raster.face_id[covered], raster.bary[covered]
        points, normals, vis = self._surface(mesh, face, bary, directions, occluder)
        if material.base_color is not None:
            if mesh.uv is None:
                raise PGCDataError(f"mesh '{mesh.name}' has no UVs for the material's base_color texture")
            uv = np.einsum("pk,pkc->pc", bary, mesh.uv[mesh.face_uv[face]].astype(np.float64))
            base = sample_uv(np.asarray(material.base_color, np.float32), uv)
        else:
            base = np.broadcast_to(_constant_base(material), (len(face), 3))
        color = np.zeros((camera.height, camera.width, 3), dtype=np.float32)
        color[covered] = self._shade(material, light, points, normals, np.broadcast_to(camera.center, points.shape),
                                     base, vis, directions)
        return RenderOutput(color=color, alpha=covered.astype(np.float32))

    def render_texture(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
                       resolution: tuple[int, int], occluder: Mesh | None = None) -> tuple[np.ndarray, np.ndarray]:
        from pgc.texture.atlas import texel_geometry
        from pgc.texture.sample import sample_uv

        height, width = int(resolution[0]), int(resolution[1])
        directions = fibonacci_sphere(self.options.directions)
        geom = texel_geometry(mesh, height, width)
        valid = geom.valid
        points, normals, vis = self._surface(mesh, geom.face[valid], geom.bary[valid], directions, occluder)
        if material.base_color is not None:
            rows, cols = np.nonzero(valid)
            uv = np.stack([(cols + 0.5) / width, 1.0 - (rows + 0.5) / height], axis=1)
            base = sample_uv(np.asarray(material.base_color, np.float32), uv)
        else:
            base = np.broadcast_to(_constant_base(material), (len(points), 3))
        out = np.zeros((height, width, 3), dtype=np.float32)
        out[valid] = self._shade(material, light, points, normals, np.broadcast_to(camera.center, points.shape),
                                 base, vis, directions)
        return out, valid.astype(np.float32)


def _merged(mesh: Mesh, other: Mesh) -> Mesh:
    """One mesh holding the faces of both (geometry only), for ray casting."""
    return Mesh(np.concatenate([mesh.vertices, other.vertices]),
                np.concatenate([mesh.faces, other.faces + len(mesh.vertices)]))


def _constant_base(material: Material) -> np.ndarray:
    value = material.params.get("base_color")
    if value is None:
        raise PGCDataError("material has neither a base_color texture nor params['base_color']; give one")
    return np.asarray(value, dtype=np.float64).reshape(3)

