// The fused splat path: projection, SH colour, culling, binning, depth order and compositing of world
// Gaussians in one call, and the backward of all of it (CPU, OpenMP, SIMD across the pixels of a tile row).
// Loaded through ctypes by pgc_torch.splat.fused; arrays are contiguous, row-major.
//
// Contract (pgc/splats/projection.py, pgc/splats/reference.py): scales clamped to [0, 1e4]; x_c = R x + t,
// culled when z < near; Sigma2D = J W Sigma W^T J^T + 0.3 I; r = ceil(3 sqrt(lambda_max)); pixel centres
// (x + 0.5, y + 0.5) inside the box |dx| <= r, |dy| <= r; alpha = min(0.99, o exp(power)), skipped below
// 1/255; a pixel stops before its transmittance would fall below 1e-4; colour = SH + 0.5 clamped at 0.
//
// Per Gaussian (projection, SH, their backward) the arithmetic is float64; per pixel-Gaussian pair it is
// the input type S (float32: 8-wide AVX2 lanes with a polynomial exp accurate to ~2e-7 relative).
// Determinism: every pixel's arithmetic is independent of the thread count; the backward writes one
// gradient row per (tile, Gaussian) entry and sums each Gaussian's rows in tile order, so the gradients are
// the same bytes for any thread count too.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <vector>

#include <omp.h>

namespace {

constexpr double DILATION = 0.3, MAX_SCALE = 1e4;
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

// Projection of one Gaussian (float64), with the intermediates its backward needs.
struct Proj {
  double pc[3], J[6], WR[9], sc[3], Tm[6], a, b, c, det, conic[3], u, v, r, dir[3], inv_norm, raw[3];
  bool valid;
};

inline void sh_basis(const double* d, int count, double* out) {
  const double x = d[0], y = d[1], z = d[2];
  out[0] = SH_C0;
  if (count > 1) {
    out[1] = -SH_C1 * y;
    out[2] = SH_C1 * z;
    out[3] = -SH_C1 * x;
  }
  if (count > 4) {
    const double xx = x * x, yy = y * y, zz = z * z;
    out[4] = SH_C2[0] * x * y;
    out[5] = SH_C2[1] * y * z;
    out[6] = SH_C2[2] * (2 * zz - xx - yy);
    out[7] = SH_C2[3] * x * z;
    out[8] = SH_C2[4] * (xx - yy);
    if (count > 9) {
      out[9] = SH_C3[0] * y * (3 * xx - yy);
      out[10] = SH_C3[1] * x * y * z;
      out[11] = SH_C3[2] * y * (4 * zz - xx - yy);
      out[12] = SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy);
      out[13] = SH_C3[4] * x * (4 * zz - xx - yy);
      out[14] = SH_C3[5] * z * (xx - yy);
      out[15] = SH_C3[6] * x * (xx - 3 * yy);
    }
  }
}

// g (count,) = dL/dbasis -> dL/d(direction) (3,).
inline void sh_basis_backward(const double* d, int count, const double* g, double* gd) {
  const double x = d[0], y = d[1], z = d[2];
  gd[0] = gd[1] = gd[2] = 0.0;
  if (count > 1) {
    gd[1] += -SH_C1 * g[1];
    gd[2] += SH_C1 * g[2];
    gd[0] += -SH_C1 * g[3];
  }
  if (count > 4) {
    const double xx = x * x, yy = y * y, zz = z * z;
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
      gd[1] += SH_C3[0] * (3 * xx - 3 * yy) * g[9];
      gd[0] += SH_C3[1] * y * z * g[10];
      gd[1] += SH_C3[1] * x * z * g[10];
      gd[2] += SH_C3[1] * x * y * g[10];
      gd[0] += -2 * SH_C3[2] * x * y * g[11];
      gd[1] += SH_C3[2] * (4 * zz - xx - 3 * yy) * g[11];
      gd[2] += 8 * SH_C3[2] * y * z * g[11];
      gd[0] += -6 * SH_C3[3] * x * z * g[12];
      gd[1] += -6 * SH_C3[3] * y * z * g[12];
      gd[2] += SH_C3[3] * (6 * zz - 3 * xx - 3 * yy) * g[12];
      gd[0] += SH_C3[4] * (4 * zz - 3 * xx - yy) * g[13];
      gd[1] += -2 * SH_C3[4] * x * y * g[13];
      gd[2] += 8 * SH_C3[4] * x * z * g[13];
      gd[0] += 2 * SH_C3[5] * x * z * g[14];
      gd[1] += -2 * SH_C3[5] * y * z * g[14];
      gd[2] += SH_C3[5] * (xx - yy) * g[14];
      gd[0] += SH_C3[6] * (3 * xx - 3 * yy) * g[15];
      gd[1] += -6 * SH_C3[6] * x * y * g[15];
    }
  }
}

template <typename S>
void project_one(const Inputs<S>& in, const CameraParams& cam, int64_t i, Proj& p) {
  const S* m = in.means + 3 * i;
  const double mw[3] = {double(m[0]), double(m[1]), double(m[2])};
  for (int r = 0; r < 3; ++r)
    p.pc[r] = cam.R[3 * r] * mw[0] + cam.R[3 * r + 1] * mw[1] + cam.R[3 * r + 2] * mw[2] + cam.t[r];
  const double x = p.pc[0], y = p.pc[1], z = p.pc[2];
  p.valid = z >= cam.near;
  const double zs = p.valid ? z : 1.0;
  p.u = (cam.fx * x + cam.skew * y) / zs + cam.cx;
  p.v = cam.fy * y / zs + cam.cy;
  p.J[0] = cam.fx / zs;
  p.J[1] = cam.skew / zs;
  p.J[2] = -(cam.fx * x + cam.skew * y) / (zs * zs);
  p.J[3] = 0.0;
  p.J[4] = cam.fy / zs;
  p.J[5] = -cam.fy * y / (zs * zs);
  const S* Rg = in.rot + 9 * i;
  for (int j = 0; j < 3; ++j) p.sc[j] = std::min(std::max(double(in.scales[3 * i + j]), 0.0), MAX_SCALE);
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
  p.conic[0] = p.c / p.det;
  p.conic[1] = -p.b / p.det;
  p.conic[2] = p.a / p.det;
  const double half = 0.5 * (p.a - p.c);
  const double lam = 0.5 * (p.a + p.c) + std::sqrt(half * half + p.b * p.b);
  p.r = p.valid ? std::ceil(3.0 * std::sqrt(lam)) : 0.0;
  double d[3] = {mw[0] - cam.centre[0], mw[1] - cam.centre[1], mw[2] - cam.centre[2]};
  p.inv_norm = 1.0 / std::sqrt(std::max(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], 1e-60));
  for (int k = 0; k < 3; ++k) p.dir[k] = d[k] * p.inv_norm;
  double basis[16];
  sh_basis(p.dir, in.count, basis);
  const S* sh = in.sh + int64_t(in.K) * 3 * i;
  for (int ch = 0; ch < 3; ++ch) {
    double acc = 0.0;
    for (int k = 0; k < in.count; ++k) acc += basis[k] * double(sh[3 * k + ch]);
    p.raw[ch] = acc + 0.5;
  }
}

// Screen-space gradient of one Gaussian (mean2d x, y; conic a, b, c; colour r, g, b; opacity; depth) ->
// gradients of its world parameters.
template <typename S>
void project_one_backward(const Inputs<S>& in, const CameraParams& cam, int64_t i, const Proj& p, const double* gs,
                          S* d_means, S* d_rot, S* d_scales, S* d_opac, S* d_sh) {
  // conic = inverse(Sigma2D): dL/dSigma = -Q G Q with G the symmetric gradient of Q
  const double Q[4] = {p.conic[0], p.conic[1], p.conic[1], p.conic[2]};
  const double G[4] = {gs[2], 0.5 * gs[3], 0.5 * gs[3], gs[4]};
  double QG[4], dS[4];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) QG[2 * r + c] = Q[2 * r] * G[c] + Q[2 * r + 1] * G[2 + c];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) dS[2 * r + c] = -(QG[2 * r] * Q[c] + QG[2 * r + 1] * Q[2 + c]);
  const double Gc[4] = {dS[0], 0.5 * (dS[1] + dS[2]), 0.5 * (dS[1] + dS[2]), dS[3]};
  double dTm[6];  // 2 Gc Tm
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) dTm[3 * r + c] = 2.0 * (Gc[2 * r] * p.Tm[c] + Gc[2 * r + 1] * p.Tm[3 + c]);
  double M[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M[3 * r + c] = p.WR[3 * r + c] * p.sc[c];
  double dJ[6], dM[9];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      dJ[3 * r + c] = dTm[3 * r] * M[3 * c] + dTm[3 * r + 1] * M[3 * c + 1] + dTm[3 * r + 2] * M[3 * c + 2];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) dM[3 * r + c] = p.J[r] * dTm[c] + p.J[3 + r] * dTm[3 + c];
  S* dr = d_rot + 9 * i;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      dr[3 * r + c] = S((cam.R[r] * dM[c] + cam.R[3 + r] * dM[3 + c] + cam.R[6 + r] * dM[6 + c]) * p.sc[c]);
  for (int c = 0; c < 3; ++c) {
    const double s = double(in.scales[3 * i + c]);
    const double g = p.WR[c] * dM[c] + p.WR[3 + c] * dM[3 + c] + p.WR[6 + c] * dM[6 + c];
    d_scales[3 * i + c] = S((s >= 0.0 && s <= MAX_SCALE) ? g : 0.0);
  }
  // camera-space mean: through J, (u, v) and depth (valid Gaussians only reach here: zs = z)
  const double x = p.pc[0], y = p.pc[1], z = p.pc[2];
  const double iz = 1.0 / z, iz2 = iz * iz, iz3 = iz2 * iz;
  const double fxs = cam.fx * x + cam.skew * y;
  const double gu = gs[0], gv = gs[1];
  double gp[3];
  gp[0] = -cam.fx * iz2 * dJ[2] + gu * cam.fx * iz;
  gp[1] = -cam.skew * iz2 * dJ[2] - cam.fy * iz2 * dJ[5] + gu * cam.skew * iz + gv * cam.fy * iz;
  gp[2] = -cam.fx * iz2 * dJ[0] - cam.skew * iz2 * dJ[1] + 2.0 * fxs * iz3 * dJ[2] - cam.fy * iz2 * dJ[4] +
          2.0 * cam.fy * y * iz3 * dJ[5] - gu * fxs * iz2 - gv * cam.fy * y * iz2 + gs[9];
  // colour: clamp at 0, SH coefficients and the viewing direction
  double graw[3];
  for (int ch = 0; ch < 3; ++ch) graw[ch] = p.raw[ch] >= 0.0 ? gs[5 + ch] : 0.0;
  double basis[16], gbasis[16];
  sh_basis(p.dir, in.count, basis);
  const S* sh = in.sh + int64_t(in.K) * 3 * i;
  S* dsh = d_sh + int64_t(in.K) * 3 * i;
  for (int k = 0; k < in.count; ++k) {
    gbasis[k] = 0.0;
    for (int ch = 0; ch < 3; ++ch) {
      dsh[3 * k + ch] = S(basis[k] * graw[ch]);
      gbasis[k] += double(sh[3 * k + ch]) * graw[ch];
    }
  }
  double gdir[3];
  sh_basis_backward(p.dir, in.count, gbasis, gdir);
  const double n2 = 1.0 / (p.inv_norm * p.inv_norm);
  const double dot = p.dir[0] * gdir[0] + p.dir[1] * gdir[1] + p.dir[2] * gdir[2];
  const bool clamped = n2 <= 1e-60;
  for (int k = 0; k < 3; ++k) {
    const double gm = cam.R[k] * gp[0] + cam.R[3 + k] * gp[1] + cam.R[6 + k] * gp[2];
    const double gd = p.inv_norm * (clamped ? gdir[k] : gdir[k] - p.dir[k] * dot);
    d_means[3 * i + k] = S(gm + gd);
  }
  d_opac[i] = S(gs[8]);
}

// Everything the backward needs from the forward; owned by the Python side through an opaque handle.
template <typename S>
struct Workspace {
  int H = 0, W = 0, tile = 0, tiles_x = 0, tiles_y = 0;
  std::vector<int64_t> order;              // rank -> Gaussian index, increasing depth (ties by index)
  std::vector<S> mx, my, qa, qb, qc, op, c0, c1, c2, dep, rad;  // per rank (SoA)
  std::vector<int64_t> offsets, ids;       // tile lists of ranks (ranks increase within a tile)
  std::vector<int64_t> goff, gent;         // per rank: positions of its entries in ``ids``, tile order
  std::vector<S> Tfinal;                   // (H, W) final transmittance
  std::vector<int32_t> last;               // (H, W) entries composited in the pixel's tile list
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

// Row stride of the per-tile pixel arrays: the tile width rounded up to whole chunks (padding never composites).
inline int padded(int tile) { return (tile + LANES - 1) / LANES * LANES; }

inline int clamp_int(double v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : int(v)); }

// Rows [ya, yb) and chunk-aligned columns [ca, xb) of a tile (tile-local) that may hold pixel centres of the
// footprint box of a Gaussian at (gx, gy) with radius r; one pixel of margin: the exact test is per pixel.
struct Span {
  int ya, yb, ca, xb;
};
template <typename S>
inline Span span(S gx, S gy, S r, int x0, int y0, int tw, int th) {
  const double R = double(r);
  const int xa = clamp_int(std::floor(double(gx) - R - 0.5) - 1 - x0, 0, tw);
  const int xb = clamp_int(std::ceil(double(gx) + R - 0.5) + 2 - x0, 0, tw);
  const int ya = clamp_int(std::floor(double(gy) - R - 0.5) - 1 - y0, 0, th);
  const int yb = clamp_int(std::ceil(double(gy) + R - 0.5) + 2 - y0, 0, th);
  return {ya, yb, xa / LANES * LANES, xb};
}

// Columns [xa, xb) of tile-local row y (pixel centre offset dy from the mean) that may hold pixels with
// alpha >= 1/255: o exp(-q / 2) >= 1/255 <=> q = A dx^2 + 2 B dx dy + C dy^2 <= tau = 2 ln(255 o); solved for dx
// on a slightly enlarged ellipse (tau (1 + 1e-3) + 1e-3) with one pixel of margin, so float rounding never
// drops a contributing pixel (the exact test is per pixel). Returns false when the row has none.
inline bool row_range(double gx, double dy, double A, double B, double C, double tau, int x0, const Span& sp,
                      int& ca, int& xb) {
  if (!(A > 0.0)) {
    ca = sp.ca;
    xb = sp.xb;
    return true;
  }
  const double disc = B * B * dy * dy - A * (C * dy * dy - tau);
  if (disc < 0.0) return false;
  const double root = std::sqrt(disc);
  const int xa = std::max(clamp_int(std::floor(gx + (-B * dy - root) / A - 0.5) - 1 - x0, 0, sp.xb), sp.ca);
  xb = std::min(clamp_int(std::ceil(gx + (-B * dy + root) / A - 0.5) + 2 - x0, 0, sp.xb), sp.xb);
  ca = xa / LANES * LANES;
  return ca < xb;
}

// tau of row_range for opacity o; negative (no pixel reaches 1/255) when o < 1/255.
inline double alpha_tau(double o) {
  const double tau = 2.0 * std::log(std::max(255.0 * o, 1e-30));
  return tau * (1.0 + 1e-3) + 1e-3;
}

template <typename S>
Workspace<S>* forward(const Inputs<S>& in, const CameraParams& cam, int H, int W, int tile, const S* bg,
                      S* out_color, S* out_alpha, S* out_dsum, int threads) {
  auto* ws = new Workspace<S>();
  ws->H = H;
  ws->W = W;
  ws->tile = tile;
  ws->tiles_x = (W + tile - 1) / tile;
  ws->tiles_y = (H + tile - 1) / tile;
  const int64_t n = in.n;
  // 1. projection and SH per Gaussian
  std::vector<S> mx(n), my(n), qa(n), qb(n), qc(n), c0(n), c1(n), c2(n), dep(n), rad(n);
  std::vector<int32_t> box(4 * n);
  std::vector<char> visible(n);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int64_t i = 0; i < n; ++i) {
    Proj p;
    project_one(in, cam, i, p);
    mx[i] = S(p.u);
    my[i] = S(p.v);
    qa[i] = S(p.conic[0]);
    qb[i] = S(p.conic[1]);
    qc[i] = S(p.conic[2]);
    c0[i] = S(std::max(p.raw[0], 0.0));
    c1[i] = S(std::max(p.raw[1], 0.0));
    c2[i] = S(std::max(p.raw[2], 0.0));
    dep[i] = S(p.pc[2]);
    rad[i] = S(p.r);
    // pixel index ranges whose centres lie in the footprint box: x + 0.5 in [u - r, u + r]
    const double r = double(rad[i]), u = double(mx[i]), v = double(my[i]);
    const double x0 = std::ceil(u - r - 0.5), x1 = std::floor(u + r - 0.5);
    const double y0 = std::ceil(v - r - 0.5), y1 = std::floor(v + r - 0.5);
    visible[i] = r > 0 && x0 <= x1 && y0 <= y1 && x0 <= W - 1 && x1 >= 0 && y0 <= H - 1 && y1 >= 0;
    if (visible[i]) {
      box[4 * i] = int32_t(std::max(x0, 0.0));
      box[4 * i + 1] = int32_t(std::min(x1, double(W - 1)));
      box[4 * i + 2] = int32_t(std::max(y0, 0.0));
      box[4 * i + 3] = int32_t(std::min(y1, double(H - 1)));
    }
  }
  // 2. depth order (stable: ties by index) and tile lists
  std::vector<int64_t>& order = ws->order;
  std::vector<uint32_t> key(n);
  for (int64_t i = 0; i < n; ++i) {
    if (!visible[i]) continue;
    order.push_back(i);
    const float f = float(dep[i]);  // positive (z >= near > 0): its bits order like its value
    std::memcpy(&key[i], &f, sizeof(uint32_t));
  }
  radix_sort(order, key);
  if (sizeof(S) == 8)  // float keys may tie where doubles differ: finish with a stable sort on exact depths
    std::stable_sort(order.begin(), order.end(), [&](int64_t a, int64_t b) { return dep[a] < dep[b]; });
  const int64_t m = int64_t(order.size());
  const int ntiles = ws->tiles_x * ws->tiles_y;
  ws->offsets.assign(ntiles + 1, 0);
  ws->goff.assign(m + 1, 0);
  auto gather = [&](std::vector<S>& dst, const std::vector<S>& src) {
    dst.resize(m);
    for (int64_t r = 0; r < m; ++r) dst[r] = src[order[r]];
  };
  gather(ws->mx, mx);
  gather(ws->my, my);
  gather(ws->qa, qa);
  gather(ws->qb, qb);
  gather(ws->qc, qc);
  gather(ws->c0, c0);
  gather(ws->c1, c1);
  gather(ws->c2, c2);
  gather(ws->dep, dep);
  gather(ws->rad, rad);
  ws->op.resize(m);
  for (int64_t r = 0; r < m; ++r) ws->op[r] = in.opac[order[r]];
  int64_t pairs = 0;
  for (int64_t r = 0; r < m; ++r) {
    const int32_t* b = &box[4 * order[r]];
    pairs += int64_t(b[1] - b[0] + 1) * (b[3] - b[2] + 1);
    const int tx0 = b[0] / tile, tx1 = b[1] / tile, ty0 = b[2] / tile, ty1 = b[3] / tile;
    for (int ty = ty0; ty <= ty1; ++ty)
      for (int tx = tx0; tx <= tx1; ++tx) ++ws->offsets[ty * ws->tiles_x + tx + 1];
    ws->goff[r + 1] = ws->goff[r] + int64_t(tx1 - tx0 + 1) * (ty1 - ty0 + 1);
  }
  ws->pairs = pairs;
  for (int t = 0; t < ntiles; ++t) ws->offsets[t + 1] += ws->offsets[t];
  ws->ids.resize(ws->offsets[ntiles]);
  ws->gent.resize(ws->goff[m]);
  {
    std::vector<int64_t> cursor(ws->offsets.begin(), ws->offsets.end() - 1);
    for (int64_t r = 0; r < m; ++r) {
      const int32_t* b = &box[4 * order[r]];
      const int tx0 = b[0] / tile, tx1 = b[1] / tile, ty0 = b[2] / tile, ty1 = b[3] / tile;
      int64_t e = ws->goff[r];
      for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) {
          const int64_t pos = cursor[ty * ws->tiles_x + tx]++;
          ws->ids[pos] = r;
          ws->gent[e++] = pos;
        }
    }
  }
  // 3. compositing: per tile, Gaussian after Gaussian, SIMD across 8-pixel chunks of the rows of its box
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
        const int64_t g = w.ids[j];
        const S gx = w.mx[g], gy = w.my[g], r = w.rad[g], A = w.qa[g], B = w.qb[g], C = w.qc[g], o = w.op[g];
        const S col0 = w.c0[g], col1 = w.c1[g], col2 = w.c2[g], depth = w.dep[g];
        const Span sp = span(gx, gy, r, x0, y0, tw, th);
        const double tau = alpha_tau(double(o));
        if (tau < 0.0) continue;
        const int32_t rank = int32_t(j + 1 - start);
        S* Tp = T.data();
        S *p0 = a0.data(), *p1 = a1.data(), *p2 = a2.data(), *pz = az.data();
        int32_t *lp = last.data(), *dp = done.data();
        for (int y = sp.ya; y < sp.yb; ++y) {
          const S dy = S(y0 + y) + S(0.5) - gy;
          int ca, xb;
          if (std::fabs(dy) > r || !row_range(gx, dy, A, B, C, tau, x0, sp, ca, xb)) continue;
          for (int cb = ca; cb < xb; cb += LANES) {
            const int base = y * stride + cb;
            const S* pxp = px.data() + cb;
#pragma omp simd
            for (int l = 0; l < LANES; ++l) {
              const int k = base + l;
              const S dx = pxp[l] - gx;
              const S power = S(-0.5) * (A * dx * dx + C * dy * dy) - B * dx * dy;
              const S oG = o * exp_neg(power);
              const S a = oG < S(0.99) ? oG : S(0.99);
              const bool ok = (dp[k] == 0) & (std::fabs(dx) <= r) & (oG >= S(1.0 / 255.0));  // = a >= 1/255
              const S nT = Tp[k] * (S(1) - a);
              const bool stop = ok & (nT < S(1e-4));
              const bool use = ok & !stop;
              const S wgt = use ? a * Tp[k] : S(0);
              p0[k] += wgt * col0;
              p1[k] += wgt * col1;
              p2[k] += wgt * col2;
              pz[k] += wgt * depth;
              Tp[k] = use ? nT : Tp[k];
              lp[k] = use ? rank : lp[k];
              dp[k] = stop ? 1 : dp[k];
            }
          }
        }
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

constexpr int NG = 10;  // screen gradient per entry: mean2d x, y; conic a, b, c; colour r, g, b; opacity; depth

template <typename S>
void backward(const Workspace<S>& w, const Inputs<S>& in, const CameraParams& cam, const S* bg, const S* g_color,
              const S* g_alpha, const S* g_dsum, S* d_means, S* d_rot, S* d_scales, S* d_opac, S* d_sh,
              int threads) {
  const int tile = w.tile, W = w.W, H = w.H;
  const int ntiles = w.tiles_x * w.tiles_y;
  std::vector<S> egrad(w.ids.size() * NG);
#pragma omp parallel num_threads(threads)
  {
    const int stride = padded(tile), P = stride * tile;
    std::vector<S> T(P), Tf(P), gTf(P), r0(P), r1(P), r2(P), rz(P), g0(P), g1(P), g2(P), gz(P), px(stride);
    std::vector<int32_t> last(P);
    S acc[NG * LANES];  // per-lane gradient sums of the current entry, added up in lane order at its end
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
      const int64_t start = w.offsets[t], end = w.offsets[t + 1];
      std::fill(egrad.begin() + (start + max_last) * NG, egrad.begin() + end * NG, S(0));
      for (int64_t j = start + max_last - 1; j >= start; --j) {
        const int64_t g = w.ids[j];
        const S gx = w.mx[g], gy = w.my[g], r = w.rad[g], A = w.qa[g], B = w.qb[g], C = w.qc[g], o = w.op[g];
        const S col0 = w.c0[g], col1 = w.c1[g], col2 = w.c2[g], depth = w.dep[g];
        const Span sp = span(gx, gy, r, x0, y0, tw, th);
        const double tau = alpha_tau(double(o));
        const int32_t jj = int32_t(j - start);
        std::fill(acc, acc + NG * LANES, S(0));
        S *Tp = T.data(), *q0 = r0.data(), *q1 = r1.data(), *q2 = r2.data(), *qz = rz.data();
        const S *Tfp = Tf.data(), *gTp = gTf.data(), *gc0 = g0.data(), *gc1 = g1.data(), *gc2 = g2.data();
        const S* gdp = gz.data();
        const int32_t* lp = last.data();
        for (int y = sp.ya; y < sp.yb; ++y) {
          const S dy = S(y0 + y) + S(0.5) - gy;
          int ca, xb;
          if (tau < 0.0 || std::fabs(dy) > r || !row_range(gx, dy, A, B, C, tau, x0, sp, ca, xb)) continue;
          for (int cb = ca; cb < xb; cb += LANES) {
            const int base = y * stride + cb;
            const S* pxp = px.data() + cb;
#pragma omp simd
            for (int l = 0; l < LANES; ++l) {
              const int k = base + l;
              const S dx = pxp[l] - gx;
              const S power = S(-0.5) * (A * dx * dx + C * dy * dy) - B * dx * dy;
              const S G = exp_neg(power);
              const S oG = o * G;
              const S a = oG < S(0.99) ? oG : S(0.99);
              const bool ok = (jj < lp[k]) & (std::fabs(dx) <= r) & (oG >= S(1.0 / 255.0));
              const S one_m = S(1) - a;
              const S Tc = ok ? Tp[k] / one_m : Tp[k];  // transmittance in front of this Gaussian
              const S wgt = ok ? a * Tc : S(0);
              acc[5 * LANES + l] += wgt * gc0[k];
              acc[6 * LANES + l] += wgt * gc1[k];
              acc[7 * LANES + l] += wgt * gc2[k];
              acc[9 * LANES + l] += wgt * gdp[k];
              const S g_a = Tc * ((col0 - q0[k]) * gc0[k] + (col1 - q1[k]) * gc1[k] + (col2 - q2[k]) * gc2[k] +
                                  (depth - qz[k]) * gdp[k]) - Tfp[k] / one_m * gTp[k];
              q0[k] = ok ? a * col0 + one_m * q0[k] : q0[k];
              q1[k] = ok ? a * col1 + one_m * q1[k] : q1[k];
              q2[k] = ok ? a * col2 + one_m * q2[k] : q2[k];
              qz[k] = ok ? a * depth + one_m * qz[k] : qz[k];
              Tp[k] = Tc;
              const S ga = (ok & (oG <= S(0.99))) ? g_a : S(0);  // clamped alpha: no gradient to o or G
              acc[8 * LANES + l] += ga * G;
              const S gp = ga * a;  // dL/dpower
              acc[0 * LANES + l] += gp * (A * dx + B * dy);
              acc[1 * LANES + l] += gp * (B * dx + C * dy);
              acc[2 * LANES + l] += gp * S(-0.5) * dx * dx;
              acc[3 * LANES + l] += gp * (-dx * dy);
              acc[4 * LANES + l] += gp * S(-0.5) * dy * dy;
            }
          }
        }
        S* e = egrad.data() + j * NG;
        for (int q = 0; q < NG; ++q) {
          S sum = S(0);
          for (int l = 0; l < LANES; ++l) sum += acc[q * LANES + l];
          e[q] = sum;
        }
      }
    }
  }
  // reduce each Gaussian's entries in tile order (fixed order: independent of the thread count), then the
  // projection and SH backward
  std::memset(d_means, 0, sizeof(S) * 3 * in.n);
  std::memset(d_rot, 0, sizeof(S) * 9 * in.n);
  std::memset(d_scales, 0, sizeof(S) * 3 * in.n);
  std::memset(d_opac, 0, sizeof(S) * in.n);
  std::memset(d_sh, 0, sizeof(S) * 3 * in.K * in.n);
  const int64_t m = int64_t(w.order.size());
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int64_t r = 0; r < m; ++r) {
    double gs[NG] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int64_t e = w.goff[r]; e < w.goff[r + 1]; ++e) {
      const S* row = egrad.data() + w.gent[e] * NG;
      for (int q = 0; q < NG; ++q) gs[q] += double(row[q]);
    }
    const int64_t i = w.order[r];
    Proj p;
    project_one(in, cam, i, p);
    project_one_backward(in, cam, i, p, gs, d_means, d_rot, d_scales, d_opac, d_sh);
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
    stats[1] = int64_t(ws->ids.size());                                                                      \
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
