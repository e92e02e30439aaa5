// XPBD cloth frame step (C ABI, OpenMP): the maths of pgc/sim/kernels.py:advance_frame, element by element.
//
// Conventions: positions (V, 3) row-major in metres; constraint arrays concatenated in group order
// (group g owns [group_start[g], group_start[g + 1])); lam, residuals and constraint values are in that order.
// Determinism: every parallel loop writes only its own elements (vertices, or the constraints of one graph
// colour, which share no vertex); the Jacobi sweep and self-collision gather per-vertex sums in a fixed order,
// so the bytes of the result do not depend on the number of threads.
//
// Speed: the working positions are (V, 4) rows (x, y, z, 0), one vector each, so a constraint update is a
// few vector operations; its three direction divisions and its multiplier division are one vector division
// (lane by lane the scalar formulas). This file is compiled twice, by including itself: once for the
// baseline ISA and once for AVX-512 (a `target` pragma), chosen at run time by the CPU. With
// -ffp-contract=off (no fused multiply-adds) and IEEE division and square root in both, the two builds give
// the same bytes (tests/test_xpbd_native.py checks it).

#ifndef PGC_XPBD_PASS
#define PGC_XPBD_PASS

#include <cmath>
#include <cstdint>
#include <vector>

#include <omp.h>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define PGC_XPBD_AVX512 1
#pragma GCC push_options
#pragma GCC target("avx2,fma,avx512f,avx512vl,avx512bw,avx512dq,avx512cd,prefer-vector-width=512")
namespace xpbd_avx512 {
#include __FILE__
}  // namespace xpbd_avx512
#pragma GCC pop_options
#endif

namespace xpbd_base {
#include __FILE__
}  // namespace xpbd_base

namespace {

bool use_avx512(int32_t simd) {
#ifdef PGC_XPBD_AVX512
    return simd && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
           __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
           __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    (void)simd;
    return false;
#endif
}

}  // namespace

// 1 when the AVX-512 build would run for simd = 1 on this CPU, else 0.
extern "C" int32_t pgc_xpbd_avx512() { return use_avx512(1) ? 1 : 0; }

#ifdef PGC_XPBD_AVX512
#define PGC_XPBD_DISPATCH(T, ...)                                                                   \
    if (use_avx512(simd)) xpbd_avx512::advance_frame<T>(__VA_ARGS__);                              \
    else xpbd_base::advance_frame<T>(__VA_ARGS__);
#else
#define PGC_XPBD_DISPATCH(T, ...) xpbd_base::advance_frame<T>(__VA_ARGS__);
#endif

#define PGC_XPBD_FRAME(SUFFIX, T)                                                                              \
    extern "C" void pgc_xpbd_frame_##SUFFIX(                                                                   \
        int64_t nv, int64_t nb, int64_t nc, int64_t ngroups, int64_t K, int64_t npairs, int32_t jacobi,         \
        int32_t self_collision, int32_t substeps, int32_t iterations, const double* scalars, int32_t threads,   \
        int32_t simd, T* x, T* v, const T* inv_mass, const T* free_, const T* gravity,                          \
        const int64_t* group_start, const int32_t* ci, const int32_t* cj, const T* rest, const T* alpha_t,      \
        const T* share, const int64_t* inc_start, const int32_t* inc, const T* body0, const T* body1,           \
        const T* normals0, const T* normals1, const int32_t* corners, const int32_t* pairs,                     \
        const uint8_t* pair_valid, T* res_out, T* c_out) {                                                     \
        PGC_XPBD_DISPATCH(T, nv, nb, nc, ngroups, K, npairs, jacobi, self_collision, substeps, iterations,     \
                          scalars, threads, x, v, inv_mass, free_, gravity, group_start, ci, cj, rest, alpha_t, \
                          share, inc_start, inc, body0, body1, normals0, normals1, corners, pairs, pair_valid,  \
                          res_out, c_out)                                                                      \
    }

PGC_XPBD_FRAME(f32, float)
PGC_XPBD_FRAME(f64, double)

#else  // the kernel, included once per ISA above

#define PGC_INLINE inline __attribute__((always_inline))

constexpr double EPS = 1e-9;  // lengths below this have no direction (kernels.EPS)

template <typename T>
struct Vec {
    T x, y, z;
};

// Row i of an (n, 3) array
template <typename T, typename I>
PGC_INLINE Vec<T> load(const T* a, I i) { return {a[3 * i], a[3 * i + 1], a[3 * i + 2]}; }
template <typename T, typename I>
PGC_INLINE void store(T* a, I i, Vec<T> v) { a[3 * i] = v.x; a[3 * i + 1] = v.y; a[3 * i + 2] = v.z; }
// Row i of the working positions, (n, 4) with a zero fourth column: one aligned vector per vertex.
template <typename T, typename I>
PGC_INLINE Vec<T> load4(const T* a, I i) { return {a[4 * i], a[4 * i + 1], a[4 * i + 2]}; }
template <typename T, typename I>
PGC_INLINE void store4(T* a, I i, Vec<T> v) { a[4 * i] = v.x; a[4 * i + 1] = v.y; a[4 * i + 2] = v.z; }
// Four lanes of T (GCC vector extension): the sweep works on (x, y, z, pad) rows
template <typename T>
struct Lanes {
    typedef T type __attribute__((vector_size(4 * sizeof(T))));
};
template <typename T>
PGC_INLINE Vec<T> operator+(Vec<T> a, Vec<T> b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <typename T>
PGC_INLINE Vec<T> operator-(Vec<T> a, Vec<T> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <typename T>
PGC_INLINE Vec<T> operator*(T s, Vec<T> a) { return {s * a.x, s * a.y, s * a.z}; }
template <typename T>
PGC_INLINE Vec<T> select(bool m, Vec<T> a, Vec<T> b) { return {m ? a.x : b.x, m ? a.y : b.y, m ? a.z : b.z}; }
template <typename T>
PGC_INLINE T dot(Vec<T> a, Vec<T> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename T>
PGC_INLINE T norm(Vec<T> a) { return std::sqrt(dot(a, a)); }
template <typename T>
PGC_INLINE Vec<T> unit(Vec<T> a) {
    T n = norm(a);
    T d = n > T(EPS) ? n : T(1);
    return {a.x / d, a.y / d, a.z / d};
}
template <typename T>
PGC_INLINE T guarded_div(T x, T y) { return std::fabs(y) > T(1e-30) ? x / y : T(0); }

// Barycentrics (u, v, w) of the point of triangle abc closest to p (Ericson's region tests, first match
// returns). The same formulas and priorities as kernels.closest_barycentric, whose later overrides win.
template <typename T>
PGC_INLINE void closest_barycentric(Vec<T> p, Vec<T> a, Vec<T> b, Vec<T> c, T& u, T& v, T& w) {
    Vec<T> ab = b - a, ac = c - a, ap = p - a;
    T d1 = dot(ab, ap), d2 = dot(ac, ap);
    v = 0; w = 0;
    if ((d1 <= 0) && (d2 <= 0)) { u = 1 - v - w; return; }  // vertex a
    Vec<T> bp = p - b;
    T d3 = dot(ab, bp), d4 = dot(ac, bp);
    if ((d3 >= 0) && (d4 <= d3)) { v = 1; u = 1 - v - w; return; }  // vertex b
    T vc = d1 * d4 - d3 * d2;
    if ((vc <= 0) && (d1 >= 0) && (d3 <= 0)) { v = guarded_div(d1, d1 - d3); u = 1 - v - w; return; }  // edge ab
    Vec<T> cp = p - c;
    T d5 = dot(ab, cp), d6 = dot(ac, cp);
    if ((d6 >= 0) && (d5 <= d6)) { w = 1; u = 1 - v - w; return; }  // vertex c
    T vb = d5 * d2 - d1 * d6;
    if ((vb <= 0) && (d2 >= 0) && (d6 <= 0)) { w = guarded_div(d2, d2 - d6); u = 1 - v - w; return; }  // edge ac
    T va = d3 * d6 - d5 * d4;
    if ((va <= 0) && (d4 - d3 >= 0) && (d5 - d6 >= 0)) {  // edge bc
        T t = guarded_div(d4 - d3, (d4 - d3) + (d5 - d6));
        v = 1 - t; w = t; u = 1 - v - w; return;
    }
    T total = va + vb + vc;  // interior
    v = guarded_div(vb, total);
    w = guarded_div(vc, total);
    u = 1 - v - w;
}

// Closest body point of one cloth vertex among its K candidate triangles (kernels.closest_contact).
template <typename T>
struct Contact {
    int32_t tri[3];
    T bary[3];
    Vec<T> point, normal;
    T signed_dist;
};

template <typename T>
PGC_INLINE Contact<T> closest_contact(Vec<T> p, const T* body, const T* normals, const int32_t* corners, int K) {
    Contact<T> best{};
    T best_d2 = T(0);
    for (int k = 0; k < K; ++k) {
        const int32_t* t = corners + 3 * k;
        Vec<T> a = load(body, t[0]), b = load(body, t[1]), c = load(body, t[2]);
        T u, v, w;
        closest_barycentric(p, a, b, c, u, v, w);
        Vec<T> q = (u * a + v * b) + w * c;
        Vec<T> d = p - q;
        T d2 = dot(d, d);
        if (k == 0 || d2 < best_d2) {  // the first minimum, as argmin
            best_d2 = d2;
            best.tri[0] = t[0]; best.tri[1] = t[1]; best.tri[2] = t[2];
            best.bary[0] = u; best.bary[1] = v; best.bary[2] = w;
            best.point = q;
        }
    }
    Vec<T> n = (best.bary[0] * load(normals, best.tri[0]) + best.bary[1] * load(normals, best.tri[1]))
               + best.bary[2] * load(normals, best.tri[2]);
    best.normal = unit(n);
    best.signed_dist = dot(p - best.point, best.normal);
    return best;
}

struct Scalars {
    double h, damping, offset, friction, contact_radius, max_step, thickness;
};

template <typename T>
void advance_frame(int64_t nv, int64_t nb, int64_t nc, int64_t ngroups, int64_t K, int64_t npairs, int jacobi,
                   int self_collision, int substeps, int iterations, const double* scalars, int threads, T* x,
                   T* vel, const T* inv_mass, const T* free_, const T* gravity, const int64_t* group_start,
                   const int32_t* ci, const int32_t* cj, const T* rest, const T* alpha_t, const T* share,
                   const int64_t* inc_start, const int32_t* inc, const T* body0, const T* body1,
                   const T* normals0, const T* normals1, const int32_t* corners, const int32_t* pairs,
                   const uint8_t* pair_valid, T* res_out, T* c_out) {
    const Scalars sc{scalars[0], scalars[1], scalars[2], scalars[3], scalars[4], scalars[5], scalars[6]};
    const T h = T(sc.h), damping = T(sc.damping), offset = T(sc.offset), friction = T(sc.friction);
    const T radius = T(sc.contact_radius), max_step = T(sc.max_step), thickness = T(sc.thickness);
    const T gx = gravity[0], gy = gravity[1], gz = gravity[2];
    std::vector<T> pbuf(4 * nv + 4), body_start_buf(3 * nb), body_buf(3 * nb), normals_buf(3 * nb), lam_buf(nc);
    std::vector<T> corr_buf(jacobi ? 3 * nc : 0), cpoint_buf(3 * nv), cnormal_buf(3 * nv), pushed_buf(nv);
    std::vector<uint8_t> active_buf(nv);
    std::vector<T> pcorr(self_collision ? 3 * npairs : 0), pmag(self_collision ? npairs : 0);
    std::vector<T> pcount(self_collision ? nv : 0);
    // working positions (V, 4), rows aligned to the vector type (4 T; pbuf has one spare row)
    T* __restrict p = pbuf.data() + (4 - (reinterpret_cast<uintptr_t>(pbuf.data()) / sizeof(T)) % 4) % 4;
    T* __restrict body_start = body_start_buf.data();
    T* __restrict body = body_buf.data();
    T* __restrict normals = normals_buf.data();
    T* __restrict lam = lam_buf.data();
    T* __restrict corr = corr_buf.data();
    T* __restrict cpoint = cpoint_buf.data();
    T* __restrict cnormal = cnormal_buf.data();
    T* __restrict pushed = pushed_buf.data();
    uint8_t* __restrict active = active_buf.data();
    const int nthreads = threads > 0 ? threads : omp_get_max_threads();
    using V = typename Lanes<T>::type;

#pragma omp parallel num_threads(nthreads)
    {
        for (int step = 0; step < substeps; ++step) {
            const T t0 = T(step) / T(substeps), t1 = T(step + 1) / T(substeps);
#pragma omp for simd schedule(static)
            for (int64_t b = 0; b < nb; ++b) {
                Vec<T> b0 = load(body0, b), b1 = load(body1, b), n0 = load(normals0, b), n1 = load(normals1, b);
                store(body_start, b, b0 + t0 * (b1 - b0));
                store(body, b, b0 + t1 * (b1 - b0));
                store(normals, b, unit(n0 + t1 * (n1 - n0)));
            }
            // damping, gravity, clamped prediction, contact planes (kernels.advance_frame, before the sweeps)
#pragma omp for schedule(static)
            for (int64_t i = 0; i < nv; ++i) {
                const T hf = h * free_[i];
                Vec<T> v = damping * load(vel, i) + Vec<T>{hf * gx, hf * gy, hf * gz};
                store(vel, i, v);
                Vec<T> st = h * v;
                T length = norm(st);
                Vec<T> pi = load(x, i) + (max_step / (length > max_step ? length : max_step)) * st;
                store4(p, i, pi);
                Contact<T> con = closest_contact(pi, body, normals, corners + 3 * K * i, (int)K);
                bool act = (free_[i] > 0) && (norm(pi - con.point) < radius);
                active[i] = act;
                T depth = act ? offset - con.signed_dist : T(0);
                pushed[i] = depth > 0 ? depth : T(0);
                store(cpoint, i, con.point);
                store(cnormal, i, con.normal);
            }
#pragma omp for simd schedule(static)
            for (int64_t c = 0; c < nc; ++c) lam[c] = 0;
            for (int it = 0; it < iterations; ++it) {
                if (jacobi) {
#pragma omp for schedule(static)
                    for (int64_t c = 0; c < nc; ++c) {  // every correction stored, gathered per vertex below
                        const int32_t i = ci[c], j = cj[c];
                        Vec<T> d = load4(p, i) - load4(p, j);
                        T length = norm(d), at = alpha_t[c], denom = (inv_mass[i] + inv_mass[j]) + at;
                        bool good = (length > T(EPS)) & (denom > 0);
                        T dlam = good ? ((rest[c] - length) - at * lam[c]) / (good ? denom : T(1)) : T(0);
                        dlam *= share[c];
                        lam[c] += dlam;
                        T l = good ? length : T(1);
                        store(corr, c, dlam * Vec<T>{d.x / l, d.y / l, d.z / l});
                    }
#pragma omp for schedule(static)
                    for (int64_t i = 0; i < nv; ++i) {  // fixed-order gather: i-side then j-side, by constraint
                        Vec<T> pi = load4(p, i);
                        for (int64_t k = inc_start[i]; k < inc_start[i + 1]; ++k) {
                            const int64_t c = inc[k] >> 1;
                            Vec<T> cr = load(corr, c);
                            pi = (inc[k] & 1) ? pi - inv_mass[i] * cr : pi + inv_mass[i] * cr;
                        }
                        store4(p, i, pi);
                    }
                } else {
                    for (int64_t gi = 0; gi < ngroups; ++gi) {  // one graph colour: no shared vertex
#pragma omp for schedule(static)
                        for (int64_t c = group_start[gi]; c < group_start[gi + 1]; ++c) {
                            // kernels.project_distance with share 1, applied in place. One vertex row is one
                            // vector (x, y, z, pad): the three divisions of the direction and the one of the
                            // multiplier update are one vector division, lane by lane the scalar formulas
                            const int32_t i = ci[c], j = cj[c];
                            V* pi = reinterpret_cast<V*>(p + 4 * i);
                            V* pj = reinterpret_cast<V*>(p + 4 * j);
                            const V a = *pi, b = *pj;
                            const V d = a - b;
                            const V dd = d * d;
                            const T length = std::sqrt(dd[0] + dd[1] + dd[2]);
                            const T wi = inv_mass[i], wj = inv_mass[j], at = alpha_t[c];
                            const T denom = (wi + wj) + at;
                            const bool good = (length > T(EPS)) & (denom > 0);
                            const T l = good ? length : T(1);
                            const V q = V{d[0], d[1], d[2], (rest[c] - length) - at * lam[c]} /
                                        V{l, l, l, good ? denom : T(1)};
                            const T dlam = good ? q[3] : T(0);
                            lam[c] += dlam;
                            const V cr = dlam * V{q[0], q[1], q[2], T(0)};
                            *pi = a + wi * cr;
                            *pj = b - wj * cr;
                        }
                    }
                }
#pragma omp for simd schedule(static)
                for (int64_t i = 0; i < nv; ++i) {  // contact half-spaces (kernels.push_out)
                    Vec<T> pi = load4(p, i), n = load(cnormal, i);
                    T depth = offset - dot(pi - load(cpoint, i), n);
                    store4(p, i, select(active[i] & (depth > 0), pi + depth * n, pi));
                }
            }
            if (self_collision) {
#pragma omp single
                {  // kernels.separate_pairs, serial in pair order: deterministic
                    for (int64_t i = 0; i < nv; ++i) pcount[i] = 0;
                    for (int64_t k = 0; k < npairs; ++k) {
                        const int64_t a = pairs[2 * k], b = pairs[2 * k + 1];
                        Vec<T> d = load4(p, a) - load4(p, b);
                        T length = norm(d), wa = inv_mass[a], wb = inv_mass[b];
                        bool on = pair_valid[k] && (length < thickness) && (length > T(EPS)) && (wa + wb > 0);
                        T l = on ? length : T(1);
                        store(pcorr.data(), k, Vec<T>{d.x / l, d.y / l, d.z / l});
                        pmag[k] = on ? (thickness - length) / (wa + wb) : T(0);
                        pcount[a] += on ? T(1) : T(0);
                        pcount[b] += on ? T(1) : T(0);
                    }
                    for (int64_t k = 0; k < npairs; ++k) {
                        const int64_t a = pairs[2 * k];
                        T sa = T(1) / (pcount[a] > 0 ? pcount[a] : T(1));
                        Vec<T> cr = pmag[k] * load(pcorr.data(), k);
                        store4(p, a, load4(p, a) + (inv_mass[a] * sa) * cr);
                    }
                    for (int64_t k = 0; k < npairs; ++k) {
                        const int64_t b = pairs[2 * k + 1];
                        T sb = T(1) / (pcount[b] > 0 ? pcount[b] : T(1));
                        Vec<T> cr = pmag[k] * load(pcorr.data(), k);
                        store4(p, b, load4(p, b) - (inv_mass[b] * sb) * cr);
                    }
                }
            }
            // body collision on fresh closest points with friction, velocity update (kernels.collide_body)
#pragma omp for schedule(static)
            for (int64_t i = 0; i < nv; ++i) {
                Vec<T> pi = load4(p, i), xs = load(x, i);
                Contact<T> con = closest_contact(pi, body, normals, corners + 3 * K * i, (int)K);
                bool act = (free_[i] > 0) && (norm(pi - con.point) < radius);
                T depth = act ? offset - dot(pi - con.point, con.normal) : T(0);
                depth = depth > 0 ? depth : T(0);
                pi = pi + depth * con.normal;
                depth = depth + pushed[i];
                Vec<T> start = (con.bary[0] * load(body_start, con.tri[0]) +
                                con.bary[1] * load(body_start, con.tri[1])) +
                               con.bary[2] * load(body_start, con.tri[2]);
                Vec<T> rel = (pi - xs) - (con.point - start);
                Vec<T> tang = rel - dot(rel, con.normal) * con.normal;
                T tl = norm(tang);
                T scale = T(0);
                if (depth > 0 && tl > T(EPS)) {
                    scale = friction * depth / tl;
                    scale = scale < T(1) ? scale : T(1);
                }
                pi = pi - scale * tang;
                Vec<T> dv = pi - xs;
                store(vel, i, Vec<T>{dv.x / h, dv.y / h, dv.z / h});
                store(x, i, pi);
            }
        }
        // final residuals C + alpha_t lam and values C (kernels.constraint_residual)
#pragma omp for simd schedule(static)
        for (int64_t c = 0; c < nc; ++c) {
            T cv = norm(load(x, ci[c]) - load(x, cj[c])) - rest[c];
            c_out[c] = cv;
            res_out[c] = cv + alpha_t[c] * lam[c];
        }
    }
}

#undef PGC_INLINE

#endif  // PGC_XPBD_PASS
