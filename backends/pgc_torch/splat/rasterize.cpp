// Tile-based front-to-back Gaussian compositing, forward and backward (CPU, OpenMP).
// Loaded through ctypes by pgc_torch.splat.kernel; every array is contiguous, row-major.
// Gaussians come pre-sorted by depth ("rank" order); tiles list ranks in increasing order.
// Conventions (pgc/splats/projection.py): pixel centre (x + 0.5, y + 0.5); a Gaussian touches a pixel when
// |dx| <= r and |dy| <= r; alpha = min(0.99, o exp(power)), skipped below 1/255; stop before T < 1e-4.
#include <cmath>
#include <cstdint>
#include <algorithm>
#include <cstring>
#include <vector>
#include <omp.h>

namespace {

template <typename S>
struct Params {
  const S* means2d;   // (N, 2)
  const S* conics;    // (N, 3)
  const S* colors;    // (N, 3)
  const S* opac;      // (N,)
  const S* depths;    // (N,)
  const S* radii;     // (N,)
  const int64_t* offsets;  // (tiles + 1,)
  const int64_t* ids;      // (entries,) ranks
  int H, W, tile, tiles_x;
};

// Pixels of the tile [x0, x1) x [y0, y1) whose centres may lie in the footprint box of g (one pixel of margin;
// the exact test is eval_alpha's).
template <typename S>
inline void box_range(const Params<S>& p, int64_t g, int x0, int x1, int y0, int y1, int& xa, int& xb, int& ya,
                      int& yb) {
  const S mx = p.means2d[2 * g], my = p.means2d[2 * g + 1], r = p.radii[g];
  xa = std::max(x0, int(std::fmax(std::floor(mx - r - S(0.5)) - 1, S(x0))));
  xb = std::min(x1, int(std::fmin(std::ceil(mx + r - S(0.5)) + 2, S(x1))));
  ya = std::max(y0, int(std::fmax(std::floor(my - r - S(0.5)) - 1, S(y0))));
  yb = std::min(y1, int(std::fmin(std::ceil(my + r - S(0.5)) + 2, S(y1))));
}

template <typename S>
inline bool eval_alpha(const Params<S>& p, int64_t g, S cx, S cy, S& dx, S& dy, S& G, S& alpha) {
  dx = cx - p.means2d[2 * g];
  dy = cy - p.means2d[2 * g + 1];
  const S r = p.radii[g];
  if (std::fabs(dx) > r || std::fabs(dy) > r) return false;
  const S* q = p.conics + 3 * g;
  const S power = S(-0.5) * (q[0] * dx * dx + q[2] * dy * dy) - q[1] * dx * dy;
  G = std::exp(power);
  alpha = std::fmin(S(0.99), p.opac[g] * G);
  return alpha >= S(1.0 / 255.0);
}

// Gaussian-outer loops: each Gaussian of a tile's depth-ordered list visits only the pixels of its footprint
// box; per-pixel state (transmittance, sums, stop flag) lives in small arrays, so every pixel sees exactly the
// sequence the per-pixel definition prescribes.
template <typename S>
void forward(const Params<S>& p, const S* bg, S* out_color, S* out_alpha, S* out_depth, int32_t* out_last,
             int threads) {
  const int tiles_y = (p.H + p.tile - 1) / p.tile;
  const int ntiles = p.tiles_x * tiles_y;
#pragma omp parallel num_threads(threads)
  {
    const size_t P = size_t(p.tile) * p.tile;
    std::vector<S> T(P), c0(P), c1(P), c2(P), z(P);
    std::vector<int32_t> last(P);
    std::vector<char> done(P);
#pragma omp for schedule(dynamic, 1)
    for (int t = 0; t < ntiles; ++t) {
      const int x0 = (t % p.tiles_x) * p.tile, y0 = (t / p.tiles_x) * p.tile;
      const int x1 = std::min(p.W, x0 + p.tile), y1 = std::min(p.H, y0 + p.tile);
      const int tw = x1 - x0;
      int active = tw * (y1 - y0);
      std::fill(T.begin(), T.end(), S(1));
      std::fill(c0.begin(), c0.end(), S(0));
      std::fill(c1.begin(), c1.end(), S(0));
      std::fill(c2.begin(), c2.end(), S(0));
      std::fill(z.begin(), z.end(), S(0));
      std::fill(last.begin(), last.end(), 0);
      std::fill(done.begin(), done.end(), 0);
      const int64_t start = p.offsets[t], end = p.offsets[t + 1];
      for (int64_t j = start; j < end && active > 0; ++j) {
        const int64_t g = p.ids[j];
        int xa, xb, ya, yb;
        box_range(p, g, x0, x1, y0, y1, xa, xb, ya, yb);
        const S* col = p.colors + 3 * g;
        const S depth = p.depths[g];
        for (int y = ya; y < yb; ++y) {
          for (int x = xa; x < xb; ++x) {
            const int k = (y - y0) * tw + (x - x0);
            if (done[k]) continue;
            S dx, dy, G, a;
            if (!eval_alpha(p, g, S(x) + S(0.5), S(y) + S(0.5), dx, dy, G, a)) continue;
            const S nextT = T[k] * (S(1) - a);
            if (nextT < S(1e-4)) {
              done[k] = 1;
              --active;
              continue;
            }
            const S w = a * T[k];
            c0[k] += w * col[0];
            c1[k] += w * col[1];
            c2[k] += w * col[2];
            z[k] += w * depth;
            T[k] = nextT;
            last[k] = int32_t(j + 1 - start);
          }
        }
      }
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
          const int k = (y - y0) * tw + (x - x0);
          const int64_t pix = int64_t(y) * p.W + x;
          out_color[3 * pix] = c0[k] + T[k] * bg[3 * pix];
          out_color[3 * pix + 1] = c1[k] + T[k] * bg[3 * pix + 1];
          out_color[3 * pix + 2] = c2[k] + T[k] * bg[3 * pix + 2];
          out_alpha[pix] = S(1) - T[k];
          out_depth[pix] = z[k];  // unnormalised: sum of weighted depths
          out_last[pix] = last[k];
        }
      }
    }
  }
}

// Gradient layout per Gaussian (10 values): mean2d x, y; conic a, b, c; colour r, g, b; opacity; depth.
template <typename S>
void backward(const Params<S>& p, int64_t n, const S* bg, const S* out_alpha, const int32_t* out_last,
              const S* g_color, const S* g_alpha, const S* g_depth, S* grad, int threads) {
  const int tiles_y = (p.H + p.tile - 1) / p.tile;
  const int ntiles = p.tiles_x * tiles_y;
  std::vector<std::vector<S>> local(threads);
#pragma omp parallel num_threads(threads)
  {
    const int tid = omp_get_thread_num();
    std::vector<S>& acc = local[tid];
    acc.assign(size_t(n) * 10, S(0));
    const size_t P = size_t(p.tile) * p.tile;
    std::vector<S> T(P), Tf(P), gTf(P), r0(P), r1(P), r2(P), rz(P);
    std::vector<int32_t> last(P);
#pragma omp for schedule(dynamic, 1)
    for (int t = 0; t < ntiles; ++t) {
      const int x0 = (t % p.tiles_x) * p.tile, y0 = (t / p.tiles_x) * p.tile;
      const int x1 = std::min(p.W, x0 + p.tile), y1 = std::min(p.H, y0 + p.tile);
      const int tw = x1 - x0;
      int32_t max_last = 0;
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
          const int k = (y - y0) * tw + (x - x0);
          const int64_t pix = int64_t(y) * p.W + x;
          T[k] = Tf[k] = S(1) - out_alpha[pix];
          const S bg_dot = bg[3 * pix] * g_color[3 * pix] + bg[3 * pix + 1] * g_color[3 * pix + 1] +
                           bg[3 * pix + 2] * g_color[3 * pix + 2];
          gTf[k] = bg_dot - g_alpha[pix];  // dL/dT_final
          r0[k] = r1[k] = r2[k] = rz[k] = S(0);
          last[k] = out_last[pix];
          max_last = std::max(max_last, last[k]);
        }
      }
      const int64_t start = p.offsets[t];
      for (int64_t j = start + max_last - 1; j >= start; --j) {
        const int64_t g = p.ids[j];
        int xa, xb, ya, yb;
        box_range(p, g, x0, x1, y0, y1, xa, xb, ya, yb);
        const S* col = p.colors + 3 * g;
        const S depth = p.depths[g], opac = p.opac[g];
        const S* q = p.conics + 3 * g;
        S gr[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
        for (int y = ya; y < yb; ++y) {
          for (int x = xa; x < xb; ++x) {
            const int k = (y - y0) * tw + (x - x0);
            if (j - start >= last[k]) continue;
            S dx, dy, G, a;
            if (!eval_alpha(p, g, S(x) + S(0.5), S(y) + S(0.5), dx, dy, G, a)) continue;
            const int64_t pix = int64_t(y) * p.W + x;
            const S gc0 = g_color[3 * pix], gc1 = g_color[3 * pix + 1], gc2 = g_color[3 * pix + 2];
            const S gd = g_depth[pix];
            const S one_m = S(1) - a;
            T[k] = T[k] / one_m;  // transmittance in front of this Gaussian
            const S w = a * T[k];
            gr[5] += w * gc0;
            gr[6] += w * gc1;
            gr[7] += w * gc2;
            gr[9] += w * gd;
            const S g_a = T[k] * ((col[0] - r0[k]) * gc0 + (col[1] - r1[k]) * gc1 + (col[2] - r2[k]) * gc2 +
                                  (depth - rz[k]) * gd) - Tf[k] / one_m * gTf[k];
            r0[k] = a * col[0] + one_m * r0[k];
            r1[k] = a * col[1] + one_m * r1[k];
            r2[k] = a * col[2] + one_m * r2[k];
            rz[k] = a * depth + one_m * rz[k];
            if (opac * G > S(0.99)) continue;  // alpha clamped: no gradient to o or G
            gr[8] += g_a * G;
            const S g_pow = g_a * a;  // dL/dpower = dL/dalpha * o * G
            gr[0] += g_pow * (q[0] * dx + q[1] * dy);
            gr[1] += g_pow * (q[1] * dx + q[2] * dy);
            gr[2] += g_pow * S(-0.5) * dx * dx;
            gr[3] += g_pow * (-dx * dy);
            gr[4] += g_pow * S(-0.5) * dy * dy;
          }
        }
        S* out = acc.data() + 10 * g;
        for (int i = 0; i < 10; ++i) out[i] += gr[i];
      }
    }
  }
  std::memset(grad, 0, sizeof(S) * size_t(n) * 10);
  for (int tid = 0; tid < threads; ++tid) {
    const std::vector<S>& acc = local[tid];
    for (size_t i = 0; i < acc.size(); ++i) grad[i] += acc[i];
  }
}

}  // namespace

#define PGC_SPLAT_EXPORT(S, suffix)                                                                          \
  extern "C" void pgc_splat_forward_##suffix(                                                                \
      const S* means2d, const S* conics, const S* colors, const S* opac, const S* depths, const S* radii,   \
      const int64_t* offsets, const int64_t* ids, int H, int W, int tile, const S* bg, S* out_color,         \
      S* out_alpha, S* out_depth, int32_t* out_last, int threads) {                                         \
    Params<S> p{means2d, conics, colors, opac, depths, radii, offsets, ids, H, W, tile, (W + tile - 1) / tile}; \
    forward(p, bg, out_color, out_alpha, out_depth, out_last, threads);                                      \
  }                                                                                                          \
  extern "C" void pgc_splat_backward_##suffix(                                                               \
      const S* means2d, const S* conics, const S* colors, const S* opac, const S* depths, const S* radii,   \
      const int64_t* offsets, const int64_t* ids, int H, int W, int tile, int64_t n, const S* bg,           \
      const S* out_alpha, const int32_t* out_last, const S* g_color, const S* g_alpha, const S* g_depth,     \
      S* grad, int threads) {                                                                                \
    Params<S> p{means2d, conics, colors, opac, depths, radii, offsets, ids, H, W, tile, (W + tile - 1) / tile}; \
    backward(p, n, bg, out_alpha, out_last, g_color, g_alpha, g_depth, grad, threads);                       \
  }

PGC_SPLAT_EXPORT(float, f32)
PGC_SPLAT_EXPORT(double, f64)
