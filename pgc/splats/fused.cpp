// The fused splat path: projection, SH colour, culling, binning, depth order and compositing of world
// Gaussians in one call, and the backward of all of it (CPU, OpenMP, SIMD across the pixels of a tile row).
// Loaded through ctypes by pgc_torch.splat.fused; arrays are contiguous, row-major.
//
// Contract (pgc/splats/projection.py, pgc/splats/reference.py): scales clamped to [0, 1e4]; x_c = R x + t,
// culled when z < near; Sigma2D = J W Sigma W^T J^T + 0.1 I; the opacity times the coverage
// k = sqrt(det(J W Sigma W^T J^T) / det(Sigma2D)) (Mip-Splatting's 2D filter); r = ceil(3 sqrt(lambda_max));
// pixel centres (x + 0.5, y + 0.5) inside the box |dx| <= r, |dy| <= r; alpha = min(0.99, o k exp(power)),
// skipped below 1/255 (a Gaussian with o k < 1/255 is culled); a pixel stops before its transmittance would
// fall below 1e-4; colour = SH + 0.5 clamped at 0.
//
// Per Gaussian (projection, SH, their backward) the arithmetic is float64, four Gaussians at a time in the lanes
// of a 4-double vector (GCC vector extension: one AVX register, or two SSE2 registers; a lane's result does not
// depend on the other lanes); per pixel-Gaussian pair it is the input type S (float32: 8-wide AVX2 lanes with a
// polynomial exp accurate to ~2e-7 relative).
// Work saving that changes no pixel: per Gaussian and pixel row, the candidate columns are those of the box
// that may reach alpha >= 1/255 (the opacity-aware ellipse q <= 2 ln(255 o), with a margin); a Gaussian is
// binned only to the tiles of its box that hold candidates, and a chunk of 8 pixels starts at a row's first
// candidate (any column), so small footprints fill the lanes. The exact per-pixel test decides as before. The
// candidate columns are solved four rows at a time (float64 vectors, branch-free).
// Memory: each tile-list entry holds a copy of its Gaussian's screen-space parameters and its candidate rows in
// the tile, in tile-list order, so the pixel loops stream through the entries (with software prefetch of the
// next entries and their row ranges) instead of gathering per-rank arrays: per entry the loops run only a few
// 8-pixel chunks (footprints of 3-5 px at 50k Gaussians), and the gathers' latency was most of their time.
// A float entry is one aligned cache line, written by non-temporal stores (the build scatters entries over the
// tile lists; ordinary stores would read every line first). The one remaining gather, the per-rank copy of the
// projected Gaussians in depth order, prefetches 16 ranks ahead. Buffers written in full are not zero-filled.
// The backward compositing takes a tile's entries 16 at a time: it lists their 8-pixel chunks, computes every
// chunk's exp(power) and footprint test in one loop of independent chunks (the exp's long dependency chain
// overlaps across chunks instead of stalling each entry's short loop), then restores the compositing state and
// adds the lane sums chunk after chunk, the colour and depth sums in a second loop over an entry's chunks (the
// ten sums spilled to the stack). The per-pixel arithmetic is unchanged (same bytes). (The forward in the same
// form measured no faster: its state update is short and its chunks already overlap.)
// Determinism: every pixel's arithmetic is independent of the thread count; tile lists are a counting sort
// in rank order (ranks increase within a tile); the backward writes one gradient row per
// (tile, Gaussian) entry into slots ordered by Gaussian, then tile, and sums each Gaussian's rows in that
// order, so the gradients are the same bytes for any thread count too.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <vector>

#include <omp.h>

#if defined(__AVX__)
#include <immintrin.h>
#endif

namespace {

constexpr double DILATION = 0.1, MAX_SCALE = 1e4;
constexpr double SH_C0 = 0.28209479177387814, SH_C1 = 0.4886025119029199;
constexpr double SH_C2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
                             0.5462742152960396};
constexpr double SH_C3[7] = {-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
                             -0.4570457994644658, 1.445305721320277, -0.5900435899266435};

// exp for x <= 0 (the Gaussian exponent): Cephes' expf (range reduction by ln 2 in two parts, degree-5
// polynomial), 2^n through the exponent bits; relative error ~2e-7. x is clamped at -30: alpha >= 1/255 needs
// exp(x) >= 1/255 = exp(-5.5), so the clamp changes no composited pixel and keeps every product normal.
inline float exp_neg(float x) {
  x = std::min(std::max(x, -30.0f), 0.0f);
  const float n = std::floor(x * 1.44269504088896341f + 0.5f);
  float r = x - n * 0.693359375f;
  r = r + n * 2.12194440e-4f;
  float p = 1.9875691500e-4f;
  p = p * r + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * (r * r) + r + 1.0f;
  const int32_t bits = (int32_t(n) + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof(float));
  return p * scale;
}
inline double exp_neg(double x) { return std::exp(x); }

struct CameraParams {
  double R[9], t[3], fx, skew, cx, fy, cy, centre[3], near;
};

template <typename S>
struct Inputs {
  const S* means;    // (N, 3) world
  const S* rot;      // (N, 3, 3) world rotation matrices
  const S* scales;   // (N, 3) world standard deviations
  const S* opac;     // (N,)
  const S* sh;       // (N, K, 3)
  int64_t n;
  int K, count;      // SH coefficients stored per Gaussian, used (degree + 1)^2
};

// Per-Gaussian arithmetic on four Gaussians at once (GCC vector extension: one AVX register of doubles, or a
// pair of SSE2 registers without AVX). Lane l holds Gaussian id[l]; every lane's arithmetic is its own, so a
// Gaussian's result does not depend on its block.
#pragma GCC diagnostic ignored "-Wpsabi"  // D4 returned without AVX: internal inline functions, no ABI involved
typedef double D4 __attribute__((vector_size(32)));
constexpr int GL = 4;  // Gaussians per block

inline D4 bc(double x) { return D4{x, x, x, x}; }
// std::min / std::max semantics lane by lane ((b < a) ? b : a, (a < b) ? b : a)
inline D4 vmin(const D4& a, const D4& b) { return b < a ? b : a; }
inline D4 vmax(const D4& a, const D4& b) { return a < b ? b : a; }
// Lane-wise sqrt, floor and ceil: one AVX instruction each, else the scalar function on every lane.
#if defined(__AVX__)
#define PGC_LANEWISE(name, scalar, avx) inline D4 name(const D4& x) { return avx(x); }
#else
#define PGC_LANEWISE(name, scalar, avx) \
  inline D4 name(const D4& x) { return D4{scalar(x[0]), scalar(x[1]), scalar(x[2]), scalar(x[3])}; }
#endif
PGC_LANEWISE(vsqrt, std::sqrt, _mm256_sqrt_pd)
PGC_LANEWISE(vfloor, std::floor, _mm256_floor_pd)
PGC_LANEWISE(vceil, std::ceil, _mm256_ceil_pd)
#undef PGC_LANEWISE

// Element `off` of the rows id[0..3] of an (N, stride) array, as doubles.
template <typename S>
inline D4 gather(const S* a, int64_t stride, const int64_t* id, int64_t off) {
  return D4{double(a[stride * id[0] + off]), double(a[stride * id[1] + off]), double(a[stride * id[2] + off]),
            double(a[stride * id[3] + off])};
}

// Writes the first `lanes` lanes of v to element `off` of the rows id[l] of an (N, stride) array.
template <typename S>
inline void scatter(S* a, int64_t stride, const int64_t* id, int lanes, int64_t off, const D4& v) {
  for (int l = 0; l < lanes; ++l) a[stride * id[l] + off] = S(v[l]);
}

// Projection of four Gaussians (float64), with the intermediates their backward needs.
struct Proj {
  D4 pc[3], J[6], WR[9], sc[3], Tm[6], a, b, c, det, conic[3], u, v, r, dir[3], inv_norm, raw[3];
  D4 coverage;  // sqrt(det(Tm Tm^T) / det): the factor of the opacity
};

inline void sh_basis(const D4* d, int count, D4* out) {
  const D4 x = d[0], y = d[1], z = d[2];
  out[0] = bc(SH_C0);
  if (count > 1) {
    out[1] = -SH_C1 * y;
    out[2] = SH_C1 * z;
    out[3] = -SH_C1 * x;
  }
  if (count > 4) {
    const D4 xx = x * x, yy = y * y, zz = z * z;
    out[4] = SH_C2[0] * x * y;
    out[5] = SH_C2[1] * y * z;
    out[6] = SH_C2[2] * (2.0 * zz - xx - yy);
    out[7] = SH_C2[3] * x * z;
    out[8] = SH_C2[4] * (xx - yy);
    if (count > 9) {
      out[9] = SH_C3[0] * y * (3.0 * xx - yy);
      out[10] = SH_C3[1] * x * y * z;
      out[11] = SH_C3[2] * y * (4.0 * zz - xx - yy);
      out[12] = SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
      out[13] = SH_C3[4] * x * (4.0 * zz - xx - yy);
      out[14] = SH_C3[5] * z * (xx - yy);
      out[15] = SH_C3[6] * x * (xx - 3.0 * yy);
    }
  }
}

// g (count,) = dL/dbasis -> dL/d(direction) (3,).
inline void sh_basis_backward(const D4* d, int count, const D4* g, D4* gd) {
  const D4 x = d[0], y = d[1], z = d[2];
  gd[0] = gd[1] = gd[2] = bc(0.0);
  if (count > 1) {
    gd[1] += -SH_C1 * g[1];
    gd[2] += SH_C1 * g[2];
    gd[0] += -SH_C1 * g[3];
  }
  if (count > 4) {
    const D4 xx = x * x, yy = y * y, zz = z * z;
    gd[0] += SH_C2[0] * y * g[4];
    gd[1] += SH_C2[0] * x * g[4];
    gd[1] += SH_C2[1] * z * g[5];
    gd[2] += SH_C2[1] * y * g[5];
    gd[0] += -2 * SH_C2[2] * x * g[6];
    gd[1] += -2 * SH_C2[2] * y * g[6];
    gd[2] += 4 * SH_C2[2] * z * g[6];
    gd[0] += SH_C2[3] * z * g[7];
    gd[2] += SH_C2[3] * x * g[7];
    gd[0] += 2 * SH_C2[4] * x * g[8];
    gd[1] += -2 * SH_C2[4] * y * g[8];
    if (count > 9) {
      gd[0] += 6 * SH_C3[0] * x * y * g[9];
      gd[1] += SH_C3[0] * (3.0 * xx - 3.0 * yy) * g[9];
      gd[0] += SH_C3[1] * y * z * g[10];
      gd[1] += SH_C3[1] * x * z * g[10];
      gd[2] += SH_C3[1] * x * y * g[10];
      gd[0] += -2 * SH_C3[2] * x * y * g[11];
      gd[1] += SH_C3[2] * (4.0 * zz - xx - 3.0 * yy) * g[11];
      gd[2] += 8 * SH_C3[2] * y * z * g[11];
      gd[0] += -6 * SH_C3[3] * x * z * g[12];
      gd[1] += -6 * SH_C3[3] * y * z * g[12];
      gd[2] += SH_C3[3] * (6.0 * zz - 3.0 * xx - 3.0 * yy) * g[12];
      gd[0] += SH_C3[4] * (4.0 * zz - 3.0 * xx - yy) * g[13];
      gd[1] += -2 * SH_C3[4] * x * y * g[13];
      gd[2] += 8 * SH_C3[4] * x * z * g[13];
      gd[0] += 2 * SH_C3[5] * x * z * g[14];
      gd[1] += -2 * SH_C3[5] * y * z * g[14];
      gd[2] += SH_C3[5] * (xx - yy) * g[14];
      gd[0] += SH_C3[6] * (3.0 * xx - 3.0 * yy) * g[15];
      gd[1] += -6 * SH_C3[6] * x * y * g[15];
    }
  }
}

// Projection of the Gaussians id[0..3]; lanes behind the near plane get r = 0 (their other fields are finite).
template <typename S>
void project(const Inputs<S>& in, const CameraParams& cam, const int64_t* id, Proj& p) {
  const D4 mw[3] = {gather(in.means, 3, id, 0), gather(in.means, 3, id, 1), gather(in.means, 3, id, 2)};
  for (int r = 0; r < 3; ++r)
    p.pc[r] = cam.R[3 * r] * mw[0] + cam.R[3 * r + 1] * mw[1] + cam.R[3 * r + 2] * mw[2] + cam.t[r];
  const D4 x = p.pc[0], y = p.pc[1], z = p.pc[2];
  const auto valid = z >= cam.near;
  const D4 zs = valid ? z : bc(1.0);
  p.u = (cam.fx * x + cam.skew * y) / zs + cam.cx;
  p.v = cam.fy * y / zs + cam.cy;
  p.J[0] = cam.fx / zs;
  p.J[1] = cam.skew / zs;
  p.J[2] = -(cam.fx * x + cam.skew * y) / (zs * zs);
  p.J[3] = bc(0.0);
  p.J[4] = cam.fy / zs;
  p.J[5] = -cam.fy * y / (zs * zs);
  for (int j = 0; j < 3; ++j) p.sc[j] = vmin(vmax(gather(in.scales, 3, id, j), bc(0.0)), bc(MAX_SCALE));
  D4 Rg[9];
  for (int k = 0; k < 9; ++k) Rg[k] = gather(in.rot, 9, id, k);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      p.WR[3 * r + c] = cam.R[3 * r] * Rg[c] + cam.R[3 * r + 1] * Rg[3 + c] + cam.R[3 * r + 2] * Rg[6 + c];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      p.Tm[3 * r + c] = (p.J[3 * r] * p.WR[c] + p.J[3 * r + 1] * p.WR[3 + c] + p.J[3 * r + 2] * p.WR[6 + c]) * p.sc[c];
  p.a = p.Tm[0] * p.Tm[0] + p.Tm[1] * p.Tm[1] + p.Tm[2] * p.Tm[2] + DILATION;
  p.b = p.Tm[0] * p.Tm[3] + p.Tm[1] * p.Tm[4] + p.Tm[2] * p.Tm[5];
  p.c = p.Tm[3] * p.Tm[3] + p.Tm[4] * p.Tm[4] + p.Tm[5] * p.Tm[5] + DILATION;
  p.det = p.a * p.c - p.b * p.b;
  // det(Tm Tm^T) as the squared 2x2 minors of Tm (Cauchy-Binet): no cancellation for needles
  const D4 m0 = p.Tm[1] * p.Tm[5] - p.Tm[2] * p.Tm[4], m1 = p.Tm[2] * p.Tm[3] - p.Tm[0] * p.Tm[5],
           m2 = p.Tm[0] * p.Tm[4] - p.Tm[1] * p.Tm[3];
  p.coverage = vsqrt((m0 * m0 + m1 * m1 + m2 * m2) / p.det);
  p.conic[0] = p.c / p.det;
  p.conic[1] = -p.b / p.det;
  p.conic[2] = p.a / p.det;
  const D4 half = 0.5 * (p.a - p.c);
  const D4 lam = 0.5 * (p.a + p.c) + vsqrt(half * half + p.b * p.b);
  p.r = valid ? vceil(3.0 * vsqrt(lam)) : bc(0.0);
  const D4 d[3] = {mw[0] - cam.centre[0], mw[1] - cam.centre[1], mw[2] - cam.centre[2]};
  p.inv_norm = 1.0 / vsqrt(vmax(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], bc(1e-60)));
  for (int k = 0; k < 3; ++k) p.dir[k] = d[k] * p.inv_norm;
  D4 basis[16];
  sh_basis(p.dir, in.count, basis);
  const int64_t K3 = int64_t(in.K) * 3;
  D4 acc[3] = {bc(0.0), bc(0.0), bc(0.0)};  // the channels' sums interleaved: three independent FMA chains
  for (int k = 0; k < in.count; ++k)
    for (int ch = 0; ch < 3; ++ch) acc[ch] += basis[k] * gather(in.sh, K3, id, 3 * k + ch);
  for (int ch = 0; ch < 3; ++ch) p.raw[ch] = acc[ch] + 0.5;
}

// Screen-space gradients gs (NG) of the Gaussians id[0..lanes-1] (mean2d x, y; conic a, b, c; colour r, g, b;
// opacity; depth; all in front of the near plane) -> gradients of their world parameters.
template <typename S>
void project_backward(const Inputs<S>& in, const CameraParams& cam, const int64_t* id, int lanes, const Proj& p,
                      const D4* gs, S* d_means, S* d_rot, S* d_scales, S* d_opac, S* d_sh) {
  // conic = inverse(Sigma2D): dL/dSigma = -Q G Q with G the symmetric gradient of Q
  const D4 Q[4] = {p.conic[0], p.conic[1], p.conic[1], p.conic[2]};
  const D4 G[4] = {gs[2], 0.5 * gs[3], 0.5 * gs[3], gs[4]};
  D4 QG[4], dS[4];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) QG[2 * r + c] = Q[2 * r] * G[c] + Q[2 * r + 1] * G[2 + c];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) dS[2 * r + c] = -(QG[2 * r] * Q[c] + QG[2 * r + 1] * Q[2 + c]);
  D4 Gc[4] = {dS[0], 0.5 * (dS[1] + dS[2]), 0.5 * (dS[1] + dS[2]), dS[3]};
  // coverage k = sqrt(D0 / D), D0 = det(Sigma2D - s I), D = det(Sigma2D): d(k^2)/dSigma2D =
  // ((1 - k^2) adj(Sigma2D - s I) - k^2 s I) / D with 1 - k^2 = s (a + c - s) / D; dk = d(k^2) / (2 k).
  // Only Gaussians with o k >= 1/255 reach here, so k > 0.
  const D4 g_cov = gs[8] * gather(in.opac, 1, id, 0);
  const auto has_cov = (g_cov != 0.0) & (p.coverage > 0.0);
  {
    const D4 k2 = p.coverage * p.coverage, rest = DILATION * (p.a + p.c - DILATION) / p.det;
    const D4 f = g_cov / (2.0 * p.coverage * p.det);
    Gc[0] = has_cov ? Gc[0] + f * (rest * (p.c - DILATION) - k2 * DILATION) : Gc[0];
    Gc[1] = has_cov ? Gc[1] - f * rest * p.b : Gc[1];
    Gc[2] = has_cov ? Gc[2] - f * rest * p.b : Gc[2];
    Gc[3] = has_cov ? Gc[3] + f * (rest * (p.a - DILATION) - k2 * DILATION) : Gc[3];
  }
  D4 dTm[6];  // 2 Gc Tm
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) dTm[3 * r + c] = 2.0 * (Gc[2 * r] * p.Tm[c] + Gc[2 * r + 1] * p.Tm[3 + c]);
  D4 M[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M[3 * r + c] = p.WR[3 * r + c] * p.sc[c];
  D4 dJ[6], dM[9];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      dJ[3 * r + c] = dTm[3 * r] * M[3 * c] + dTm[3 * r + 1] * M[3 * c + 1] + dTm[3 * r + 2] * M[3 * c + 2];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) dM[3 * r + c] = p.J[r] * dTm[c] + p.J[3 + r] * dTm[3 + c];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      scatter(d_rot, 9, id, lanes, 3 * r + c,
              (cam.R[r] * dM[c] + cam.R[3 + r] * dM[3 + c] + cam.R[6 + r] * dM[6 + c]) * p.sc[c]);
  for (int c = 0; c < 3; ++c) {
    const D4 s = gather(in.scales, 3, id, c);
    const D4 g = p.WR[c] * dM[c] + p.WR[3 + c] * dM[3 + c] + p.WR[6 + c] * dM[6 + c];
    scatter(d_scales, 3, id, lanes, c, (s >= 0.0) & (s <= MAX_SCALE) ? g : bc(0.0));
  }
  // camera-space mean: through J, (u, v) and depth (zs = z: in front of the near plane)
  const D4 x = p.pc[0], y = p.pc[1], z = p.pc[2];
  const D4 iz = 1.0 / z, iz2 = iz * iz, iz3 = iz2 * iz;
  const D4 fxs = cam.fx * x + cam.skew * y;
  const D4 gu = gs[0], gv = gs[1];
  D4 gp[3];
  gp[0] = -cam.fx * iz2 * dJ[2] + gu * cam.fx * iz;
  gp[1] = -cam.skew * iz2 * dJ[2] - cam.fy * iz2 * dJ[5] + gu * cam.skew * iz + gv * cam.fy * iz;
  gp[2] = -cam.fx * iz2 * dJ[0] - cam.skew * iz2 * dJ[1] + 2.0 * fxs * iz3 * dJ[2] - cam.fy * iz2 * dJ[4] +
          2.0 * cam.fy * y * iz3 * dJ[5] - gu * fxs * iz2 - gv * cam.fy * y * iz2 + gs[9];
  // colour: clamp at 0, SH coefficients and the viewing direction
  D4 graw[3];
  for (int ch = 0; ch < 3; ++ch) graw[ch] = p.raw[ch] >= 0.0 ? gs[5 + ch] : bc(0.0);
  D4 basis[16], gbasis[16];
  sh_basis(p.dir, in.count, basis);
  const int64_t K3 = int64_t(in.K) * 3;
  for (int k = 0; k < in.count; ++k) {
    gbasis[k] = bc(0.0);
    for (int ch = 0; ch < 3; ++ch) {
      scatter(d_sh, K3, id, lanes, 3 * k + ch, basis[k] * graw[ch]);
      gbasis[k] += gather(in.sh, K3, id, 3 * k + ch) * graw[ch];
    }
  }
  D4 gdir[3];
  sh_basis_backward(p.dir, in.count, gbasis, gdir);
  const D4 n2 = 1.0 / (p.inv_norm * p.inv_norm);
  const D4 dot = p.dir[0] * gdir[0] + p.dir[1] * gdir[1] + p.dir[2] * gdir[2];
  const auto clamped = n2 <= 1e-60;
  for (int k = 0; k < 3; ++k) {
    const D4 gm = cam.R[k] * gp[0] + cam.R[3 + k] * gp[1] + cam.R[6 + k] * gp[2];
    const D4 gd = p.inv_norm * (clamped ? gdir[k] : gdir[k] - p.dir[k] * dot);
    scatter(d_means, 3, id, lanes, k, gm + gd);
  }
  scatter(d_opac, 1, id, lanes, 0, gs[8] * p.coverage);
}

// One Gaussian in screen space: mean, footprint radius, conic, opacity, colour, depth.
template <typename S>
struct Splat {
  S gx, gy, r, A, B, C, o, col0, col1, col2, depth;
};

// One tile-list entry as the pixel loops read it: a copy of the Gaussian and its candidate rows inside the tile,
// stored in tile-list order so that the loops stream through the entries (64 bytes for float) instead of
// gathering each Gaussian's parameters by rank. Cache-line aligned: a float entry is one line, fetched whole.
template <typename S>
struct alignas(64) Entry {
  Splat<S> s;
  int32_t ya, yb;  // candidate pixel rows inside the tile (global)
  int64_t rows;    // offset of row ya's column range in Workspace::xr
};

// Writes a tile-list entry. A float entry is one cache line, written by non-temporal stores: the build scatters
// entries over the tiles' lists, and ordinary stores would first read each line.
template <typename S>
inline void store_entry(Entry<S>* dst, const Entry<S>& e) { *dst = e; }
#if defined(__AVX__)
template <>
inline void store_entry<float>(Entry<float>* dst, const Entry<float>& e) {
  static_assert(sizeof(Entry<float>) == 64, "one cache line");
  const __m256i* src = reinterpret_cast<const __m256i*>(&e);
  _mm256_stream_si256(reinterpret_cast<__m256i*>(dst), _mm256_loadu_si256(src));
  _mm256_stream_si256(reinterpret_cast<__m256i*>(dst) + 1, _mm256_loadu_si256(src + 1));
}
#endif

// Allocator whose resize() leaves the elements uninitialised: for buffers the code writes in full (a zero fill
// of the megabytes of tile lists and candidate rows would be wasted bandwidth).
template <typename T>
struct NoInit : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = NoInit<U>;
  };
  NoInit() = default;
  template <typename U>
  NoInit(const NoInit<U>&) {}
  template <typename U>
  void construct(U* p) {
    ::new (static_cast<void*>(p)) U;
  }
};
template <typename T>
using Buffer = std::vector<T, NoInit<T>>;

// Everything the backward needs from the forward; owned by the Python side through an opaque handle.
template <typename S>
struct Workspace {
  int H = 0, W = 0, tile = 0, tiles_x = 0, tiles_y = 0;
  std::vector<int64_t> order;              // rank -> Gaussian index, increasing depth (ties by index)
  std::vector<int64_t> rank_of;            // Gaussian index -> rank (-1: culled)
  Buffer<int32_t> xr;                      // per candidate row: candidate columns [xa, xb] (empty when xa > xb)
  std::vector<int64_t> offsets;            // tile t's entries: offsets[t] .. offsets[t + 1] - 1
  Buffer<Entry<S>> ent;                    // tile lists (ranks increase within a tile)
  std::vector<int64_t> ioff;               // entry slots: Gaussian i owns ioff[i] .. ioff[i + 1] - 1 (tile order)
  Buffer<int64_t> slot;                    // slot[j] = the slot of tile-list position j
  Buffer<S> Tfinal;                        // (H, W) final transmittance
  Buffer<int32_t> last;                    // (H, W) entries composited in the pixel's tile list
  int64_t pairs = 0;                       // pixel-Gaussian pairs inside footprint boxes (work measure)
};

// Stable LSD radix sort of indices by a non-negative float key (its bits order like the values).
void radix_sort(std::vector<int64_t>& idx, const std::vector<uint32_t>& key) {
  std::vector<int64_t> tmp(idx.size());
  for (int shift = 0; shift < 32; shift += 11) {
    std::vector<int64_t> count(2049, 0);
    for (int64_t i : idx) ++count[((key[i] >> shift) & 2047) + 1];
    for (int b = 0; b < 2048; ++b) count[b + 1] += count[b];
    for (int64_t i : idx) tmp[count[(key[i] >> shift) & 2047]++] = i;
    idx.swap(tmp);
  }
}

constexpr int LANES = 8;  // pixels per SIMD chunk (one AVX2 register of floats)

// Row stride of the per-tile pixel arrays: the tile width plus one chunk, so a chunk may start at any column of
// the tile (the padding never composites).
inline int padded(int tile) { return (tile + LANES - 1) / LANES * LANES + LANES; }

// The backward pixel loop takes a tile's entries in batches of BATCH: the batch's chunks are listed, then their
// exp(power) computed in one loop of independent chunks (the exp's dependency chains overlap), then the
// compositing state updated chunk after chunk.
constexpr int BATCH = 16;
// Most chunks of one entry in a tile: every row, each at most ceil(tile / LANES) chunks.
inline int max_chunks(int tile) { return tile * ((tile + LANES - 1) / LANES); }

// floor(v) clamped to [lo, hi] lane by lane (NaN -> lo)
inline D4 floor_clamp(const D4& v, int64_t lo, int64_t hi) {
  const D4 l = bc(double(lo)), h = bc(double(hi));
  return (v >= l) == 0 ? l : (v > h ? h : vfloor(v));
}

// tau of the alpha cutoff for opacity o: o exp(-q / 2) >= 1/255 <=> q = A dx^2 + 2 B dx dy + C dy^2 <= 2 ln(255 o),
// enlarged to tau (1 + 1e-3) + 1e-3 so float rounding never drops a contributing pixel; negative (no pixel reaches
// 1/255) when o < 1/255.
inline double alpha_tau(double o) {
  const double tau = 2.0 * std::log(std::max(255.0 * o, 1e-30));
  return tau * (1.0 + 1e-3) + 1e-3;
}

// Candidate columns [xa, xb] (global) of the pixel rows [ry0, ry1] of the Gaussian sp: pixels whose centre may
// lie in its footprint box (columns [bx0, bx1], one pixel of margin) and may have alpha >= 1/255, the ellipse
// q <= tau solved for dx: x = c +- h, c = gx - (B / A) dy - 0.5, h^2 = k2 dy^2 + k0 = ((B^2 - A C) dy^2 + A tau) / A^2.
// A row is a candidate only if a column lies within the tight bound: h^2 plus the float rounding of the per-pixel
// power (2^-20 of its terms' magnitudes over A, dx^2 + 2 |B / A dx dy| + (C / A) dy^2, bounded at |dy| <= r + 1,
// |dx| <= (|B / A| + sqrt(k2)) |dy| + sqrt(k0) by (7 (B / A)^2 + 6 k2 + C / A) (r + 1)^2 + 6 k0), h plus 1e-3 px
// (rounding of dx). xb is the tight bound; xa is floor(c - h) - 1, where a row's chunks started before the tight
// bound, so every pixel keeps its lane and the gradients' float32 sums stay the same bytes (the rows and tiles the
// tight bound drops held no composited pixel: they added zeros). The exact test is per pixel. Rows the per-pixel
// test rejects (float |dy| > r) or without a candidate column get an empty range.
template <typename S>
inline void row_columns(const Splat<S>& sp, int ry0, int ry1, double tau, int64_t bx0, int64_t bx1, int32_t* out) {
  const double A = sp.A, B = sp.B, C = sp.C, gx = sp.gx;
  const bool ellipse = A > 0.0;
  const double kb = ellipse ? B / A : 0.0, k2 = ellipse ? (B * B - A * C) / (A * A) : 0.0;
  const double k0 = ellipse ? tau / A : 0.0, dmax = double(sp.r) + 1.0, kc = ellipse ? C / A : 0.0;
  const double slack = 0x1p-20 * ((7.0 * kb * kb + 6.0 * std::max(k2, 0.0) + kc) * dmax * dmax + 6.0 * k0);
  for (int y = ry0; y <= ry1; y += GL, out += 2 * GL) {  // GL rows at a time, branch-free
    D4 d;  // dy in S, as the per-pixel test computes it
    for (int l = 0; l < GL; ++l) d[l] = double(S(y + l) + S(0.5) - sp.gy);
    auto keep = (vmax(d, -d) > double(sp.r)) == 0;
    D4 xa = bc(double(bx0)), xb = bc(double(bx1));
    if (ellipse) {
      const D4 h2 = k2 * d * d + k0, c = gx - kb * d - 0.5;
      const D4 ht = vsqrt(h2 + slack) + 1e-3;  // NaN where h2 + slack < 0: an empty tight range
      xb = vmin(xb, floor_clamp(c + ht, bx0 - 2, bx1 + 2));
      keep &= (vmax(xa, -floor_clamp(ht - c, -bx1 - 2, -bx0 + 2)) > xb) == 0;  // ceil(c - ht) <= xb
      xa = vmax(xa, floor_clamp(c - vsqrt(h2), bx0 - 2, bx1 + 2) - 1.0);
    }
    keep &= (xa > xb) == 0;
    const D4 oa = keep ? xa : bc(1.0), ob = keep ? xb : bc(0.0);  // selects: empty rows are frequent
    for (int l = 0; l < GL && y + l <= ry1; ++l) {
      out[2 * l] = int32_t(oa[l]);
      out[2 * l + 1] = int32_t(ob[l]);
    }
  }
}

// Prefetches tile-list entry `far` and the candidate rows of entry `near` (fetched as `far` earlier): the
// per-entry pixel loops are short and would otherwise wait for both (the rows are a gather, and the backward
// walks the entries in reverse, which the hardware prefetchers did not follow).
template <typename S>
inline void prefetch_entries(const Workspace<S>& w, int64_t far, int64_t near) {
  __builtin_prefetch(&w.ent[far]);
  __builtin_prefetch(w.xr.data() + 2 * w.ent[near].rows);
}

// Calls chunk(dy, c, k) for every LANES-pixel chunk of entry e's candidate columns (its per-row spans) inside the
// tile at (x0, y0) of width tw, row stride `stride`: dy is the row's offset from the mean, c the chunk's first
// column in the tile, k its index in the tile buffers. The forward and the backward walk the same chunks.
template <typename S, typename F>
inline void for_each_chunk(const Workspace<S>& w, const Entry<S>& e, int x0, int y0, int tw, int stride, F&& chunk) {
  const int32_t* xr = w.xr.data() + 2 * e.rows;
  for (int y = e.ya; y <= e.yb; ++y, xr += 2) {
    const int ca = std::max(xr[0], x0) - x0, cb = std::min(xr[1], x0 + tw - 1) - x0;
    if (ca > cb) continue;
    const S dy = S(y) + S(0.5) - e.s.gy;
    for (int c = ca; c <= cb; c += LANES) chunk(dy, c, (y - y0) * stride + c);
  }
}

// One chunk of a batch of entries in the backward: G, its pixels' exp(power) where the pixel is inside the box
// and alpha >= 1/255, else 0 (the part of the pixel arithmetic that does not depend on the compositing state;
// backward_chunk overwrites it with the weights a T); c, the chunk's first column in the tile; k, its index in the
// tile buffers; dy, the row's offset from the mean.
template <typename S>
struct alignas(32) Chunk {
  S G[LANES];
  int32_t c, k;
  S dy;
};

// Chunk::G of one chunk (px: the pixel centres x of its columns).
template <typename S>
inline void chunk_G(const Splat<S>& s, S dy, const S* px, S* out) {
#pragma omp simd
  for (int l = 0; l < LANES; ++l) {
    const S dx = px[l] - s.gx;
    const S power = S(-0.5) * (s.A * dx * dx + s.C * dy * dy) - s.B * dx * dy;
    const S G = exp_neg(power);
    out[l] = ((std::fabs(dx) <= s.r) & (s.o * G >= S(1.0 / 255.0))) ? G : S(0);
  }
}

// Forward of one chunk of LANES pixels of a row (offset dy from the mean; px: pixel centre x; the other pointers
// at the chunk's first pixel): alpha, the exact footprint test, front-to-back compositing, early stop.
template <typename S>
inline void composite_chunk(const Splat<S>& s, S dy, const S* px, S* T, S* p0, S* p1, S* p2, S* pz, int32_t* lp,
                            int32_t* dp, int32_t rank) {
#pragma omp simd
  for (int l = 0; l < LANES; ++l) {
    const S dx = px[l] - s.gx;
    const S power = S(-0.5) * (s.A * dx * dx + s.C * dy * dy) - s.B * dx * dy;
    const S oG = s.o * exp_neg(power);
    const S a = oG < S(0.99) ? oG : S(0.99);
    const bool ok = (dp[l] == 0) & (std::fabs(dx) <= s.r) & (oG >= S(1.0 / 255.0));  // = a >= 1/255
    const S nT = T[l] * (S(1) - a);
    const bool stop = ok & (nT < S(1e-4));
    const bool use = ok & !stop;
    const S wgt = use ? a * T[l] : S(0);
    p0[l] += wgt * s.col0;
    p1[l] += wgt * s.col1;
    p2[l] += wgt * s.col2;
    pz[l] += wgt * s.depth;
    T[l] = use ? nT : T[l];
    lp[l] = use ? rank : lp[l];
    dp[l] = stop ? 1 : dp[l];
  }
}

constexpr int NG = 10;  // screen gradient per entry: mean2d x, y; conic a, b, c; colour r, g, b; opacity; depth

// Per-lane sums (NG x LANES) of one entry, added up in a fixed order at its end (generic: lane order). With
// gp = dL/dpower, sums 0-4 are gp dx, gp dy, gp dx^2, gp dx dy, gp dy^2 (the mean and conic gradients follow from
// them and the entry's conic in `reduce`, which saves per-pixel work), 5-9 the colour, opacity and depth gradients.
template <typename S>
struct LaneSums {
  S v[NG * LANES];
  void zero() { std::fill(v, v + NG * LANES, S(0)); }
  void lane_sums(S* t) const {
    for (int q = 0; q < NG; ++q) {
      S sum = S(0);
      for (int l = 0; l < LANES; ++l) sum += v[q * LANES + l];
      t[q] = sum;
    }
  }
};

// The entry's screen-space gradient (NG) from its lane sums.
template <typename S>
inline void reduce(const LaneSums<S>& sums, const Splat<S>& s, S* out) {
  S t[NG];
  sums.lane_sums(t);
  out[0] = s.A * t[0] + s.B * t[1];  // dpower/dmean = (A dx + B dy, B dx + C dy)
  out[1] = s.B * t[0] + s.C * t[1];
  out[2] = S(-0.5) * t[2];
  out[3] = -t[3];
  out[4] = S(-0.5) * t[4];
  for (int q = 5; q < NG; ++q) out[q] = t[q];
}

// Backward of one chunk (Gc: its Chunk::G), back to front: restores the transmittance in front of the Gaussian
// (T, one division), the colour and depth composited behind it (q0..qz: q + a (c - q) on the lanes it was
// composited on, where a = 0 elsewhere leaves q unchanged), and adds its screen-space gradient to the per-lane
// sums, but for the colour and depth sums: it leaves the weights a T in Gc for colour_sums (fewer live sums,
// which spilled to the stack).
template <typename S>
inline void backward_chunk(const Splat<S>& s, S dy, const S* px, S* Gc, int32_t jj, const int32_t* lp, S* T,
                           S* q0, S* q1, S* q2, S* qz, const S* Tf, const S* gT, const S* gc0, const S* gc1,
                           const S* gc2, const S* gd, LaneSums<S>& sums) {
  S* acc = sums.v;
#pragma omp simd
  for (int l = 0; l < LANES; ++l) {
    const S dx = px[l] - s.gx;
    const S G = Gc[l];
    const S oG = s.o * G;
    const S a = oG < S(0.99) ? oG : S(0.99);
    const bool ok = (jj < lp[l]) & (G > S(0));
    const S inv = ok ? S(1) / (S(1) - a) : S(1);
    const S Tc = T[l] * inv;  // transmittance in front of this Gaussian
    const S am = ok ? a : S(0);
    const S wgt = am * Tc;
    const S d0 = s.col0 - q0[l], d1 = s.col1 - q1[l], d2 = s.col2 - q2[l], dz = s.depth - qz[l];
    const S g_a = Tc * (d0 * gc0[l] + d1 * gc1[l] + d2 * gc2[l] + dz * gd[l]) - Tf[l] * inv * gT[l];
    q0[l] += am * d0;
    q1[l] += am * d1;
    q2[l] += am * d2;
    qz[l] += am * dz;
    T[l] = Tc;
    const S ga = (ok & (oG <= S(0.99))) ? g_a : S(0);  // clamped alpha: no gradient to o or G
    acc[8 * LANES + l] += ga * G;
    Gc[l] = wgt;
    const S gp = ga * a;  // dL/dpower
    acc[0 * LANES + l] += gp * dx;
    acc[1 * LANES + l] += gp * dy;
    acc[2 * LANES + l] += gp * dx * dx;
    acc[3 * LANES + l] += gp * dx * dy;
    acc[4 * LANES + l] += gp * dy * dy;
  }
}

// Adds the colour and depth sums (5-7, 9) of one chunk: its weights a T (wgt, left by backward_chunk) times the
// pixels' colour and depth gradients.
template <typename S>
inline void colour_sums(const S* wgt, const S* gc0, const S* gc1, const S* gc2, const S* gd, LaneSums<S>& sums) {
  S* acc = sums.v;
#pragma omp simd
  for (int l = 0; l < LANES; ++l) {
    acc[5 * LANES + l] += wgt[l] * gc0[l];
    acc[6 * LANES + l] += wgt[l] * gc1[l];
    acc[7 * LANES + l] += wgt[l] * gc2[l];
    acc[9 * LANES + l] += wgt[l] * gd[l];
  }
}

#if defined(__AVX2__) && defined(__FMA__)
// float32 chunks in AVX2 intrinsics: the same arithmetic as the generic loops, written out because GCC turns
// the loops' conditional updates into masked stores (vmaskmovps), which are microcoded and slow on AMD cores;
// here every lane is blended in registers and stored whole.
inline __m256 exp_neg8(__m256 x) {
  x = _mm256_min_ps(_mm256_max_ps(x, _mm256_set1_ps(-30.0f)), _mm256_setzero_ps());
  const __m256 n = _mm256_floor_ps(_mm256_fmadd_ps(x, _mm256_set1_ps(1.44269504088896341f), _mm256_set1_ps(0.5f)));
  __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693359375f), x);
  r = _mm256_fmadd_ps(n, _mm256_set1_ps(2.12194440e-4f), r);
  __m256 p = _mm256_set1_ps(1.9875691500e-4f);
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.3981999507e-3f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(8.3334519073e-3f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(4.1665795894e-2f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.6666665459e-1f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(5.0000001201e-1f));
  p = _mm256_add_ps(_mm256_fmadd_ps(p, _mm256_mul_ps(r, r), r), _mm256_set1_ps(1.0f));
  const __m256i bits = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(p, _mm256_castsi256_ps(bits));
}

// alpha inputs of a chunk: dx, exp(power) and o exp(power)
inline void chunk_alpha(const Splat<float>& s, float dy, const float* px, __m256& dx, __m256& G, __m256& oG) {
  dx = _mm256_sub_ps(_mm256_loadu_ps(px), _mm256_set1_ps(s.gx));
  const __m256 q = _mm256_fmadd_ps(_mm256_mul_ps(_mm256_set1_ps(s.A), dx), dx, _mm256_set1_ps(s.C * dy * dy));
  const __m256 power = _mm256_fmsub_ps(_mm256_set1_ps(-0.5f), q, _mm256_mul_ps(_mm256_set1_ps(s.B * dy), dx));
  G = exp_neg8(power);
  oG = _mm256_mul_ps(_mm256_set1_ps(s.o), G);
}

inline __m256 in_box(const Splat<float>& s, __m256 dx) {
  const __m256 adx = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), dx);
  return _mm256_cmp_ps(adx, _mm256_set1_ps(s.r), _CMP_LE_OQ);
}

template <>
inline void chunk_G<float>(const Splat<float>& s, float dy, const float* px, float* out) {
  __m256 dx, G, oG;
  chunk_alpha(s, dy, px, dx, G, oG);
  const __m256 ok = _mm256_and_ps(in_box(s, dx), _mm256_cmp_ps(oG, _mm256_set1_ps(1.0f / 255.0f), _CMP_GE_OQ));
  _mm256_store_ps(out, _mm256_and_ps(ok, G));
}

template <>
inline void composite_chunk<float>(const Splat<float>& s, float dy, const float* px, float* T, float* p0, float* p1,
                                   float* p2, float* pz, int32_t* lp, int32_t* dp, int32_t rank) {
  const __m256i done = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(dp));
  const __m256 live = _mm256_castsi256_ps(_mm256_cmpeq_epi32(done, _mm256_setzero_si256()));
  if (_mm256_testz_ps(live, live)) return;  // every pixel has stopped: nothing changes
  __m256 dx, G, oG;
  chunk_alpha(s, dy, px, dx, G, oG);
  const __m256 a = _mm256_min_ps(oG, _mm256_set1_ps(0.99f));
  const __m256 ok = _mm256_and_ps(_mm256_and_ps(live, in_box(s, dx)),
                                  _mm256_cmp_ps(oG, _mm256_set1_ps(1.0f / 255.0f), _CMP_GE_OQ));
  const __m256 t = _mm256_loadu_ps(T);
  const __m256 nT = _mm256_mul_ps(t, _mm256_sub_ps(_mm256_set1_ps(1.0f), a));
  const __m256 stop = _mm256_and_ps(ok, _mm256_cmp_ps(nT, _mm256_set1_ps(1e-4f), _CMP_LT_OQ));
  const __m256 use = _mm256_andnot_ps(stop, ok);
  const __m256 wgt = _mm256_and_ps(use, _mm256_mul_ps(a, t));
  _mm256_storeu_ps(p0, _mm256_fmadd_ps(wgt, _mm256_set1_ps(s.col0), _mm256_loadu_ps(p0)));
  _mm256_storeu_ps(p1, _mm256_fmadd_ps(wgt, _mm256_set1_ps(s.col1), _mm256_loadu_ps(p1)));
  _mm256_storeu_ps(p2, _mm256_fmadd_ps(wgt, _mm256_set1_ps(s.col2), _mm256_loadu_ps(p2)));
  _mm256_storeu_ps(pz, _mm256_fmadd_ps(wgt, _mm256_set1_ps(s.depth), _mm256_loadu_ps(pz)));
  _mm256_storeu_ps(T, _mm256_blendv_ps(t, nT, use));
  const __m256i lv = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(lp));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(lp),
                      _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(lv),
                                                           _mm256_castsi256_ps(_mm256_set1_epi32(rank)), use)));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(dp),
                      _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(done),
                                                           _mm256_castsi256_ps(_mm256_set1_epi32(1)), stop)));
}

// One vector per sum, added to by FMA; at the entry's end the lanes are summed by a fixed pairwise tree.
template <>
struct LaneSums<float> {
  __m256 v[NG];
  void zero() {
    for (__m256& x : v) x = _mm256_setzero_ps();
  }
  // horizontal adds, eight sums at a time
  void lane_sums(float* t) const {
    const __m256 z = _mm256_setzero_ps();
    _mm256_storeu_ps(t, sum8(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]));
    alignas(32) float rest[LANES];
    _mm256_store_ps(rest, sum8(v[8], v[9], z, z, z, z, z, z));
    t[8] = rest[0];
    t[9] = rest[1];
  }
  static __m256 sum8(__m256 a, __m256 b, __m256 c, __m256 d, __m256 e, __m256 f, __m256 g, __m256 h) {
    const __m256 abcd = _mm256_hadd_ps(_mm256_hadd_ps(a, b), _mm256_hadd_ps(c, d));  // per 128-bit half
    const __m256 efgh = _mm256_hadd_ps(_mm256_hadd_ps(e, f), _mm256_hadd_ps(g, h));
    return _mm256_add_ps(_mm256_permute2f128_ps(abcd, efgh, 0x20), _mm256_permute2f128_ps(abcd, efgh, 0x31));
  }
};

template <>
inline void backward_chunk<float>(const Splat<float>& s, float dy, const float* px, float* Gc, int32_t jj,
                                  const int32_t* lp, float* T, float* q0, float* q1, float* q2, float* qz,
                                  const float* Tf, const float* gT, const float* gc0, const float* gc1,
                                  const float* gc2, const float* gd, LaneSums<float>& sums) {
  const __m256 G = _mm256_load_ps(Gc), oG = _mm256_mul_ps(_mm256_set1_ps(s.o), G);
  const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(px), _mm256_set1_ps(s.gx));
  const __m256 a = _mm256_min_ps(oG, _mm256_set1_ps(0.99f));
  const __m256i lv = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(lp));
  const __m256 behind = _mm256_castsi256_ps(_mm256_cmpgt_epi32(lv, _mm256_set1_epi32(jj)));
  const __m256 ok = _mm256_and_ps(behind, _mm256_cmp_ps(G, _mm256_setzero_ps(), _CMP_GT_OQ));
  if (_mm256_testz_ps(ok, ok)) {  // no lane composited this Gaussian: nothing changes
    _mm256_store_ps(Gc, _mm256_setzero_ps());
    return;
  }
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 inv = _mm256_blendv_ps(one, _mm256_div_ps(one, _mm256_sub_ps(one, a)), ok);
  const __m256 Tc = _mm256_mul_ps(_mm256_loadu_ps(T), inv);
  const __m256 am = _mm256_and_ps(ok, a);
  const __m256 wgt = _mm256_mul_ps(am, Tc);
  const __m256 g0 = _mm256_loadu_ps(gc0), g1 = _mm256_loadu_ps(gc1), g2 = _mm256_loadu_ps(gc2),
               gz = _mm256_loadu_ps(gd);
  auto add = [&](int q, __m256 x, __m256 y) { sums.v[q] = _mm256_fmadd_ps(x, y, sums.v[q]); };
  _mm256_store_ps(Gc, wgt);
  const __m256 r0 = _mm256_loadu_ps(q0), r1 = _mm256_loadu_ps(q1), r2 = _mm256_loadu_ps(q2), rz = _mm256_loadu_ps(qz);
  const __m256 d0 = _mm256_sub_ps(_mm256_set1_ps(s.col0), r0), d1 = _mm256_sub_ps(_mm256_set1_ps(s.col1), r1),
               d2 = _mm256_sub_ps(_mm256_set1_ps(s.col2), r2), dz = _mm256_sub_ps(_mm256_set1_ps(s.depth), rz);
  __m256 dot = _mm256_mul_ps(d0, g0);
  dot = _mm256_fmadd_ps(d1, g1, dot);
  dot = _mm256_fmadd_ps(d2, g2, dot);
  dot = _mm256_fmadd_ps(dz, gz, dot);
  const __m256 g_a = _mm256_fmsub_ps(Tc, dot, _mm256_mul_ps(_mm256_mul_ps(_mm256_loadu_ps(Tf), inv),
                                                            _mm256_loadu_ps(gT)));
  _mm256_storeu_ps(q0, _mm256_fmadd_ps(am, d0, r0));
  _mm256_storeu_ps(q1, _mm256_fmadd_ps(am, d1, r1));
  _mm256_storeu_ps(q2, _mm256_fmadd_ps(am, d2, r2));
  _mm256_storeu_ps(qz, _mm256_fmadd_ps(am, dz, rz));
  _mm256_storeu_ps(T, Tc);
  const __m256 ga = _mm256_and_ps(_mm256_and_ps(ok, _mm256_cmp_ps(oG, _mm256_set1_ps(0.99f), _CMP_LE_OQ)), g_a);
  add(8, ga, G);
  const __m256 gp = _mm256_mul_ps(ga, a);
  const __m256 vdy = _mm256_set1_ps(dy), gpdx = _mm256_mul_ps(gp, dx), gpdy = _mm256_mul_ps(gp, vdy);
  sums.v[0] = _mm256_add_ps(sums.v[0], gpdx);
  sums.v[1] = _mm256_add_ps(sums.v[1], gpdy);
  add(2, gpdx, dx);
  add(3, gpdx, vdy);
  add(4, gpdy, vdy);
}
template <>
inline void colour_sums<float>(const float* wgt, const float* gc0, const float* gc1, const float* gc2, const float* gd,
                               LaneSums<float>& sums) {
  const __m256 w = _mm256_load_ps(wgt);
  sums.v[5] = _mm256_fmadd_ps(w, _mm256_loadu_ps(gc0), sums.v[5]);
  sums.v[6] = _mm256_fmadd_ps(w, _mm256_loadu_ps(gc1), sums.v[6]);
  sums.v[7] = _mm256_fmadd_ps(w, _mm256_loadu_ps(gc2), sums.v[7]);
  sums.v[9] = _mm256_fmadd_ps(w, _mm256_loadu_ps(gd), sums.v[9]);
}
#endif

// Threads worth starting for a render of H x W pixels and n Gaussians: one per 1024 pixels or 4096 Gaussians,
// at most `threads`. A tiny render (the tiny demo's 33 x 34 px garment crop, 2000 Gaussians) takes under a
// millisecond on one thread, and when another process holds the other cores each parallel region waits a time
// slice for its partner (measured beside a busy process: 0.9 ms on one thread, 20-30 ms on two). The result is
// the same bytes on any thread count.
inline int threads_worth(int threads, int64_t pixels, int64_t n) {
  const int64_t useful = std::max<int64_t>(1, std::max(pixels / 1024, n / 4096));
  return int(std::max<int64_t>(1, std::min<int64_t>(threads, useful)));
}

template <typename S>
Workspace<S>* forward(const Inputs<S>& in, const CameraParams& cam, int H, int W, int tile, const S* bg,
                      S* out_color, S* out_alpha, S* out_dsum, int threads) {
  threads = threads_worth(threads, int64_t(H) * W, in.n);
  auto* ws = new Workspace<S>();
  ws->H = H;
  ws->W = W;
  ws->tile = tile;
  ws->tiles_x = (W + tile - 1) / tile;
  ws->tiles_y = (H + tile - 1) / tile;
  const int64_t n = in.n;
  // 1. projection and SH per Gaussian; culling (behind the near plane, box outside the image, opacity < 1/255)
  Buffer<Splat<S>> proj(n);  // index order
  Buffer<int32_t> box(4 * n);
  std::vector<char> visible(n);
  std::vector<double> tau(n);  // alpha_tau of the opacity
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int64_t i0 = 0; i0 < n; i0 += GL) {
    const int64_t id[GL] = {i0, std::min(i0 + 1, n - 1), std::min(i0 + 2, n - 1), std::min(i0 + 3, n - 1)};
    Proj p;
    project(in, cam, id, p);
    for (int l = 0; l < GL && i0 + l < n; ++l) {
      const int64_t i = i0 + l;
      Splat<S>& s = proj[i];
      s.gx = S(p.u[l]);
      s.gy = S(p.v[l]);
      s.r = S(p.r[l]);
      s.A = S(p.conic[0][l]);
      s.B = S(p.conic[1][l]);
      s.C = S(p.conic[2][l]);
      s.o = S(double(in.opac[i]) * p.coverage[l]);
      s.col0 = S(std::max(p.raw[0][l], 0.0));
      s.col1 = S(std::max(p.raw[1][l], 0.0));
      s.col2 = S(std::max(p.raw[2][l], 0.0));
      s.depth = S(p.pc[2][l]);
      // pixel index ranges whose centres lie in the footprint box: x + 0.5 in [u - r, u + r]
      const double r = double(s.r), u = double(s.gx), v = double(s.gy);
      const double x0 = std::ceil(u - r - 0.5), x1 = std::floor(u + r - 0.5);
      const double y0 = std::ceil(v - r - 0.5), y1 = std::floor(v + r - 0.5);
      tau[i] = alpha_tau(double(s.o));
      visible[i] = r > 0 && x0 <= x1 && y0 <= y1 && x0 <= W - 1 && x1 >= 0 && y0 <= H - 1 && y1 >= 0 && tau[i] >= 0.0;
      if (visible[i]) {
        box[4 * i] = int32_t(std::max(x0, 0.0));
        box[4 * i + 1] = int32_t(std::min(x1, double(W - 1)));
        box[4 * i + 2] = int32_t(std::max(y0, 0.0));
        box[4 * i + 3] = int32_t(std::min(y1, double(H - 1)));
      }
    }
  }
  // 2. depth order (stable: ties by index), per-rank copies (SoA, rank order)
  std::vector<int64_t>& order = ws->order;
  std::vector<uint32_t> key(n);
  for (int64_t i = 0; i < n; ++i) {
    if (!visible[i]) continue;
    order.push_back(i);
    const float f = float(proj[i].depth);  // positive (z >= near > 0): its bits order like its value
    std::memcpy(&key[i], &f, sizeof(uint32_t));
  }
  radix_sort(order, key);
  if (sizeof(S) == 8)  // float keys may tie where doubles differ: finish with a stable sort on exact depths
    std::stable_sort(order.begin(), order.end(),
                     [&](int64_t a, int64_t b) { return proj[a].depth < proj[b].depth; });
  const int64_t m = int64_t(order.size());
  const int ntiles = ws->tiles_x * ws->tiles_y;
  ws->rank_of.assign(n, -1);
  for (int64_t r = 0; r < m; ++r) ws->rank_of[order[r]] = r;
  Buffer<Splat<S>> sp(m);
  std::vector<int32_t> rbox(4 * m);  // footprint box per rank
  std::vector<int32_t> ry0(m), ry1(m);  // per rank: candidate pixel rows [ry0, ry1] (global, in the image)
  std::vector<int64_t> roff(m + 1, 0);  // per rank: offset of its rows' column ranges in ws->xr
  std::vector<int64_t> boff(m + 1, 0);  // per rank: its bands of tile rows (tile row, first and last tile column)
  std::vector<double> rtau(m);  // per rank: alpha_tau
  for (int64_t r = 0; r < m; ++r) {  // serial: cheap, and each parallel region costs a barrier on a busy machine
    if (r + 16 < m) {  // the reads by index are a gather: fetch ahead
      const int64_t f = order[r + 16];
      __builtin_prefetch(&proj[f]);
      __builtin_prefetch(reinterpret_cast<const char*>(&proj[f] + 1) - 1);
      __builtin_prefetch(&box[4 * f]);
      __builtin_prefetch(&tau[f]);
    }
    const int64_t i = order[r];
    sp[r] = proj[i];
    rtau[r] = tau[i];
    for (int q = 0; q < 4; ++q) rbox[4 * r + q] = box[4 * i + q];
    // candidate rows: the box rows with one row of margin (the per-row test is in float)
    ry0[r] = std::max(box[4 * i + 2] - 1, 0);
    ry1[r] = std::min(box[4 * i + 3] + 1, H - 1);
    roff[r + 1] = roff[r] + ry1[r] - ry0[r] + 1;
    boff[r + 1] = boff[r] + box[4 * i + 3] / tile - box[4 * i + 2] / tile + 1;
  }
  // 3. candidate columns per row (the alpha ellipse within the box), entries per rank: the tiles that hold a
  // candidate pixel (per band of tile rows, the tiles between the band's leftmost and rightmost candidate)
  ws->xr.resize(2 * roff[m]);
  std::vector<int64_t> entries(m);
  std::vector<int64_t> bpairs(m);
  // per band of tile rows of the footprint box: the first and last tile column holding a candidate pixel inside
  // the box (the tiles of the contract's box that the alpha ellipse reaches; none when first > last)
  std::vector<int32_t> band_tx(2 * boff[m]);
  std::vector<int32_t> rows(2 * m);  // per rank: the first and last of its rows that have candidate columns
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int64_t r = 0; r < m; ++r) {
    const int32_t* b = &rbox[4 * r];
    bpairs[r] = int64_t(b[1] - b[0] + 1) * (b[3] - b[2] + 1);
    int32_t* xr = ws->xr.data() + 2 * roff[r];
    row_columns(sp[r], ry0[r], ry1[r], rtau[r], std::max(b[0] - 1, 0), std::min(b[1] + 1, W - 1), xr);
    int ya = ry0[r], yb = ry1[r];  // rows without candidate columns (empty: xa > xb) off both ends
    while (ya < yb && xr[2 * (ya - ry0[r])] > xr[2 * (ya - ry0[r]) + 1]) ++ya;
    while (yb > ya && xr[2 * (yb - ry0[r])] > xr[2 * (yb - ry0[r]) + 1]) --yb;
    rows[2 * r] = ya;
    rows[2 * r + 1] = yb;
    int32_t* bt = band_tx.data() + 2 * boff[r];
    const int ty0 = b[2] / tile;
    int64_t count = 0;
    for (int ty = ty0; ty <= b[3] / tile; ++ty, bt += 2) {
      int lo = W, hi = -1;
      for (int y = std::max(ty * tile, b[2]); y <= std::min(ty * tile + tile - 1, b[3]); ++y) {
        const int32_t* row = xr + 2 * (y - ry0[r]);
        const int xa = std::max(row[0], b[0]), xb = std::min(row[1], b[1]);
        if (xa <= xb) {
          lo = std::min(lo, xa);
          hi = std::max(hi, xb);
        }
      }
      bt[0] = lo <= hi ? lo / tile : 1;
      bt[1] = lo <= hi ? hi / tile : 0;
      count += bt[1] - bt[0] + 1;
    }
    entries[r] = count;
  }
  auto bands = [&](int64_t r, auto&& visit) {  // visit(ty, tx0, tx1) for every band of rank r with tiles
    const int32_t* bt = band_tx.data() + 2 * boff[r];
    const int ty0 = rbox[4 * r + 2] / tile;
    for (int64_t k = 0; k < boff[r + 1] - boff[r]; ++k, bt += 2)
      if (bt[0] <= bt[1]) visit(ty0 + int(k), bt[0], bt[1]);
  };
  int64_t pairs = 0;
  for (int64_t r = 0; r < m; ++r) pairs += bpairs[r];
  ws->pairs = pairs;
  ws->ioff.assign(n + 1, 0);
  for (int64_t r = 0; r < m; ++r) ws->ioff[order[r] + 1] = entries[r];
  for (int64_t i = 0; i < n; ++i) ws->ioff[i + 1] += ws->ioff[i];
  // 4. tile lists by a counting sort in rank order (ranks increase within a tile); each entry a copy of the
  // Gaussian and its candidate rows in the tile
  ws->offsets.assign(ntiles + 1, 0);
  for (int64_t r = 0; r < m; ++r)
    bands(r, [&](int ty, int tx0, int tx1) {
      for (int tx = tx0; tx <= tx1; ++tx) ++ws->offsets[ty * ws->tiles_x + tx + 1];
    });
  for (int t = 0; t < ntiles; ++t) ws->offsets[t + 1] += ws->offsets[t];
  ws->ent.resize(ws->offsets[ntiles]);
  ws->slot.resize(ws->offsets[ntiles]);
  {
    std::vector<int64_t> cursor(ws->offsets.begin(), ws->offsets.end() - 1);
    for (int64_t r = 0; r < m; ++r) {
      int64_t e = ws->ioff[order[r]];
      bands(r, [&](int ty, int tx0, int tx1) {
        const int ya = std::max(rows[2 * r], ty * tile), yb = std::min(rows[2 * r + 1], ty * tile + tile - 1);
        const Entry<S> entry{sp[r], ya, yb, roff[r] + ya - ry0[r]};
        for (int tx = tx0; tx <= tx1; ++tx) {
          const int64_t pos = cursor[ty * ws->tiles_x + tx]++;
          store_entry(&ws->ent[pos], entry);
          ws->slot[pos] = e++;
        }
      });
    }
#if defined(__AVX__)
    _mm_sfence();  // the non-temporal entry stores, before the threads read them
#endif
  }
  // 5. compositing: per tile, Gaussian after Gaussian, SIMD across 8-pixel chunks of its candidate columns
  ws->Tfinal.resize(size_t(H) * W);
  ws->last.resize(size_t(H) * W);
  const Workspace<S>& w = *ws;
#pragma omp parallel num_threads(threads)
  {
    const int stride = padded(tile), P = stride * tile;
    std::vector<S> T(P), a0(P), a1(P), a2(P), az(P), px(stride);
    std::vector<int32_t> last(P), done(P);
#pragma omp for schedule(dynamic, 1)
    for (int t = 0; t < ntiles; ++t) {
      const int x0 = (t % w.tiles_x) * tile, y0 = (t / w.tiles_x) * tile;
      const int tw = std::min(W, x0 + tile) - x0, th = std::min(H, y0 + tile) - y0;
      for (int k = 0; k < P; ++k) {
        T[k] = S(1);
        a0[k] = a1[k] = a2[k] = az[k] = S(0);
        last[k] = 0;
        done[k] = (k % stride) >= tw || (k / stride) >= th;  // padding pixels never composite
      }
      for (int x = 0; x < stride; ++x) px[x] = S(x0 + x) + S(0.5);
      const int64_t start = w.offsets[t], end = w.offsets[t + 1];
      for (int64_t j = start; j < end; ++j) {
        if (((j - start) & 15) == 15) {  // early out once every pixel of the tile has stopped
          int active = 0;
          for (int k = 0; k < P; ++k) active += done[k] == 0;
          if (active == 0) break;
        }
        if (j + 8 < end) prefetch_entries(w, j + 8, j + 4);
        const Entry<S>& e = w.ent[j];
        const Splat<S> sp = e.s;
        const int32_t rank = int32_t(j + 1 - start);
        for_each_chunk(w, e, x0, y0, tw, stride, [&](S dy, int c, int k) {
          composite_chunk(sp, dy, px.data() + c, T.data() + k, a0.data() + k, a1.data() + k, a2.data() + k,
                          az.data() + k, last.data() + k, done.data() + k, rank);
        });
      }
      for (int y = 0; y < th; ++y) {
        for (int x = 0; x < tw; ++x) {
          const int k = y * stride + x;
          const int64_t pix = int64_t(y0 + y) * W + x0 + x;
          out_color[3 * pix] = a0[k] + T[k] * bg[3 * pix];
          out_color[3 * pix + 1] = a1[k] + T[k] * bg[3 * pix + 1];
          out_color[3 * pix + 2] = a2[k] + T[k] * bg[3 * pix + 2];
          out_alpha[pix] = S(1) - T[k];
          out_dsum[pix] = az[k];
          ws->Tfinal[pix] = T[k];
          ws->last[pix] = last[k];
        }
      }
    }
  }
  return ws;
}

template <typename S>
void backward(const Workspace<S>& w, const Inputs<S>& in, const CameraParams& cam, const S* bg, const S* g_color,
              const S* g_alpha, const S* g_dsum, S* d_means, S* d_rot, S* d_scales, S* d_opac, S* d_sh,
              int threads) {
  threads = threads_worth(threads, int64_t(w.H) * w.W, in.n);
  const int tile = w.tile, W = w.W, H = w.H;
  const int ntiles = w.tiles_x * w.tiles_y;
  std::vector<S> egrad(w.ent.size() * NG);  // per entry slot (index order, then tile order); zero when unused
#pragma omp parallel num_threads(threads)
  {
    const int stride = padded(tile), P = stride * tile;
    std::vector<S> T(P), Tf(P), gTf(P), r0(P), r1(P), r2(P), rz(P), g0(P), g1(P), g2(P), gz(P), px(stride);
    std::vector<int32_t> last(P);
    LaneSums<S> sums;
    std::vector<Chunk<S>> ch(BATCH * max_chunks(tile));
    int bnd[BATCH + 1];  // the chunks of entry jb - q: ch[bnd[q]] .. ch[bnd[q + 1] - 1]
#pragma omp for schedule(dynamic, 1)
    for (int t = 0; t < ntiles; ++t) {
      const int x0 = (t % w.tiles_x) * tile, y0 = (t / w.tiles_x) * tile;
      const int tw = std::min(W, x0 + tile) - x0, th = std::min(H, y0 + tile) - y0;
      int32_t max_last = 0;
      for (int k = 0; k < P; ++k) {
        const int x = k % stride, y = k / stride;
        r0[k] = r1[k] = r2[k] = rz[k] = S(0);
        if (x >= tw || y >= th) {
          T[k] = Tf[k] = S(1);
          gTf[k] = g0[k] = g1[k] = g2[k] = gz[k] = S(0);
          last[k] = 0;
          continue;
        }
        const int64_t pix = int64_t(y0 + y) * W + x0 + x;
        T[k] = Tf[k] = w.Tfinal[pix];
        g0[k] = g_color[3 * pix];
        g1[k] = g_color[3 * pix + 1];
        g2[k] = g_color[3 * pix + 2];
        gz[k] = g_dsum[pix];
        gTf[k] = bg[3 * pix] * g0[k] + bg[3 * pix + 1] * g1[k] + bg[3 * pix + 2] * g2[k] - g_alpha[pix];
        last[k] = w.last[pix];
        max_last = std::max(max_last, last[k]);
      }
      for (int x = 0; x < stride; ++x) px[x] = S(x0 + x) + S(0.5);
      const int64_t start = w.offsets[t];
      const Entry<S>* ent = w.ent.data() + start;
      for (int64_t jb = max_last - 1; jb >= 0; jb -= BATCH) {  // batches of entries, back to front
        const int64_t je = std::max<int64_t>(0, jb - BATCH + 1);
        int n = 0;
        for (int64_t j = jb; j >= je; --j) {
          if (j - 8 >= 0) prefetch_entries(w, start + j - 8, start + j - 4);
          bnd[jb - j] = n;
          for_each_chunk(w, ent[j], x0, y0, tw, stride, [&](S dy, int c, int k) {
            ch[n].c = c;
            ch[n].k = k;
            ch[n++].dy = dy;
          });
        }
        bnd[jb - je + 1] = n;
        for (int64_t j = jb; j >= je; --j)
          for (int i = bnd[jb - j]; i < bnd[jb - j + 1]; ++i)
            chunk_G(ent[j].s, ch[i].dy, px.data() + ch[i].c, ch[i].G);
        for (int64_t j = jb; j >= je; --j) {
          const Splat<S> sp = ent[j].s;
          sums.zero();
          for (int i = bnd[jb - j]; i < bnd[jb - j + 1]; ++i) {
            const int c = ch[i].c, k = ch[i].k;
            backward_chunk(sp, ch[i].dy, px.data() + c, ch[i].G, int32_t(j), last.data() + k, T.data() + k,
                           r0.data() + k, r1.data() + k, r2.data() + k, rz.data() + k, Tf.data() + k,
                           gTf.data() + k, g0.data() + k, g1.data() + k, g2.data() + k, gz.data() + k, sums);
          }
          for (int i = bnd[jb - j]; i < bnd[jb - j + 1]; ++i) {
            const int k = ch[i].k;
            colour_sums(ch[i].G, g0.data() + k, g1.data() + k, g2.data() + k, gz.data() + k, sums);
          }
          reduce(sums, sp, egrad.data() + w.slot[start + j] * NG);
        }
      }
    }
  }
  // per block of GL Gaussians, in index order (sequential reads of their inputs and entry slots): each one's
  // entries summed in tile order (fixed: independent of the thread count), then the projection and SH backward;
  // culled ones get zeros
  const int64_t n = in.n, K3 = int64_t(3) * in.K;
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int64_t i0 = 0; i0 < n; i0 += GL) {
    const int lanes = int(std::min<int64_t>(GL, n - i0));
    const int64_t id[GL] = {i0, std::min(i0 + 1, n - 1), std::min(i0 + 2, n - 1), std::min(i0 + 3, n - 1)};
    std::fill(d_sh + K3 * i0, d_sh + K3 * (i0 + lanes), S(0));
    D4 gs[NG];
    bool any = false;
    for (int q = 0; q < NG; ++q) gs[q] = bc(0.0);
    for (int l = 0; l < lanes; ++l) {
      const int64_t i = i0 + l;
      any |= w.rank_of[i] >= 0;
      for (int64_t e = w.ioff[i]; e < w.ioff[i + 1]; ++e)
        for (int q = 0; q < NG; ++q) gs[q][l] += double(egrad[e * NG + q]);
    }
    if (any) {
      Proj p;
      project(in, cam, id, p);
      project_backward(in, cam, id, lanes, p, gs, d_means, d_rot, d_scales, d_opac, d_sh);
    }
    for (int l = 0; l < lanes; ++l) {
      const int64_t i = i0 + l;
      if (w.rank_of[i] >= 0) continue;
      std::fill(d_means + 3 * i, d_means + 3 * i + 3, S(0));
      std::fill(d_rot + 9 * i, d_rot + 9 * i + 9, S(0));
      std::fill(d_scales + 3 * i, d_scales + 3 * i + 3, S(0));
      std::fill(d_sh + K3 * i, d_sh + K3 * (i + 1), S(0));
      d_opac[i] = S(0);
    }
  }
}

CameraParams camera_params(const double* c) {
  CameraParams cam;
  std::memcpy(cam.R, c, sizeof(cam.R));
  std::memcpy(cam.t, c + 9, sizeof(cam.t));
  cam.fx = c[12];
  cam.skew = c[13];
  cam.cx = c[14];
  cam.fy = c[15];
  cam.cy = c[16];
  std::memcpy(cam.centre, c + 17, sizeof(cam.centre));
  cam.near = c[20];
  return cam;
}

}  // namespace

// camera: 21 doubles = R (9, row-major), t (3), K00, K01, K02, K11, K12, centre (3), near.
// stats (3): visible Gaussians, tile entries, pixel-Gaussian pairs inside footprint boxes.
#define PGC_FUSED_EXPORT(S, suffix)                                                                          \
  extern "C" void* pgc_fused_forward_##suffix(                                                               \
      const S* means, const S* rot, const S* scales, const S* opac, const S* sh, int64_t n, int K, int count, \
      const double* camera, int H, int W, int tile, const S* bg, S* color, S* alpha, S* dsum, int64_t* stats, \
      int threads) {                                                                                         \
    const Inputs<S> in{means, rot, scales, opac, sh, n, K, count};                                           \
    Workspace<S>* ws = forward(in, camera_params(camera), H, W, tile, bg, color, alpha, dsum, threads);      \
    stats[0] = int64_t(ws->order.size());                                                                    \
    stats[1] = int64_t(ws->ent.size());                                                                      \
    stats[2] = ws->pairs;                                                                                    \
    return ws;                                                                                               \
  }                                                                                                          \
  extern "C" void pgc_fused_backward_##suffix(                                                               \
      const void* ws, const S* means, const S* rot, const S* scales, const S* opac, const S* sh, int64_t n,  \
      int K, int count, const double* camera, const S* bg, const S* g_color, const S* g_alpha,               \
      const S* g_dsum, S* d_means, S* d_rot, S* d_scales, S* d_opac, S* d_sh, int threads) {                 \
    const Inputs<S> in{means, rot, scales, opac, sh, n, K, count};                                           \
    backward(*static_cast<const Workspace<S>*>(ws), in, camera_params(camera), bg, g_color, g_alpha, g_dsum, \
             d_means, d_rot, d_scales, d_opac, d_sh, threads);                                               \
  }                                                                                                          \
  extern "C" void pgc_fused_free_##suffix(void* ws) { delete static_cast<Workspace<S>*>(ws); }

PGC_FUSED_EXPORT(float, f32)
PGC_FUSED_EXPORT(double, f64)

// Machine limits, measured with the kernel's own code generation (same flags): float FMA throughput
// (FLOP/s, an FMA counted as 2) and throughput of the kernel's exp (evaluations/s), on ``threads`` threads.
namespace {
volatile float peak_sink;
}

namespace {
double thread_cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}
}  // namespace

// Rates are summed over threads, each per second of its own CPU time (on a shared machine the wall clock
// counts time other processes hold the core).
extern "C" double pgc_fused_peak_fma(int64_t iters, int threads) {
  double rate = 0.0;
#pragma omp parallel num_threads(threads) reduction(+ : rate)
  {
    const double start = thread_cpu_seconds();
    float acc[128];
    for (int k = 0; k < 128; ++k) acc[k] = float(k) * 1e-3f;
    const float a = 0.9999999f, b = 1e-7f;
    for (int64_t it = 0; it < iters; ++it) {
#pragma omp simd
      for (int k = 0; k < 128; ++k) acc[k] = acc[k] * a + b;
    }
    float s = 0.0f;
    for (int k = 0; k < 128; ++k) s += acc[k];
    peak_sink = s;
    rate += 2.0 * 128.0 * double(iters) / (thread_cpu_seconds() - start);
  }
  return rate;
}

extern "C" double pgc_fused_peak_exp(int64_t iters, int threads) {
  double rate = 0.0;
#pragma omp parallel num_threads(threads) reduction(+ : rate)
  {
    const double start = thread_cpu_seconds();
    float x[256], acc[256];
    for (int k = 0; k < 256; ++k) {
      x[k] = -5.0f * float(k) / 256.0f;
      acc[k] = 0.0f;
    }
    for (int64_t it = 0; it < iters; ++it) {
#pragma omp simd
      for (int k = 0; k < 256; ++k) acc[k] += exp_neg(x[k] - acc[k] * 1e-9f);
    }
    float s = 0.0f;
    for (int k = 0; k < 256; ++k) s += acc[k];
    peak_sink = s;
    rate += 256.0 * double(iters) / (thread_cpu_seconds() - start);
  }
  return rate;
}
