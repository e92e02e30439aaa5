// XPBD cloth frame step (C ABI, OpenMP): the maths of pgc/sim/kernels.py:advance_frame, element by element.
//
// Conventions: positions (V, 3) row-major in metres; constraint arrays concatenated in group order
// (group g owns [group_start[g], group_start[g + 1])); lam, residuals and constraint values are in that order.
// Determinism: every parallel loop writes only its own elements (vertices, or the constraints of one graph
// colour, which share no vertex); the Jacobi sweep and self-collision gather per-vertex sums in a fixed order,
// so the bytes of the result do not depend on the number of threads.

#include <cmath>
#include <cstdint>
#include <vector>

#include <omp.h>

namespace {

constexpr double EPS = 1e-9;  // lengths below this have no direction (kernels.EPS)

template <typename T>
struct Vec {
    T x, y, z;
};

template <typename T>
inline Vec<T> load(const T* a, int64_t i) { return {a[3 * i], a[3 * i + 1], a[3 * i + 2]}; }
template <typename T>
inline void store(T* a, int64_t i, Vec<T> v) { a[3 * i] = v.x; a[3 * i + 1] = v.y; a[3 * i + 2] = v.z; }
template <typename T>
inline Vec<T> operator+(Vec<T> a, Vec<T> b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <typename T>
inline Vec<T> operator-(Vec<T> a, Vec<T> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <typename T>
inline Vec<T> operator*(T s, Vec<T> a) { return {s * a.x, s * a.y, s * a.z}; }
template <typename T>
inline T dot(Vec<T> a, Vec<T> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename T>
inline T norm(Vec<T> a) { return std::sqrt(dot(a, a)); }
template <typename T>
inline Vec<T> unit(Vec<T> a) {
    T n = norm(a);
    T d = n > T(EPS) ? n : T(1);
    return {a.x / d, a.y / d, a.z / d};
}
template <typename T>
inline T guarded_div(T x, T y) { return std::fabs(y) > T(1e-30) ? x / y : T(0); }

// Barycentrics (u, v, w) of the point of triangle abc closest to p (Ericson's region tests, first match
// returns). The same formulas and priorities as kernels.closest_barycentric, whose later overrides win.
template <typename T>
inline void closest_barycentric(Vec<T> p, Vec<T> a, Vec<T> b, Vec<T> c, T& u, T& v, T& w) {
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
inline Contact<T> closest_contact(Vec<T> p, const T* body, const T* normals, const int32_t* corners, int K) {
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

// A constraint's data packed together (one cache line holds several): built once per frame call.
template <typename T>
struct Packed {
    int32_t i, j;
    T rest, alpha_t, share;
};

// One XPBD update of constraint c (kernels.project_distance): applied to p, or, for a Jacobi sweep, the
// correction dlam * n stored in corr for the per-vertex gather. Coloured groups have share 1 (skipped:
// x * 1 == x).
template <typename T, bool Jacobi>
inline void project(T* p, const T* inv_mass, int64_t c, const Packed<T>& k, T* lam, T* corr) {
    Vec<T> d = load(p, k.i) - load(p, k.j);
    T length = norm(d);
    T wi = inv_mass[k.i], wj = inv_mass[k.j], at = k.alpha_t;
    T denom = (wi + wj) + at;
    bool good = (length > T(EPS)) && (denom > 0);
    T dlam = good ? ((k.rest - length) - at * lam[c]) / denom : T(0);
    if (Jacobi) dlam *= k.share;
    lam[c] += dlam;
    T l = good ? length : T(1);
    Vec<T> n{d.x / l, d.y / l, d.z / l};
    Vec<T> cr = dlam * n;
    if (Jacobi) {
        store(corr, c, cr);
    } else {
        store(p, k.i, load(p, k.i) + wi * cr);
        store(p, k.j, load(p, k.j) - wj * cr);
    }
}

template <typename T>
void advance_frame(int64_t nv, int64_t nb, int64_t nc, int64_t ngroups, int64_t K, int64_t npairs, int jacobi,
                   int self_collision, int substeps, int iterations, const Scalars& sc, int threads, T* x, T* vel,
                   const T* inv_mass, const T* free_, const T* gravity, const int64_t* group_start,
                   const int32_t* ci, const int32_t* cj, const T* rest, const T* alpha_t, const T* share,
                   const int64_t* inc_start, const int32_t* inc, const T* body0, const T* body1,
                   const T* normals0, const T* normals1, const int32_t* corners, const int32_t* pairs,
                   const uint8_t* pair_valid, T* res_out, T* c_out) {
    const T h = T(sc.h), damping = T(sc.damping), offset = T(sc.offset), friction = T(sc.friction);
    const T radius = T(sc.contact_radius), max_step = T(sc.max_step), thickness = T(sc.thickness);
    const Vec<T> g = load(gravity, 0);
    std::vector<T> p(3 * nv), body_start(3 * nb), body(3 * nb), normals(3 * nb), lam(nc), corr(jacobi ? 3 * nc : 0);
    std::vector<T> cpoint(3 * nv), cnormal(3 * nv), pushed(nv);
    std::vector<uint8_t> active(nv);
    std::vector<Packed<T>> packed(nc);
    for (int64_t c = 0; c < nc; ++c) packed[c] = {ci[c], cj[c], rest[c], alpha_t[c], share[c]};
    std::vector<T> pcorr(self_collision ? 3 * npairs : 0), pmag(self_collision ? npairs : 0);
    std::vector<T> pcount(self_collision ? nv : 0);
    const int nthreads = threads > 0 ? threads : omp_get_max_threads();

#pragma omp parallel num_threads(nthreads)
    {
        for (int step = 0; step < substeps; ++step) {
            const T t0 = T(step) / T(substeps), t1 = T(step + 1) / T(substeps);
#pragma omp for schedule(static)
            for (int64_t b = 0; b < nb; ++b) {
                Vec<T> b0 = load(body0, b), b1 = load(body1, b), n0 = load(normals0, b), n1 = load(normals1, b);
                store(body_start.data(), b, b0 + t0 * (b1 - b0));
                store(body.data(), b, b0 + t1 * (b1 - b0));
                store(normals.data(), b, unit(n0 + t1 * (n1 - n0)));
            }
            // damping, gravity, clamped prediction, contact planes (kernels.advance_frame, before the sweeps)
#pragma omp for schedule(static)
            for (int64_t i = 0; i < nv; ++i) {
                Vec<T> v = damping * load(vel, i) + (h * free_[i]) * g;
                store(vel, i, v);
                Vec<T> st = h * v;
                T length = norm(st);
                Vec<T> pi = load(x, i) + (max_step / (length > max_step ? length : max_step)) * st;
                store(p.data(), i, pi);
                Contact<T> con = closest_contact(pi, body.data(), normals.data(), corners + 3 * K * i, (int)K);
                bool act = (free_[i] > 0) && (norm(pi - con.point) < radius);
                active[i] = act;
                T depth = act ? offset - con.signed_dist : T(0);
                pushed[i] = depth > 0 ? depth : T(0);
                store(cpoint.data(), i, con.point);
                store(cnormal.data(), i, con.normal);
            }
#pragma omp for schedule(static)
            for (int64_t c = 0; c < nc; ++c) lam[c] = 0;
            for (int it = 0; it < iterations; ++it) {
                if (jacobi) {
#pragma omp for schedule(static)
                    for (int64_t c = 0; c < nc; ++c)
                        project<T, true>(p.data(), inv_mass, c, packed[c], lam.data(), corr.data());
#pragma omp for schedule(static)
                    for (int64_t i = 0; i < nv; ++i) {  // fixed-order gather: i-side then j-side, by constraint
                        Vec<T> pi = load(p.data(), i);
                        for (int64_t k = inc_start[i]; k < inc_start[i + 1]; ++k) {
                            const int64_t c = inc[k] >> 1;
                            Vec<T> cr = load(corr.data(), c);
                            pi = (inc[k] & 1) ? pi - inv_mass[i] * cr : pi + inv_mass[i] * cr;
                        }
                        store(p.data(), i, pi);
                    }
                } else {
                    for (int64_t gi = 0; gi < ngroups; ++gi) {  // one graph colour: no shared vertex
#pragma omp for schedule(static)
                        for (int64_t c = group_start[gi]; c < group_start[gi + 1]; ++c)
                            project<T, false>(p.data(), inv_mass, c, packed[c], lam.data(), nullptr);
                    }
                }
#pragma omp for schedule(static)
                for (int64_t i = 0; i < nv; ++i) {  // contact half-spaces (kernels.push_out)
                    if (!active[i]) continue;
                    Vec<T> pi = load(p.data(), i), n = load(cnormal.data(), i);
                    T depth = offset - dot(pi - load(cpoint.data(), i), n);
                    if (depth > 0) store(p.data(), i, pi + depth * n);
                }
            }
            if (self_collision) {
#pragma omp single
                {  // kernels.separate_pairs, serial in pair order: deterministic
                    for (int64_t i = 0; i < nv; ++i) pcount[i] = 0;
                    for (int64_t k = 0; k < npairs; ++k) {
                        const int64_t a = pairs[2 * k], b = pairs[2 * k + 1];
                        Vec<T> d = load(p.data(), a) - load(p.data(), b);
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
                        store(p.data(), a, load(p.data(), a) + (inv_mass[a] * sa) * cr);
                    }
                    for (int64_t k = 0; k < npairs; ++k) {
                        const int64_t b = pairs[2 * k + 1];
                        T sb = T(1) / (pcount[b] > 0 ? pcount[b] : T(1));
                        Vec<T> cr = pmag[k] * load(pcorr.data(), k);
                        store(p.data(), b, load(p.data(), b) - (inv_mass[b] * sb) * cr);
                    }
                }
            }
            // body collision on fresh closest points with friction, velocity update (kernels.collide_body)
#pragma omp for schedule(static)
            for (int64_t i = 0; i < nv; ++i) {
                Vec<T> pi = load(p.data(), i), xs = load(x, i);
                Contact<T> con = closest_contact(pi, body.data(), normals.data(), corners + 3 * K * i, (int)K);
                bool act = (free_[i] > 0) && (norm(pi - con.point) < radius);
                T depth = act ? offset - dot(pi - con.point, con.normal) : T(0);
                depth = depth > 0 ? depth : T(0);
                pi = pi + depth * con.normal;
                depth = depth + pushed[i];
                Vec<T> start = (con.bary[0] * load(body_start.data(), con.tri[0]) +
                                con.bary[1] * load(body_start.data(), con.tri[1])) +
                               con.bary[2] * load(body_start.data(), con.tri[2]);
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
#pragma omp for schedule(static)
        for (int64_t c = 0; c < nc; ++c) {
            T cv = norm(load(x, ci[c]) - load(x, cj[c])) - rest[c];
            c_out[c] = cv;
            res_out[c] = cv + alpha_t[c] * lam[c];
        }
    }
}

}  // namespace

#define PGC_XPBD_FRAME(SUFFIX, T)                                                                              \
    extern "C" void pgc_xpbd_frame_##SUFFIX(                                                                   \
        int64_t nv, int64_t nb, int64_t nc, int64_t ngroups, int64_t K, int64_t npairs, int32_t jacobi,         \
        int32_t self_collision, int32_t substeps, int32_t iterations, const double* scalars, int32_t threads,   \
        T* x, T* v, const T* inv_mass, const T* free_, const T* gravity, const int64_t* group_start,           \
        const int32_t* ci, const int32_t* cj, const T* rest, const T* alpha_t, const T* share,                 \
        const int64_t* inc_start, const int32_t* inc, const T* body0, const T* body1, const T* normals0,         \
        const T* normals1, const int32_t* corners, const int32_t* pairs, const uint8_t* pair_valid, T* res_out,  \
        T* c_out) {                                                                                            \
        Scalars sc{scalars[0], scalars[1], scalars[2], scalars[3], scalars[4], scalars[5], scalars[6]};         \
        advance_frame<T>(nv, nb, nc, ngroups, K, npairs, jacobi, self_collision, substeps, iterations, sc,      \
                         threads, x, v, inv_mass, free_, gravity, group_start, ci, cj, rest, alpha_t, share,    \
                         inc_start, inc, body0, body1, normals0, normals1, corners, pairs, pair_valid, res_out, \
                         c_out);                                                                               \
    }

PGC_XPBD_FRAME(f32, float)
PGC_XPBD_FRAME(f64, double)
