/* fuzzyservo: fuzzy-system evaluators in C99 (a fragment the code generator pastes verbatim).
 *
 * A line-by-line port of the compiled (numba) Python evaluators:
 *
 *   fs_grid_eval   fuzzyservo.fuzzy.kernels.eval_uniform_grid   (uniform rule tables)
 *   fs_grid_pair   fuzzyservo.fuzzy.kernels.eval_uniform_pair
 *   fs_sys_eval    fuzzyservo.fuzzy.general.eval_point          (packed general systems)
 *   fs_sys_eval2   fuzzyservo.fuzzy.general.eval_first2
 *
 * with every path of the general evaluator: the partition fast path (fuzzy/partition.py), the
 * exact piecewise-linear path, singletons, Sugeno and the smooth adaptive Gauss-Kronrod path.
 *
 * Exactness. In double precision the operations are those of the Python code, in the same
 * order (a * b + c is written as numba evaluates it, left to right), so results are
 * bit-identical: no -ffast-math, no FMA contraction (GCC does not contract in ISO C mode,
 * -std=c99; clang is told so by the pragma below), and IEEE double arithmetic without excess
 * precision (FLT_EVAL_METHOD 0: SSE2 on x86, not the x87 FPU). exp, pow and sqrt come from the
 * C library, which is the one numba calls on the same machine. Where numba's semantics needed
 * care the code says "numba:".
 *
 * Use. Before this fragment the including file sets the real type:
 *     typedef double fs_real;                      or
 *     typedef float fs_real;  #define FS_FLOAT 1
 * Integer tables are int32_t (fuzzyservo.export.fuzzy_c checks that the values fit). Every
 * function is static and named fs_*; nothing is allocated and nothing global is written: the
 * caller passes the scratch (sizes from fuzzyservo.export.fuzzy_c.scratch_sizes). Optional:
 * FS_SCRATCH (the storage class the generated wrappers give their scratch arrays; empty, i.e.
 * automatic, by default; "static" trades reentrancy for stack on small targets).
 */
#ifndef FS_FUZZY_FRAGMENT
#define FS_FUZZY_FRAGMENT 1

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#if defined(__GNUC__) || defined(__clang__)
#define FS_MAYBE_UNUSED __attribute__((unused))
#else
#define FS_MAYBE_UNUSED
#endif

#ifndef FS_SCRATCH
#define FS_SCRATCH
#endif

#define FS_R(x) ((fs_real)(x))

#ifdef FS_FLOAT
#define FS_SQRT sqrtf
#define FS_FABS fabsf
#define FS_EXP expf
#define FS_POW powf
#define FS_FLOOR floorf
#else
#define FS_SQRT sqrt
#define FS_FABS fabs
#define FS_EXP exp
#define FS_POW pow
#define FS_FLOOR floor
#endif
#define FS_NAN FS_R(NAN)
#define FS_INF FS_R(INFINITY)

/* Tolerances. In double they are the Python code's numbers (so the results are its
 * results). In float (FS_FLOAT) each is chosen for float; the measured effect of each
 * choice is in docs/export-fuzzy-c.md. FS_ULPS(d) is d * FLT_EPSILON / DBL_EPSILON (2^29):
 * the same number of units in the last place as the double code allows. */
#ifdef FS_FLOAT
#define FS_ULPS(d) FS_R((d) * 536870912.0)
/* c + m y equal to the clip height h "up to its rounding": 4.5 ulps of |c| + |m y|, as in
 * double (it snaps a rounding error, so it scales with the rounding) */
#define FS_TOL_CLIP FS_ULPS(1e-15)
/* bisector: a linear piece is flat when its rise is below 45 ulps of its values, as in
 * double (the quadratic's root loses that much to cancellation there) */
#define FS_TOL_FLAT FS_ULPS(1e-14)
/* maxima of piecewise-linear and singleton outputs: values within 64 ulps (7.6e-6) of the
 * largest tie, and a plateau (or a second maximising point) must be longer than 64 ulps of
 * the support. The double code's 1e-12 is 4500 ulps; 4500 float ulps (5.4e-4) merged
 * distinct plateaus and dropped real plateau pieces up to 5e-4 of the support long, moving
 * the mean of maximum by 2e-4 of the range; 64 ulps still covers the rounding of clip points
 * and crossings (a few ulps of coordinates up to ~10x the support) */
#define FS_TOL_TIE (FS_R(64.0) * FLT_EPSILON)
#define FS_TOL_MINLEN (FS_R(64.0) * FLT_EPSILON)
/* smooth outputs: a Gauss-Kronrod subinterval is accepted when |K15 - G7| <= RTOL A len /
 * range. |K15 - G7| carries the rounding of the sums, which does not shrink with the
 * interval: the double code's 1e-12 leaves 4500 ulps of headroom above it, and float keeps
 * that headroom (5.4e-4). |K15 - G7| overestimates the K15 error by orders of magnitude on
 * smooth pieces: float centroids and bisectors stay within ~4e-7 of the range of Python's.
 * A smaller value would subdivide a peaked aggregate to the subdivision budget (slow, no
 * gain: the rounding does not shrink). */
#define FS_QUAD_RTOL FS_ULPS(1e-12)
/* smooth maxima: values within 16 ulps (1.9e-6) of the largest tie. The aggregate's values
 * carry a few ulps of rounding (exp of a rounded argument: up to ~t^2 ulps); the double
 * code's 4500 ulps would tie maxima 5e-4 apart in value and average points far apart */
#define FS_TOL_SMAX (FS_R(16.0) * FLT_EPSILON)
/* the scan of a knot interval starts and ends this fraction of half a cell inside it, off
 * the knot itself. Double: 1e-9 (p + inset != p for |p| up to 1e6 cells); float: 1e-4 (the
 * same for |p| up to ~100 cells); the piece boundaries it can miss are caught by the
 * quadrature's error test, as in double */
#define FS_SCAN_INSET FS_R(1e-4)
/* golden section stops at 4.5 ulps of the range, as in double (a rounding limit) */
#define FS_TOL_GOLDEN FS_ULPS(1e-15)
/* a second difference's rounding: 7.2 ulps of g / (d/2)^2, as in double */
#define FS_TOL_D2 FS_ULPS(16e-16)
/* the largest share of a second difference its rounding may take before the refinement of
 * a smooth maximum gives up. Double: 1e-3. In float that share is only met at steps wider
 * than the scan's cells, so every smooth maximum stayed at its golden-section estimate
 * (sqrt(eps): 1e-4 of the range); 0.1 lets the Newton refinement run (the fixed second
 * derivative then is within 10 %: Newton still converges, and a refined point that lowers
 * the value is rejected below) and brings 90 % of them within 1e-5 of the range */
#define FS_D2_SHARE FS_R(0.1)
/* rounding's share of a Newton root: 0.9 ulps of g / (d |g''|), as in double */
#define FS_TOL_ROOT FS_ULPS(2e-16)
/* a refined maximum may not lower the value by more than 1.8 ulps, as in double */
#define FS_TOL_DROP FS_ULPS(4e-16)
/* the refined maximum's location. Double: 1e-11 of the range (eps^0.69). Central
 * differences in float locate a smooth maximum to about eps^0.8 of its width at best; 64
 * ulps (7.6e-6 of the range) keeps the refinement's target reachable */
#define FS_TOL_X (FS_R(64.0) * FLT_EPSILON)
#else
#define FS_TOL_CLIP 1e-15
#define FS_TOL_FLAT 1e-14
#define FS_TOL_TIE 1e-12
#define FS_TOL_MINLEN 1e-12
#define FS_QUAD_RTOL 1e-12
#define FS_TOL_SMAX 1e-12
#define FS_SCAN_INSET 1e-9
#define FS_TOL_GOLDEN 1e-15
#define FS_TOL_D2 16e-16
#define FS_D2_SHARE 1e-3
#define FS_TOL_ROOT 2e-16
#define FS_TOL_DROP 4e-16
#define FS_TOL_X 1e-11
#endif

/* header of the packed integers (fuzzyservo.fuzzy.general, H_*) */
#define FS_H_MAGIC 0
#define FS_H_NIN 1
#define FS_H_NOUT 2
#define FS_H_NTERMS 3
#define FS_H_NRULES 4
#define FS_H_KIND 5
#define FS_H_AND 6
#define FS_H_OR 7
#define FS_H_IMPL 8
#define FS_H_AGG 9
#define FS_H_DEFUZZ 10
#define FS_H_VARS 11
#define FS_H_TERMS 12
#define FS_H_RULES 13
#define FS_H_PROG 14
#define FS_H_CONS 15
#define FS_H_OUTS 16
#define FS_H_WORK 17
#define FS_H_STACK 18
#define FS_H_FVARS 19
#define FS_H_FLAT 20
#define FS_H_FLATOFF 21
#define FS_H_MAXITEMS 22
#define FS_H_FWEIGHT 23
#define FS_H_PIVOT 24
#define FS_H_IWORK 25
#define FS_H_GRID 26
#define FS_H_PART 27
#define FS_H_PARTF 28
#define FS_MAGIC 20261130L

/* term shapes (general.SHAPE_CODE) */
#define FS_TRI 0
#define FS_TRAP 1
#define FS_RECT 2
#define FS_RAMP 3
#define FS_DISC 4
#define FS_SING 5
#define FS_GAUSS 6
#define FS_GAUSS2 7
#define FS_BELL 8
#define FS_SIG 9
#define FS_DSIG 10
#define FS_PSIG 11
#define FS_SMF 12
#define FS_ZMF 13
#define FS_PIMF 14
#define FS_CONST 15
#define FS_LIN 16

/* output modes, program ops */
#define FS_M_PL 0
#define FS_M_SING 1
#define FS_M_SMOOTH 2
#define FS_M_SUGENO 3
#define FS_OUT_FIELDS 7
#define FS_OP_IS 0
#define FS_OP_NOT 1
#define FS_OP_AND 2
#define FS_OP_OR 3

/* the smooth path (general.SCAN_CELLS, CELL_CHANGES, QUAD_MAX_SUB; its stack of 256) */
#define FS_SCAN_CELLS 32
#define FS_CELL_CHANGES 8
#define FS_QUAD_MAX_SUB 4000L
#define FS_QUAD_STACK 256

/* Gauss-Kronrod 7-15 nodes and weights (QUADPACK's qk15), the Python tables' doubles
 * written exactly */
static const fs_real fs_xgk[8] = {
    FS_R(0x1.fba009d4d09b1p-1), FS_R(0x1.e5f178e7c6229p-1), FS_R(0x1.bacf827b9bb3ep-1),
    FS_R(0x1.7ba9f9be3a1d6p-1), FS_R(0x1.2c13a049dfa24p-1), FS_R(0x1.9f95df119fd62p-2),
    FS_R(0x1.a98b2892e0c77p-3), FS_R(0x0.0p+0)};
static const fs_real fs_wgk[8] = {
    FS_R(0x1.77c5b67d57470p-6), FS_R(0x1.026cdaa7b61c4p-4), FS_R(0x1.ad384a34814c6p-4),
    FS_R(0x1.200ed0f46e8c1p-3), FS_R(0x1.5a1f266e47d5cp-3), FS_R(0x1.85d6861c80eb1p-3),
    FS_R(0x1.a2adbcbec9cd8p-3), FS_R(0x1.ad04f9087090fp-3)};
static const fs_real fs_wg[4] = {
    FS_R(0x1.092f69f826d57p-3), FS_R(0x1.1e6b1713d8644p-2), FS_R(0x1.86fe74ee32b3dp-2),
    FS_R(0x1.abfd7e03c2fa6p-2)};

/* numba: min(a, b) and max(a, b) are Python's: the first argument unless the second
 * compares smaller (larger); with a NaN the result depends on the order, as here. */
FS_MAYBE_UNUSED static fs_real fs_min(fs_real a, fs_real b) { return b < a ? b : a; }
FS_MAYBE_UNUSED static fs_real fs_max(fs_real a, fs_real b) { return b > a ? b : a; }
FS_MAYBE_UNUSED static long fs_imin(long a, long b) { return b < a ? b : a; }
FS_MAYBE_UNUSED static long fs_imax(long a, long b) { return b > a ? b : a; }

/* ======================================================================================
 * uniform rule tables (fuzzy/kernels.py)
 */

/* segment_integrals: area and first moment over s in [0, 1] of max(min(a, 1-s), min(b, s)) */
FS_MAYBE_UNUSED static void fs_segment_integrals(fs_real a, fs_real b, fs_real *area,
                                                 fs_real *moment) {
    fs_real m = fs_min(fs_min(a, b), FS_R(0.5)); /* min(a, b, 0.5) */
    fs_real tm = m - m * m;
    *area = a - FS_R(0.5) * a * a + b - FS_R(0.5) * b * b - tm;
    *moment = FS_R(0.5) * (a - a * a + b - tm) + (a * a * a - b * b * b) * (FS_R(1.0) / FS_R(6.0));
}

FS_MAYBE_UNUSED static fs_real fs_height(long j, long la, fs_real wa, long lb, fs_real wb,
                                         long lc, fs_real wc, long ld, fs_real wd) {
    return fs_max(fs_max(la == j ? wa : FS_R(0.0), lb == j ? wb : FS_R(0.0)),
                  fs_max(lc == j ? wc : FS_R(0.0), ld == j ? wd : FS_R(0.0)));
}

FS_MAYBE_UNUSED static void fs_grid_cell(fs_real x1, fs_real x2, int n1, int n2,
                                         const fs_real *lims, long *k1, long *k2, fs_real *f1,
                                         fs_real *f2) {
    fs_real lo1 = lims[0], hi1 = lims[1], lo2 = lims[2], hi2 = lims[3], t1, t2;
    if (x1 < lo1) x1 = lo1;
    else if (x1 > hi1) x1 = hi1;
    if (x2 < lo2) x2 = lo2;
    else if (x2 > hi2) x2 = hi2;
    t1 = (x1 - lo1) / (hi1 - lo1) * FS_R(n1 - 1);
    t2 = (x2 - lo2) / (hi2 - lo2) * FS_R(n2 - 1);
    /* numba: int() truncates toward zero; t1, t2 are in [0, n - 1] here (clipped inputs) */
    *k1 = (long)t1;
    if (*k1 > n1 - 2) *k1 = n1 - 2;
    *k2 = (long)t2;
    if (*k2 > n2 - 2) *k2 = n2 - 2;
    *f1 = t1 - FS_R(*k1);
    *f2 = t2 - FS_R(*k2);
}

FS_MAYBE_UNUSED static fs_real fs_grid_centroid(long k1, long k2, fs_real f1, fs_real f2,
                                                const int32_t *rules, int n1,
                                                const fs_real *lims) {
    fs_real g1 = FS_R(1.0) - f1, g2 = FS_R(1.0) - f2;
    long la = rules[k2 * n1 + k1], lb = rules[k2 * n1 + k1 + 1];
    long lc = rules[(k2 + 1) * n1 + k1], ld = rules[(k2 + 1) * n1 + k1 + 1];
    fs_real wa = fs_min(g1, g2), wb = fs_min(f1, g2), wc = fs_min(g1, f2), wd = fs_min(f1, f2);
    fs_real area = FS_R(0.0), parea = FS_R(0.0), moment = FS_R(0.0), ha, hb, ar, mo, lo;
    long n_out, lmin, lmax, j, jend;
    if (la < 0) wa = FS_R(0.0);
    if (lb < 0) wb = FS_R(0.0);
    if (lc < 0) wc = FS_R(0.0);
    if (ld < 0) wd = FS_R(0.0);
    n_out = (long)lims[6];
    lmin = n_out;
    lmax = -1;
    if (wa > FS_R(0.0)) { lmin = fs_imin(lmin, la); lmax = fs_imax(lmax, la); }
    if (wb > FS_R(0.0)) { lmin = fs_imin(lmin, lb); lmax = fs_imax(lmax, lb); }
    if (wc > FS_R(0.0)) { lmin = fs_imin(lmin, lc); lmax = fs_imax(lmax, lc); }
    if (wd > FS_R(0.0)) { lmin = fs_imin(lmin, ld); lmax = fs_imax(lmax, ld); }
    j = fs_imax(lmin - 1, 0);
    jend = fs_imin(lmax, n_out - 2);
    ha = fs_height(j, la, wa, lb, wb, lc, wc, ld, wd);
    while (j <= jend) {
        hb = fs_height(j + 1, la, wa, lb, wb, lc, wc, ld, wd);
        if (ha > FS_R(0.0) || hb > FS_R(0.0)) {
            fs_segment_integrals(ha, hb, &ar, &mo);
            area += ar;
            parea += FS_R(j) * ar;
            moment += mo;
        }
        ha = hb;
        j += 1;
    }
    if (area <= FS_R(0.0)) return lims[7];
    lo = lims[4];
    return lo + (lims[5] - lo) * (parea + moment) / (area * FS_R(n_out - 1));
}

/* eval_uniform_grid: rules row-major (n2 rows of x2, n1 columns of x1), lims[8] */
FS_MAYBE_UNUSED static fs_real fs_grid_eval(fs_real x1, fs_real x2, const int32_t *rules,
                                            int n2, int n1, const fs_real *lims) {
    long k1, k2;
    fs_real f1, f2;
    if (x1 != x1 || x2 != x2) return FS_NAN;
    fs_grid_cell(x1, x2, n1, n2, lims, &k1, &k2, &f1, &f2);
    return fs_grid_centroid(k1, k2, f1, f2, rules, n1, lims);
}

/* eval_uniform_pair: two rule tables on the same inputs (located once when their grids are
 * the same) */
FS_MAYBE_UNUSED static void fs_grid_pair(fs_real x1, fs_real x2, const int32_t *rules_a,
                                         int n2a, int n1a, const fs_real *lims_a,
                                         const int32_t *rules_b, int n2b, int n1b,
                                         const fs_real *lims_b, fs_real *out_a,
                                         fs_real *out_b) {
    long k1, k2;
    fs_real f1, f2;
    if (x1 != x1 || x2 != x2) {
        *out_a = FS_NAN;
        *out_b = FS_NAN;
        return;
    }
    fs_grid_cell(x1, x2, n1a, n2a, lims_a, &k1, &k2, &f1, &f2);
    *out_a = fs_grid_centroid(k1, k2, f1, f2, rules_a, n1a, lims_a);
    if (n2b == n2a && n1b == n1a && lims_b[0] == lims_a[0] && lims_b[1] == lims_a[1] &&
        lims_b[2] == lims_a[2] && lims_b[3] == lims_a[3]) {
        *out_b = fs_grid_centroid(k1, k2, f1, f2, rules_b, n1b, lims_b);
        return;
    }
    fs_grid_cell(x1, x2, n1b, n2b, lims_b, &k1, &k2, &f1, &f2);
    *out_b = fs_grid_centroid(k1, k2, f1, f2, rules_b, n1b, lims_b);
}

/* ======================================================================================
 * membership functions (general.mf_value)
 */

FS_MAYBE_UNUSED static fs_real fs_sigmoid(fs_real x, fs_real c, fs_real a) {
    return FS_R(1.0) / (FS_R(1.0) + FS_EXP(-a * (x - c)));
}

FS_MAYBE_UNUSED static fs_real fs_smf(fs_real x, fs_real a, fs_real b) {
    fs_real m, t;
    if (x <= a) return FS_R(0.0);
    if (x >= b) return FS_R(1.0);
    m = FS_R(0.5) * (a + b);
    if (x <= m) {
        t = (x - a) / (b - a);
        return FS_R(2.0) * t * t;
    }
    t = (x - b) / (b - a);
    return FS_R(1.0) - FS_R(2.0) * t * t;
}

/* membership (height applied) of term `code` with parameters f[off:off+n], height f[off+n]
 * (and, for triangles and trapezoids, the edges' slopes at f[off+n+1], f[off+n+2]) */
FS_MAYBE_UNUSED static fs_real fs_mf(long code, const fs_real *f, long off, long n, fs_real x) {
    fs_real h = f[off + n], a, b, c, d, t, v;
    if (x != x) return FS_NAN;
    switch (code) {
    case FS_TRI:
        a = f[off];
        b = f[off + 1];
        c = f[off + 2];
        if (x < a || x > c) return FS_R(0.0);
        if (x == b) return h;
        if (x < b) return (x - a) * f[off + n + 1];
        return (c - x) * f[off + n + 2];
    case FS_TRAP:
        a = f[off];
        b = f[off + 1];
        c = f[off + 2];
        d = f[off + 3];
        if (x < a || x > d) return FS_R(0.0);
        if (x < b) return a == -FS_INF ? h : (x - a) * f[off + n + 1];
        if (x <= c) return h;
        if (x < d) return d == FS_INF ? h : (d - x) * f[off + n + 2];
        return d == FS_INF ? h : FS_R(0.0);
    case FS_RECT:
        return (f[off] <= x && x <= f[off + 1]) ? h : FS_R(0.0);
    case FS_RAMP:
        a = f[off];
        b = f[off + 1];
        if (a == b) return FS_R(0.0);
        if (a < b) {
            if (x <= a) return FS_R(0.0);
            if (x >= b) return h;
            return h * (x - a) / (b - a);
        }
        if (x >= a) return FS_R(0.0);
        if (x <= b) return h;
        return h * (a - x) / (a - b);
    case FS_DISC: {
        long m = n / 2, lo = 0, hi, mid; /* numba: n // 2 with n >= 4 */
        fs_real x0, x1, y0, y1;
        if (x <= f[off]) return h * f[off + 1];
        if (x >= f[off + 2 * (m - 1)]) return h * f[off + 2 * m - 1];
        hi = m - 1;
        while (hi - lo > 1) {
            mid = (lo + hi) / 2;
            if (f[off + 2 * mid] <= x) lo = mid;
            else hi = mid;
        }
        x0 = f[off + 2 * lo];
        x1 = f[off + 2 * hi];
        y0 = f[off + 2 * lo + 1];
        y1 = f[off + 2 * hi + 1];
        if (x1 == x0) return h * y1;
        return h * (y0 + (y1 - y0) * (x - x0) / (x1 - x0));
    }
    case FS_SING:
        return x == f[off] ? h : FS_R(0.0);
    case FS_GAUSS:
        t = (x - f[off]) / f[off + 1];
        return h * FS_EXP(FS_R(-0.5) * t * t);
    case FS_GAUSS2:
        v = FS_R(1.0);
        if (x < f[off]) {
            t = (x - f[off]) / f[off + 1];
            v *= FS_EXP(FS_R(-0.5) * t * t);
        }
        if (x > f[off + 2]) {
            t = (x - f[off + 2]) / f[off + 3];
            v *= FS_EXP(FS_R(-0.5) * t * t);
        }
        return h * v;
    case FS_BELL:
        /* numba: t ** p is the C library's pow */
        t = FS_FABS((x - f[off]) / f[off + 1]);
        return h / (FS_R(1.0) + FS_POW(t, FS_R(2.0) * f[off + 2]));
    case FS_SIG:
        return h * fs_sigmoid(x, f[off], f[off + 1]);
    case FS_DSIG:
        return h * FS_FABS(fs_sigmoid(x, f[off], f[off + 1]) -
                           fs_sigmoid(x, f[off + 3], f[off + 2]));
    case FS_PSIG:
        return h * fs_sigmoid(x, f[off], f[off + 1]) * fs_sigmoid(x, f[off + 3], f[off + 2]);
    case FS_SMF:
        return h * fs_smf(x, f[off], f[off + 1]);
    case FS_ZMF:
        return h * (FS_R(1.0) - fs_smf(x, f[off], f[off + 1]));
    case FS_PIMF:
        return h * fs_smf(x, f[off], f[off + 1]) * (FS_R(1.0) - fs_smf(x, f[off + 2], f[off + 3]));
    default:
        return FS_NAN;
    }
}

/* ======================================================================================
 * rule strengths (general._strengths)
 */

/* a + b - a b, exact at the ends (1 - (1 - a)(1 - b) once either is >= 1/2) */
FS_MAYBE_UNUSED static fs_real fs_probor(fs_real a, fs_real b) {
    if (a >= FS_R(0.5) || b >= FS_R(0.5)) return FS_R(1.0) - (FS_R(1.0) - a) * (FS_R(1.0) - b);
    return a + b - a * b;
}

/* input memberships mu, rule strengths w (weight applied, valid for the rules that fired) and
 * the list of the rules that fired; returns their number */
FS_MAYBE_UNUSED static long fs_strengths(const int32_t *ints, const fs_real *f,
                                         const fs_real *xin, fs_real *mu, fs_real *w,
                                         fs_real *stk, int32_t *fired, int32_t *nz) {
    long n_in = ints[FS_H_NIN], vt = ints[FS_H_VARS], tt = ints[FS_H_TERMS];
    long n_rules = ints[FS_H_NRULES], rt = ints[FS_H_RULES], and_op = ints[FS_H_AND];
    long or_op = ints[FS_H_OR], flat = ints[FS_H_FLAT], fw = ints[FS_H_FWEIGHT];
    long nf = 0, gt = ints[FS_H_GRID], pv, i, t, r, q;
    fs_real acc, v;
    for (i = 0; i < n_in; ++i) {
        long first = ints[vt + 2 * i];
        for (t = first; t < first + ints[vt + 2 * i + 1]; ++t)
            mu[t] = fs_mf(ints[tt + 3 * t], f, ints[tt + 3 * t + 1], ints[tt + 3 * t + 2], xin[i]);
    }
    if (gt >= 0) {
        /* a rule table: the cells of the non-zero terms (a mixed-radix counter over the
         * inputs); nz[0:n_in] = number of non-zero terms per input, then their indices */
        long pos = n_in, total, combo;
        for (i = 0; i < n_in; ++i) {
            long first = ints[vt + 2 * i], cnt = 0, tl;
            for (tl = 0; tl < ints[vt + 2 * i + 1]; ++tl) {
                if (mu[first + tl] > FS_R(0.0)) {
                    nz[pos + cnt] = (int32_t)tl;
                    cnt += 1;
                }
            }
            if (cnt == 0) return 0;
            nz[i] = (int32_t)cnt;
            pos += cnt;
        }
        total = 1;
        for (i = 0; i < n_in; ++i) total *= nz[i];
        for (combo = 0; combo < total; ++combo) {
            long rem = combo, cell = 0, ce, st;
            pos = n_in;
            acc = FS_R(1.0);
            for (i = 0; i < n_in; ++i) {
                /* numba: % and // of non-negative integers, as C's */
                long d = rem % nz[i], tl;
                rem /= nz[i];
                tl = nz[pos + d];
                pos += nz[i];
                cell += ints[gt + 1 + i] * tl;
                v = mu[ints[vt + 2 * i] + tl];
                if (and_op == 0) {
                    if (v < acc) acc = v;
                } else {
                    acc *= v;
                }
            }
            ce = gt + 1 + n_in + 2 * cell;
            st = gt + ints[ce];
            for (q = 0; q < ints[ce + 1]; ++q) {
                fs_real wr;
                r = ints[st + q];
                wr = acc * f[fw + r];
                if (wr > FS_R(0.0)) {
                    w[r] = wr;
                    fired[nf] = (int32_t)r;
                    nf += 1;
                }
            }
        }
        return nf;
    }
    pv = ints[FS_H_PIVOT];
    if (pv >= 0) {
        /* flat AND with a pivot input named by every rule: its non-zero terms' rules only */
        long fo = ints[FS_H_FLATOFF], p = ints[pv], first_p = ints[vt + 2 * p], tl;
        for (tl = 0; tl < ints[pv + 1]; ++tl) {
            long st;
            if (mu[first_p + tl] <= FS_R(0.0)) continue;
            st = pv + ints[pv + 2 + 2 * tl];
            for (q = 0; q < ints[pv + 3 + 2 * tl]; ++q) {
                long row;
                r = ints[st + q];
                row = fo + 2 * n_in * r;
                acc = FS_R(1.0);
                for (i = 0; i < n_in; ++i) {
                    t = ints[row + i];
                    if (t < 0) continue;
                    v = mu[t];
                    if (ints[row + n_in + i] != 0) v = FS_R(1.0) - v;
                    if (and_op == 0) {
                        if (v < acc) acc = v;
                    } else {
                        acc *= v;
                    }
                    if (acc <= FS_R(0.0)) break;
                }
                if (acc > FS_R(0.0)) {
                    acc *= f[fw + r];
                    if (acc > FS_R(0.0)) {
                        w[r] = acc;
                        fired[nf] = (int32_t)r;
                        nf += 1;
                    }
                }
            }
        }
        return nf;
    }
    if (flat != 0) {
        long fo = ints[FS_H_FLATOFF];
        for (r = 0; r < n_rules; ++r) {
            long row = fo + 2 * n_in * r;
            if (flat == 1) {
                acc = FS_R(1.0);
                for (i = 0; i < n_in; ++i) {
                    t = ints[row + i];
                    if (t < 0) continue;
                    v = mu[t];
                    if (ints[row + n_in + i] != 0) v = FS_R(1.0) - v;
                    if (and_op == 0) {
                        if (v < acc) acc = v;
                    } else {
                        acc *= v;
                    }
                    if (acc <= FS_R(0.0)) {
                        acc = FS_R(0.0);
                        break;
                    }
                }
            } else {
                acc = FS_R(0.0);
                for (i = 0; i < n_in; ++i) {
                    t = ints[row + i];
                    if (t < 0) continue;
                    v = mu[t];
                    if (ints[row + n_in + i] != 0) v = FS_R(1.0) - v;
                    if (or_op == 0) {
                        if (v > acc) acc = v;
                    } else {
                        acc = fs_probor(acc, v);
                    }
                }
            }
            w[r] = acc * f[fw + r];
            if (w[r] > FS_R(0.0)) {
                fired[nf] = (int32_t)r;
                nf += 1;
            }
        }
        return nf;
    }
    {
        long pg = ints[FS_H_PROG];
        for (r = 0; r < n_rules; ++r) {
            long start = pg + ints[rt + 4 * r], end = start + ints[rt + 4 * r + 1];
            long sp = 0, k = start;
            while (k < end) {
                long op = ints[k];
                if (op == FS_OP_IS) {
                    v = mu[ints[k + 2]];
                    if (ints[k + 3] != 0) v = FS_R(1.0) - v;
                    stk[sp] = v;
                    sp += 1;
                    k += 4;
                } else if (op == FS_OP_NOT) {
                    stk[sp - 1] = FS_R(1.0) - stk[sp - 1];
                    k += 1;
                } else {
                    long cnt = ints[k + 1], base = sp - cnt, j;
                    acc = stk[base];
                    for (j = base + 1; j < sp; ++j) {
                        v = stk[j];
                        if (op == FS_OP_AND) acc = and_op == 0 ? fs_min(acc, v) : acc * v;
                        else acc = or_op == 0 ? fs_max(acc, v) : fs_probor(acc, v);
                    }
                    stk[base] = acc;
                    sp = base + 1;
                    k += 2;
                }
            }
            w[r] = stk[0] * f[fw + r];
            if (w[r] > FS_R(0.0)) {
                fired[nf] = (int32_t)r;
                nf += 1;
            }
        }
    }
    return nf;
}

/* the items of output o that fired: (term lab, height h) pairs; their number. Max
 * aggregation: one per term (the largest strength naming it); else one per (rule,
 * consequent) */
FS_MAYBE_UNUSED static long fs_items(const int32_t *ints, const fs_real *w, const int32_t *fired,
                                     long nf, long o, fs_real *hts, int32_t *lab, fs_real *h) {
    long n_t = ints[ints[FS_H_OUTS] + FS_OUT_FIELDS * o + 5];
    long rt = ints[FS_H_RULES], ct = ints[FS_H_CONS], n = 0, j, q, c;
    if (ints[FS_H_AGG] == 0) {
        for (j = 0; j < n_t; ++j) hts[j] = FS_R(0.0);
        for (q = 0; q < nf; ++q) {
            long r = fired[q], c0 = ct + ints[rt + 4 * r + 2];
            for (c = 0; c < ints[rt + 4 * r + 3]; ++c) {
                if (ints[c0 + 2 * c] == o) {
                    j = ints[c0 + 2 * c + 1];
                    if (w[r] > hts[j]) hts[j] = w[r];
                }
            }
        }
        for (j = 0; j < n_t; ++j) {
            if (hts[j] > FS_R(0.0)) {
                lab[n] = (int32_t)j;
                h[n] = hts[j];
                n += 1;
            }
        }
        return n;
    }
    for (q = 0; q < nf; ++q) {
        long r = fired[q], c0 = ct + ints[rt + 4 * r + 2];
        for (c = 0; c < ints[rt + 4 * r + 3]; ++c) {
            if (ints[c0 + 2 * c] == o) {
                lab[n] = ints[c0 + 2 * c + 1];
                h[n] = w[r];
                n += 1;
            }
        }
    }
    return n;
}

/* ======================================================================================
 * piecewise-linear outputs, exact (general._pl_segments, _defuzz_segments)
 */

FS_MAYBE_UNUSED static long fs_insort(fs_real *buf, long n, fs_real y) {
    long i = n;
    while (i > 0 && buf[i - 1] > y) {
        buf[i] = buf[i - 1];
        i -= 1;
    }
    buf[i] = y;
    return n + 1;
}

/* (aggregate, unclamped sum) at y of the na lines c + m y clipped / scaled by hh */
FS_MAYBE_UNUSED static void fs_agg_lines(fs_real y, long na, const fs_real *c, const fs_real *m,
                                         const fs_real *hh, long impl, long agg, fs_real *agg_v,
                                         fs_real *tot_v) {
    fs_real best = FS_R(0.0), total = FS_R(0.0), line, fv;
    long i;
    for (i = 0; i < na; ++i) {
        line = c[i] + m[i] * y;
        if (line < FS_R(0.0)) line = FS_R(0.0);
        if (impl == 0 && FS_FABS(line - hh[i]) <= FS_TOL_CLIP * (FS_FABS(c[i]) + FS_FABS(m[i] * y)))
            line = hh[i];
        fv = impl == 0 ? fs_min(hh[i], line) : hh[i] * line;
        total += fv;
        if (fv > best) best = fv;
    }
    if (agg == 0) {
        *agg_v = best;
        *tot_v = best;
    } else if (agg == 1) {
        *agg_v = fs_min(FS_R(1.0), total);
        *tot_v = total;
    } else {
        *agg_v = total;
        *tot_v = total;
    }
}

FS_MAYBE_UNUSED static long fs_pl_segments(long n_items, const int32_t *lab, const fs_real *h,
                                           const fs_real *f, long bp_off, long k0, long k1,
                                           long s_off, long i_off, long n_t, long impl, long agg,
                                           fs_real *c, fs_real *m, fs_real *hh, fs_real *cand,
                                           fs_real *su, fs_real *sv, fs_real *gu, fs_real *gv) {
    long n_seg = 0, k, i, jj, na, nc, t;
    fs_real p, q, y, au, tu, av, tv, u, v;
    for (k = k0; k < k1 + 1; ++k) {
        p = f[bp_off + k];
        q = f[bp_off + k + 1];
        na = 0;
        for (i = 0; i < n_items; ++i) {
            long j = lab[i];
            fs_real mm = f[s_off + k * n_t + j], cc = f[i_off + k * n_t + j];
            if (mm == FS_R(0.0) && cc <= FS_R(0.0)) continue;
            c[na] = cc;
            m[na] = mm;
            hh[na] = h[i];
            na += 1;
        }
        if (na == 0) continue;
        cand[0] = p;
        cand[1] = q;
        nc = 2;
        for (i = 0; i < na; ++i) {
            if (m[i] != FS_R(0.0)) {
                y = -c[i] / m[i];
                if (p < y && y < q) nc = fs_insort(cand, nc, y);
                if (impl == 0) {
                    y = (hh[i] - c[i]) / m[i];
                    if (p < y && y < q) nc = fs_insort(cand, nc, y);
                }
            }
            if (agg == 0) {
                for (jj = 0; jj < na; ++jj) {
                    if (jj == i) continue;
                    if (impl == 0) {
                        if (m[i] != FS_R(0.0)) {
                            y = (hh[jj] - c[i]) / m[i];
                            if (p < y && y < q) nc = fs_insort(cand, nc, y);
                        }
                        if (jj > i && m[i] != m[jj]) {
                            y = (c[jj] - c[i]) / (m[i] - m[jj]);
                            if (p < y && y < q) nc = fs_insort(cand, nc, y);
                        }
                    } else if (jj > i) {
                        fs_real di = hh[i] * m[i] - hh[jj] * m[jj];
                        if (di != FS_R(0.0)) {
                            y = (hh[jj] * c[jj] - hh[i] * c[i]) / di;
                            if (p < y && y < q) nc = fs_insort(cand, nc, y);
                        }
                    }
                }
            }
        }
        fs_agg_lines(cand[0], na, c, m, hh, impl, agg, &au, &tu);
        for (t = 0; t < nc - 1; ++t) {
            u = cand[t];
            v = cand[t + 1];
            if (v <= u) continue;
            fs_agg_lines(v, na, c, m, hh, impl, agg, &av, &tv);
            if (au == FS_R(0.0) && av == FS_R(0.0)) {
                au = av;
                tu = tv;
                continue;
            }
            if (agg == 1 && (tu - FS_R(1.0)) * (tv - FS_R(1.0)) < FS_R(0.0)) {
                fs_real ys = u + (FS_R(1.0) - tu) * (v - u) / (tv - tu);
                su[n_seg] = u;
                sv[n_seg] = ys;
                gu[n_seg] = au;
                gv[n_seg] = FS_R(1.0);
                n_seg += 1;
                su[n_seg] = ys;
                sv[n_seg] = v;
                gu[n_seg] = FS_R(1.0);
                gv[n_seg] = av;
                n_seg += 1;
            } else {
                su[n_seg] = u;
                sv[n_seg] = v;
                gu[n_seg] = au;
                gv[n_seg] = av;
                n_seg += 1;
            }
            au = av;
            tu = tv;
        }
    }
    return n_seg;
}

/* centroid (0), bisector (1), mean (2), smallest (3) or largest (4) of maximum of a
 * piecewise-linear function given by its pieces and by n_pt isolated points (px, pv: the
 * zero-width terms, no area, read by the maxima only); NaN for zero area (centroid,
 * bisector) or a zero maximum (general._defuzz_segments) */
FS_MAYBE_UNUSED static fs_real fs_defuzz_segments(long n_seg, const fs_real *su, const fs_real *sv,
                                                  const fs_real *gu, const fs_real *gv, long mode,
                                                  const fs_real *px, const fs_real *pv,
                                                  long n_pt) {
    fs_real area = FS_R(0.0), moment = FS_R(0.0), gmax = FS_R(0.0), gpt = FS_R(0.0), ref, span,
            u, v, tol, best;
    long s, i, j;
    ref = n_seg > 0 ? su[0] : FS_R(0.0);
    span = n_seg > 0 ? sv[n_seg - 1] - ref : FS_R(1.0);
    if (!(span > FS_R(0.0))) span = FS_R(1.0);
    for (s = 0; s < n_seg; ++s) {
        u = (su[s] - ref) / span;
        v = (sv[s] - ref) / span;
        moment += (v - u) * (u * (FS_R(2.0) * gu[s] + gv[s]) + v * (gu[s] + FS_R(2.0) * gv[s])) /
                  FS_R(6.0);
        area += FS_R(0.5) * (sv[s] - su[s]) * (gu[s] + gv[s]);
        gmax = fs_max(fs_max(gmax, gu[s]), gv[s]);
    }
    for (i = 0; i < n_pt; ++i) gpt = fs_max(gpt, pv[i]);
    if (!(area > FS_R(0.0)) && (mode <= 1 || !(gpt > FS_R(0.0)))) return FS_NAN;
    if (mode == 0) return ref + span * (moment * span) / area;
    if (mode == 1) {
        fs_real sc = FS_R(1.0) / gmax, half = FS_R(0.5) * area * sc, acc = FS_R(0.0);
        for (s = 0; s < n_seg; ++s) {
            fs_real a = gu[s] * sc, b = gv[s] * sc, seg;
            u = su[s];
            v = sv[s];
            seg = FS_R(0.5) * (v - u) * (a + b);
            if (acc + seg >= half && seg > FS_R(0.0)) {
                fs_real need = half - acc, length = v - u, sl, disc, t_root;
                sl = (b - a) / length;
                if (FS_FABS(sl) * length <= FS_TOL_FLAT * fs_max(a, b))
                    return u + need / (FS_R(0.5) * (a + b));
                disc = a * a + FS_R(2.0) * sl * need;
                t_root = FS_R(2.0) * need / (a + FS_SQRT(fs_max(disc, FS_R(0.0))));
                return u + fs_min(fs_max(t_root, FS_R(0.0)), length);
            }
            acc += seg;
        }
        return sv[n_seg - 1];
    }
    /* the maximum over the pieces and the points (gmax itself without zero-width terms) */
    gmax = fs_max(gmax, gpt);
    tol = FS_TOL_TIE * gmax;
    if (mode == 2) {
        fs_real plen = FS_R(0.0), pmom = FS_R(0.0), minlen, tot = FS_R(0.0), last = -FS_INF;
        long cnt = 0;
        minlen = n_seg > 0 ? FS_TOL_MINLEN * (sv[n_seg - 1] - su[0]) : FS_R(0.0);
        for (s = 0; s < n_seg; ++s) {
            if (gu[s] >= gmax - tol && gv[s] >= gmax - tol && sv[s] - su[s] > minlen) {
                plen += sv[s] - su[s];
                pmom += FS_R(0.5) * (sv[s] - su[s]) * (sv[s] + su[s]);
            }
        }
        if (plen > FS_R(0.0)) return pmom / plen;
        for (s = 0; s < n_seg; ++s) {
            if (gu[s] >= gmax - tol && su[s] > last + minlen) {
                cnt += 1;
                tot += su[s];
                last = su[s];
            }
            if (gv[s] >= gmax - tol && sv[s] > last + minlen) {
                cnt += 1;
                tot += sv[s];
                last = sv[s];
            }
        }
        /* the maximising points of zero width, each place once (a piece's end there is one) */
        for (i = 0; i < n_pt; ++i) {
            int seen = 0;
            if (pv[i] < gmax - tol) continue;
            for (j = 0; j < i; ++j)
                if (pv[j] >= gmax - tol && px[j] == px[i]) seen = 1;
            for (s = 0; s < n_seg; ++s)
                if ((gu[s] >= gmax - tol && FS_FABS(su[s] - px[i]) <= minlen) ||
                    (gv[s] >= gmax - tol && FS_FABS(sv[s] - px[i]) <= minlen))
                    seen = 1;
            if (!seen) {
                cnt += 1;
                tot += px[i];
            }
        }
        return tot / FS_R(cnt);
    }
    best = FS_NAN;
    if (mode == 3) {
        for (s = 0; s < n_seg; ++s) {
            if (gu[s] >= gmax - tol) {
                best = su[s];
                break;
            }
            if (gv[s] >= gmax - tol) {
                best = sv[s];
                break;
            }
        }
        for (i = 0; i < n_pt; ++i)
            if (pv[i] >= gmax - tol && !(px[i] >= best)) best = px[i];
        return best;
    }
    for (s = n_seg - 1; s > -1; --s) {
        if (gv[s] >= gmax - tol) {
            best = sv[s];
            break;
        }
        if (gu[s] >= gmax - tol) {
            best = su[s];
            break;
        }
    }
    for (i = 0; i < n_pt; ++i)
        if (pv[i] >= gmax - tol && !(px[i] <= best)) best = px[i];
    return best;
}

/* ======================================================================================
 * singleton outputs (general._singletons)
 */

FS_MAYBE_UNUSED static fs_real fs_singletons(const int32_t *ints, const fs_real *f, long o,
                                             long n_items, const int32_t *lab, const fs_real *h,
                                             fs_real *hts, long mode) {
    long n_t = ints[ints[FS_H_OUTS] + FS_OUT_FIELDS * o + 5], agg = ints[FS_H_AGG];
    long impl = ints[FS_H_IMPL], tt = ints[FS_H_TERMS];
    long first = ints[ints[FS_H_VARS] + 2 * (ints[FS_H_NIN] + o)], i, j, jj, cnt = 0;
    fs_real num = FS_R(0.0), den = FS_R(0.0), gmax = FS_R(0.0), best_lo = FS_INF;
    fs_real best_hi = -FS_INF, tot = FS_R(0.0), x;
    for (j = 0; j < n_t; ++j) hts[j] = FS_R(0.0);
    for (i = 0; i < n_items; ++i) {
        long off;
        fs_real v;
        j = lab[i];
        off = ints[tt + 3 * (first + j) + 1];
        v = impl == 0 ? fs_min(h[i], f[off + 1]) : h[i] * f[off + 1];
        if (agg == 0) hts[j] = fs_max(hts[j], v);
        else if (agg == 1) hts[j] = fs_min(FS_R(1.0), hts[j] + v);
        else if (agg == 2) hts[j] += v;
        else hts[j] = fs_probor(hts[j], v);
    }
    for (j = 0; j < n_t; ++j) {
        long off = ints[tt + 3 * (first + j) + 1];
        num += hts[j] * f[off];
        den += hts[j];
        gmax = fs_max(gmax, hts[j]);
    }
    if (!(den > FS_R(0.0))) return FS_NAN;
    if (mode == 0) return num / den;
    for (j = 0; j < n_t; ++j) {
        if (hts[j] >= gmax * (FS_R(1.0) - FS_TOL_TIE) && hts[j] > FS_R(0.0)) {
            int seen = 0;
            x = f[ints[tt + 3 * (first + j) + 1]];
            best_lo = fs_min(best_lo, x);
            best_hi = fs_max(best_hi, x);
            for (jj = 0; jj < j; ++jj) {
                if (hts[jj] >= gmax * (FS_R(1.0) - FS_TOL_TIE) && hts[jj] > FS_R(0.0) &&
                    f[ints[tt + 3 * (first + jj) + 1]] == x) {
                    seen = 1;
                    break;
                }
            }
            if (!seen) {
                tot += x;
                cnt += 1;
            }
        }
    }
    if (mode == 2) return tot / FS_R(cnt);
    return mode == 3 ? best_lo : best_hi;
}

/* ======================================================================================
 * smooth outputs: pieces located, adaptive Gauss-Kronrod (general._smooth and helpers)
 *
 * Memory: the Python code keeps a record of the accepted subintervals (for the bisector) and
 * of the maxima's candidate points; here both are recomputed by a second identical pass
 * instead (same subintervals in the same order, same candidates: same result, bounded
 * scratch). Only the knots and the cuts are stored.
 */

/* the smooth path's context: output's first term, its fired items */
typedef struct {
    const int32_t *ints;
    const fs_real *f;
    long first, n_items, tt, impl, agg;
    const int32_t *lab;
    const fs_real *h;
} fs_smooth_ctx;

/* the context of output o's fired items */
FS_MAYBE_UNUSED static void fs_ctx_init(fs_smooth_ctx *cx, const int32_t *ints, const fs_real *f,
                                        long o, long n_items, const int32_t *lab,
                                        const fs_real *h) {
    cx->ints = ints;
    cx->f = f;
    cx->tt = ints[FS_H_TERMS];
    cx->impl = ints[FS_H_IMPL];
    cx->agg = ints[FS_H_AGG];
    cx->first = ints[ints[FS_H_VARS] + 2 * (ints[FS_H_NIN] + o)];
    cx->n_items = n_items;
    cx->lab = lab;
    cx->h = h;
}

/* the aggregate at y */
FS_MAYBE_UNUSED static fs_real fs_g(fs_real y, const fs_smooth_ctx *cx) {
    fs_real acc = FS_R(0.0), mu, v;
    long i;
    for (i = 0; i < cx->n_items; ++i) {
        long t = cx->first + cx->lab[i];
        mu = fs_mf(cx->ints[cx->tt + 3 * t], cx->f, cx->ints[cx->tt + 3 * t + 1],
                   cx->ints[cx->tt + 3 * t + 2], y);
        v = cx->impl == 0 ? fs_min(cx->h[i], mu) : cx->h[i] * mu;
        if (cx->agg == 0) {
            if (v > acc) acc = v;
        } else if (cx->agg == 3) {
            acc = fs_probor(acc, v);
        } else {
            acc += v;
        }
    }
    if (cx->agg == 1 && acc > FS_R(1.0)) acc = FS_R(1.0);
    return acc;
}

/* where a zero-width term sits (triangle a = c, trapezoid a = d), NaN for any other term
 * (general._point_x) */
FS_MAYBE_UNUSED static fs_real fs_point_x(long code, const fs_real *f, long off) {
    if (code == FS_TRI && f[off] == f[off + 2]) return f[off];
    if (code == FS_TRAP && f[off] == f[off + 3]) return f[off];
    return FS_NAN;
}

/* the zero-width items of output o inside its range: their places (px) and the aggregate
 * there (pv); their number (general._pl_points) */
FS_MAYBE_UNUSED static long fs_pl_points(const int32_t *ints, const fs_real *f, long o,
                                         long n_items, const int32_t *lab, const fs_real *h,
                                         fs_real *px, fs_real *pv) {
    long n_in = ints[FS_H_NIN], fv = ints[FS_H_FVARS] + 4 * (n_in + o), i, n = 0;
    fs_smooth_ctx cx;
    fs_ctx_init(&cx, ints, f, o, n_items, lab, h);
    for (i = 0; i < n_items; ++i) {
        long t = cx.first + lab[i];
        fs_real x0 = fs_point_x(ints[cx.tt + 3 * t], f, ints[cx.tt + 3 * t + 1]);
        if (x0 == x0 && f[fv] <= x0 && x0 <= f[fv + 1]) {
            px[n] = x0;
            pv[n] = fs_g(x0, &cx);
            n += 1;
        }
    }
    return n;
}

/* which smooth piece y lies on. numba: the key is int64 arithmetic that wraps on overflow;
 * unsigned 64-bit arithmetic wraps the same way (signed overflow would be undefined in C),
 * and keys are only compared for equality */
FS_MAYBE_UNUSED static uint64_t fs_signature(fs_real y, const fs_smooth_ctx *cx) {
    uint64_t key = 0;
    fs_real best = FS_R(-1.0), total = FS_R(0.0), mu, v;
    long arg = 0, i;
    for (i = 0; i < cx->n_items; ++i) {
        long t = cx->first + cx->lab[i];
        long code = cx->ints[cx->tt + 3 * t], off = cx->ints[cx->tt + 3 * t + 1];
        int clipped, bend;
        mu = fs_mf(code, cx->f, off, cx->ints[cx->tt + 3 * t + 2], y);
        clipped = cx->impl == 0 && mu > cx->h[i];
        v = cx->impl == 0 ? fs_min(cx->h[i], mu) : cx->h[i] * mu;
        total += v;
        if (v > best) {
            best = v;
            arg = i;
        }
        bend = code == FS_DSIG && fs_sigmoid(y, cx->f[off], cx->f[off + 1]) >=
                                      fs_sigmoid(y, cx->f[off + 3], cx->f[off + 2]);
        key = key * 1000003u + (uint64_t)(clipped ? 1 : 0) + (uint64_t)(mu > FS_R(0.0) ? 2 : 0) +
              (uint64_t)(bend ? 4 : 0);
    }
    if (cx->agg == 0) key = key * 1000003u + (uint64_t)arg;
    else if (cx->agg == 1) key = key * 1000003u + (uint64_t)(total >= FS_R(1.0) ? 1 : 0);
    return key;
}

/* add to buf the points inside (lo, hi) where a term is not smooth or peaks */
FS_MAYBE_UNUSED static long fs_knots(long code, const fs_real *f, long off, long n, fs_real lo,
                                     fs_real hi, fs_real *buf, long k) {
    long cnt = n, i;
    fs_real x;
    if (code == FS_DISC) {
        for (i = 0; i < n / 2; ++i) {
            x = f[off + 2 * i];
            if (lo < x && x < hi) buf[k++] = x;
        }
        return k;
    }
    if (code == FS_BELL || code == FS_GAUSS || code == FS_SING) cnt = 1;
    else if (code == FS_SIG) cnt = 1;
    for (i = 0; i < cnt; ++i) {
        x = f[off + i];
        if (code == FS_GAUSS2 && i % 2 == 1) continue;
        if ((code == FS_DSIG || code == FS_PSIG) && (i == 1 || i == 2)) continue;
        if (code == FS_SIG && i == 1) continue;
        if (lo < x && x < hi) buf[k++] = x;
    }
    if (code == FS_SMF || code == FS_ZMF || code == FS_PIMF) {
        for (i = 0; i < n; i += 2) {
            x = FS_R(0.5) * (f[off + i] + f[off + i + 1]);
            if (lo < x && x < hi) buf[k++] = x;
        }
    }
    return k;
}

/* (K15 area, G7 area, K15 moment, G7 moment) of g and (y - c0) g on [a, b]; the moments only
 * when km is not NULL (they do not enter the areas) */
FS_MAYBE_UNUSED static void fs_gk(fs_real a, fs_real b, fs_real c0, const fs_smooth_ctx *cx,
                                  fs_real *ka_out, fs_real *ga_out, fs_real *km_out,
                                  fs_real *gm_out) {
    fs_real hl = FS_R(0.5) * (b - a), cen = FS_R(0.5) * (a + b), gc, ka, ga, inv, km, gm;
    long j;
    gc = fs_g(cen, cx);
    ka = fs_wgk[7] * gc;
    ga = fs_wg[3] * gc;
    inv = FS_R(1.0) / (b - a);
    km = fs_wgk[7] * gc * (cen - c0) * inv;
    gm = fs_wg[3] * gc * (cen - c0) * inv;
    for (j = 0; j < 7; ++j) {
        fs_real dx = hl * fs_xgk[j], y1 = cen - dx, y2 = cen + dx, g1, g2;
        g1 = fs_g(y1, cx);
        g2 = fs_g(y2, cx);
        ka += fs_wgk[j] * (g1 + g2);
        if (km_out) km += fs_wgk[j] * (g1 * (y1 - c0) + g2 * (y2 - c0)) * inv;
        if (j % 2 == 1) {
            ga += fs_wg[j / 2] * (g1 + g2);
            if (km_out) gm += fs_wg[j / 2] * (g1 * (y1 - c0) + g2 * (y2 - c0)) * inv;
        }
    }
    *ka_out = ka * hl;
    if (ga_out) *ga_out = ga * hl;
    if (km_out) *km_out = km * hl;
    if (gm_out) *gm_out = gm * hl;
}

/* golden-section search for the maximum of the aggregate on [a, b] */
FS_MAYBE_UNUSED static fs_real fs_golden_max(fs_real a, fs_real b, fs_real span,
                                             const fs_smooth_ctx *cx) {
    fs_real invphi = (FS_SQRT(FS_R(5.0)) - FS_R(1.0)) / FS_R(2.0);
    fs_real x1 = b - invphi * (b - a), x2 = a + invphi * (b - a), f1, f2, aa = a, bb = b;
    int it;
    f1 = fs_g(x1, cx);
    f2 = fs_g(x2, cx);
    for (it = 0; it < 200; ++it) {
        if (bb - aa <= FS_TOL_GOLDEN * span) break;
        if (f1 < f2) {
            aa = x1;
            x1 = x2;
            f1 = f2;
            x2 = aa + invphi * (bb - aa);
            f2 = fs_g(x2, cx);
        } else {
            bb = x2;
            x2 = x1;
            f2 = f1;
            x1 = bb - invphi * (bb - aa);
            f1 = fs_g(x1, cx);
        }
    }
    return FS_R(0.5) * (aa + bb);
}

/* Newton steps from x on the Richardson-extrapolated central difference of step d (d2 < 0
 * held fixed); returns whether they converged, the root in *root */
FS_MAYBE_UNUSED static int fs_newton_max(fs_real x, fs_real d, fs_real d2, const fs_smooth_ctx *cx,
                                         fs_real *root) {
    fs_real xn = x, g1, g2, step;
    int it;
    for (it = 0; it < 8; ++it) {
        g1 = (fs_g(xn + d, cx) - fs_g(xn - d, cx)) / (FS_R(2.0) * d);
        g2 = (fs_g(xn + FS_R(0.5) * d, cx) - fs_g(xn - FS_R(0.5) * d, cx)) / d;
        step = -((FS_R(4.0) * g2 - g1) / FS_R(3.0)) / d2;
        xn += step;
        if (FS_FABS(step) <= FS_R(1e-3) * d) {
            *root = xn;
            return 1;
        }
    }
    *root = xn;
    return 0;
}

/* Newton steps on the derivative from a maximum x found in [a, b] by comparing values; x is
 * kept at a kink, a plateau, a flat top or when a step lowers the value */
FS_MAYBE_UNUSED static fs_real fs_refine_max(fs_real x, fs_real a, fs_real b, fs_real span,
                                             const fs_smooth_ctx *cx) {
    fs_real gx = fs_g(x, cx), d, d2 = FS_R(0.0), d2h, tol_x, xn, x2;
    int quadratic = 0, it, conv, conv2;
    if (!(gx > FS_R(0.0))) return x;
    d = FS_R(0.25) * (b - a);
    for (it = 0; it < 12; ++it) {
        d2 = (fs_g(x + d, cx) - FS_R(2.0) * gx + fs_g(x - d, cx)) / (d * d);
        d2h = (fs_g(x + FS_R(0.5) * d, cx) - FS_R(2.0) * gx + fs_g(x - FS_R(0.5) * d, cx)) /
              (FS_R(0.25) * d * d);
        if (!(d2 < FS_R(0.0) && d2h < FS_R(0.0)) ||
            FS_TOL_D2 * gx / (FS_R(0.25) * d * d) > FS_D2_SHARE * -d2h)
            return x;
        if (FS_FABS(d2h - d2) <= FS_R(1e-2) * -d2) {
            quadratic = 1;
            break;
        }
        d *= FS_R(0.1);
    }
    if (!quadratic) return x;
    tol_x = FS_TOL_X * span;
    for (;;) {
        if (FS_TOL_ROOT * gx / (d * -d2) > tol_x) return x;
        conv = fs_newton_max(x, d, d2, cx, &xn);
        conv2 = fs_newton_max(x, FS_R(2.0) * d, d2, cx, &x2);
        if (!(conv && conv2)) return x;
        if (FS_FABS(xn - x2) <= FS_R(15.0) * tol_x) break;
        d *= FS_R(0.1);
    }
    xn = fs_min(fs_max(xn, a), b);
    if (fs_g(xn, cx) < gx - FS_TOL_DROP * gx) return x;
    return xn;
}

/* One adaptive Gauss-Kronrod traversal of the pieces (the Python loop, in its order). With
 * find == 0: the area and the moment (in units of the span). With find == 1: the bisector,
 * the point where the accepted subintervals' areas, summed in that order, reach `half`
 * (returns 1 and the point in *res; 0 if not reached). */
FS_MAYBE_UNUSED static int fs_quad(const fs_real *cuts, long nc, fs_real a0, fs_real span,
                                   fs_real c0, const fs_smooth_ctx *cx, fs_real *stack_a,
                                   fs_real *stack_b, int find, fs_real half, fs_real *area,
                                   fs_real *mom, fs_real *res) {
    long cap = FS_QUAD_MAX_SUB * (nc + 1), n_acc = 0, k, sp;
    fs_real cum = FS_R(0.0), a, b, ka, ga, km, gm, tol, mid;
    int ok;
    *area = FS_R(0.0);
    *mom = FS_R(0.0);
    for (k = 0; k < nc - 1; ++k) {
        if (!(cuts[k + 1] > cuts[k])) continue;
        stack_a[0] = cuts[k];
        stack_b[0] = cuts[k + 1];
        sp = 1;
        while (sp > 0) {
            sp -= 1;
            a = stack_a[sp];
            b = stack_b[sp];
            fs_gk(a, b, c0, cx, &ka, &ga, &km, &gm);
            tol = FS_QUAD_RTOL * a0 * (b - a) / span;
            ok = FS_FABS(ka - ga) <= tol && FS_FABS(km - gm) <= FS_QUAD_RTOL * a0;
            mid = FS_R(0.5) * (a + b);
            if (ok || sp >= FS_QUAD_STACK - 2 || n_acc >= cap || !(a < mid && mid < b)) {
                *area += ka;
                *mom += km * ((b - a) / span);
                n_acc += 1;
                if (find) {
                    if (cum + ka >= half) {
                        /* solve int_a^t g = need on [a, b] by bisection on K15 partial
                         * integrals */
                        fs_real need = half - cum, ta = a, tb = b, tm, pa;
                        int it;
                        for (it = 0; it < 80; ++it) {
                            tm = FS_R(0.5) * (ta + tb);
                            if (tm <= ta || tm >= tb) break;
                            fs_gk(a, tm, c0, cx, &pa, NULL, NULL, NULL);
                            if (pa < need) ta = tm;
                            else tb = tm;
                        }
                        *res = FS_R(0.5) * (ta + tb);
                        return 1;
                    }
                    cum += ka;
                }
            } else {
                stack_a[sp] = mid;
                stack_b[sp] = b;
                stack_a[sp + 1] = a;
                stack_b[sp + 1] = mid;
                sp += 2;
            }
        }
    }
    return 0;
}

/* the maxima's candidates of one pass (see fs_smooth): pass 0 finds their largest value
 * *gmax; pass 1 gathers those within tolm of it */
typedef struct {
    int pass;
    fs_real gmax, tolm, lo_pt, hi_pt, tot;
    long cnt;
} fs_cands;

FS_MAYBE_UNUSED static void fs_cand(fs_cands *cs, fs_real x, fs_real v) {
    if (cs->pass == 0) {
        cs->gmax = fs_max(cs->gmax, v);
    } else if (v >= cs->gmax - cs->tolm) {
        cs->lo_pt = fs_min(cs->lo_pt, x);
        cs->hi_pt = fs_max(cs->hi_pt, x);
        cs->tot += x;
        cs->cnt += 1;
    }
}

/* the defuzzified smooth aggregate of output o (NaN if empty). Scratch `scr` (NULL only
 * for a system without smooth outputs, which never calls this): the two
 * quadrature stacks, the scan's abscissae and values, the knots (2 + the fired items'
 * parameter counts + 4 each, as the Python allocates) and the cuts (fuzzyservo.export.
 * fuzzy_c.scratch_sizes bounds the total) */
FS_MAYBE_UNUSED static fs_real fs_smooth(const int32_t *ints, const fs_real *f, long o,
                                         long n_items, const int32_t *lab, const fs_real *h,
                                         long mode, fs_real *scr) {
    long n_in = ints[FS_H_NIN], fv = ints[FS_H_FVARS] + 4 * (n_in + o), nk_max = 2, nk, i, k;
    long nc = 0, s, it, cc;
    fs_real lo = f[fv], hi = f[fv + 1], *knots, *cuts, *stack_a, *stack_b, *ys, *gs;
    fs_real c0, a0 = FS_R(0.0), span, area, mom, res, a, b, p, q, dy, ya, yb;
    uint64_t sa, sb, sc;
    fs_smooth_ctx cx;
    fs_cands cs;
    if (!scr) return FS_NAN; /* the caller has no smooth scratch: the system has no such output */
    fs_ctx_init(&cx, ints, f, o, n_items, lab, h);
    /* knots of the fired terms */
    for (i = 0; i < n_items; ++i) nk_max += ints[cx.tt + 3 * (cx.first + lab[i]) + 2] + 4;
    stack_a = scr;
    stack_b = stack_a + FS_QUAD_STACK;
    ys = stack_b + FS_QUAD_STACK;
    gs = ys + (FS_SCAN_CELLS + 1);
    knots = gs + (FS_SCAN_CELLS + 1);
    /* the cuts last: at most 257 per distinct knot (equal knots bound no piece), so their
     * scratch is bounded by the output's distinct terms, not by the fired items */
    cuts = knots + nk_max;
    knots[0] = lo;
    knots[1] = hi;
    nk = 2;
    for (i = 0; i < n_items; ++i) {
        long t = cx.first + lab[i];
        nk = fs_knots(ints[cx.tt + 3 * t], f, ints[cx.tt + 3 * t + 1], ints[cx.tt + 3 * t + 2],
                      lo, hi, knots, nk);
    }
    /* numba: np.sort; a stable insertion sort gives the same array (equal values are
     * interchangeable; only 0.0 and -0.0 could trade places, which changes no result) */
    for (i = 1; i < nk; ++i) {
        fs_real v = knots[i];
        long j = i;
        while (j > 0 && v < knots[j - 1]) {
            knots[j] = knots[j - 1];
            j -= 1;
        }
        knots[j] = v;
    }
    /* pieces: the knots, and the points where the signature changes on a scan (bisected) */
    for (k = 0; k < nk - 1; ++k) {
        p = knots[k];
        q = knots[k + 1];
        if (!(q > p)) continue;
        cuts[nc++] = p;
        dy = (q - p) / FS_R(FS_SCAN_CELLS);
        ya = p + FS_R(0.5) * dy * FS_SCAN_INSET;
        sa = fs_signature(ya, &cx);
        for (s = 1; s < FS_SCAN_CELLS + 1; ++s) {
            fs_real yc = ya;
            yb = s < FS_SCAN_CELLS ? p + FS_R(s) * dy : q - FS_R(0.5) * dy * FS_SCAN_INSET;
            sb = fs_signature(yb, &cx);
            sc = sa;
            for (cc = 0; cc < FS_CELL_CHANGES; ++cc) {
                if (sb == sc) break;
                a = yc;
                b = yb;
                for (it = 0; it < 200; ++it) {
                    fs_real mid = FS_R(0.5) * (a + b);
                    if (mid <= a || mid >= b) break;
                    if (fs_signature(mid, &cx) == sc) a = mid;
                    else b = mid;
                }
                cuts[nc++] = FS_R(0.5) * (a + b);
                yc = b;
                sc = fs_signature(yc, &cx);
            }
            ya = yb;
            sa = sb;
        }
    }
    cuts[nc++] = knots[nk - 1];
    c0 = FS_R(0.5) * (lo + hi);
    /* first pass: K15 on every piece for the scale of the area */
    for (k = 0; k < nc - 1; ++k) {
        if (cuts[k + 1] > cuts[k]) {
            fs_real ka;
            fs_gk(cuts[k], cuts[k + 1], c0, &cx, &ka, NULL, NULL, NULL);
            a0 += FS_FABS(ka);
        }
    }
    if (!(a0 > FS_R(0.0))) {
        /* no area: no centroid or bisector; the maxima are the fired zero-width terms'
         * points (none fired: NaN). The knots are done with: their nk_max >= 2 + 4 n_items
         * places hold the points (px) and the aggregate there (pv) */
        long n_pt;
        if (mode <= 1) return FS_NAN;
        n_pt = fs_pl_points(ints, f, o, n_items, lab, h, knots, knots + n_items);
        return fs_defuzz_segments(0, knots, knots, knots + n_items, knots + n_items, mode, knots,
                                  knots + n_items, n_pt);
    }
    span = hi - lo;
    fs_quad(cuts, nc, a0, span, c0, &cx, stack_a, stack_b, 0, FS_R(0.0), &area, &mom, &res);
    if (!(area > FS_R(0.0))) return FS_NAN;
    if (mode == 0) return c0 + span * (mom / area);
    if (mode == 1) {
        /* the Python code replays its record of accepted subintervals; the second traversal
         * accepts the same ones in the same order */
        if (fs_quad(cuts, nc, a0, span, c0, &cx, stack_a, stack_b, 1, FS_R(0.5) * area, &area,
                    &mom, &res))
            return res;
        return hi;
    }
    /* maxima: the cut points, and in every piece each local maximum of a scan of SCAN_CELLS
     * cells, located by golden section and refined to the zero of the derivative. The
     * Python code stores every candidate; here pass 0 finds the largest value and pass 1
     * recomputes the same candidates and gathers those within the tolerance of it */
    cs.gmax = FS_R(0.0);
    cs.tolm = FS_R(0.0);
    cs.lo_pt = FS_INF;
    cs.hi_pt = -FS_INF;
    cs.tot = FS_R(0.0);
    cs.cnt = 0;
    {
        fs_real plen = FS_R(0.0), pmom = FS_R(0.0), pmin = FS_INF, pmax = -FS_INF;
        for (cs.pass = 0; cs.pass < 2; ++cs.pass) {
            if (cs.pass == 1) {
                fs_real gmax = cs.gmax;
                cs.tolm = FS_TOL_SMAX * gmax;
                /* plateaus: pieces where g stays at gmax (both ends and the middle) */
                for (k = 0; k < nc - 1; ++k) {
                    a = cuts[k];
                    b = cuts[k + 1];
                    if (!(b > a)) continue;
                    if (fs_g(a, &cx) >= gmax - cs.tolm && fs_g(b, &cx) >= gmax - cs.tolm &&
                        fs_g(FS_R(0.5) * (a + b), &cx) >= gmax - cs.tolm) {
                        plen += b - a;
                        pmom += FS_R(0.5) * (b - a) * (a + b);
                        pmin = fs_min(pmin, a);
                        pmax = fs_max(pmax, b);
                    }
                }
            }
            for (k = 0; k < nc - 1; ++k) {
                a = cuts[k];
                b = cuts[k + 1];
                if (!(b > a)) continue;
                for (s = 0; s < FS_SCAN_CELLS + 1; ++s) {
                    ys[s] = s < FS_SCAN_CELLS ? a + (b - a) * FS_R(s) / FS_R(FS_SCAN_CELLS) : b;
                    gs[s] = fs_g(ys[s], &cx);
                }
                fs_cand(&cs, ys[0], gs[0]);
                fs_cand(&cs, ys[FS_SCAN_CELLS], gs[FS_SCAN_CELLS]);
                for (s = 0; s < FS_SCAN_CELLS + 1; ++s) {
                    fs_real left = s > 0 ? gs[s - 1] : FS_R(-1.0);
                    fs_real right = s < FS_SCAN_CELLS ? gs[s + 1] : FS_R(-1.0);
                    fs_real aa, bb, xm, xr;
                    if (gs[s] < left || gs[s] < right || (left == gs[s] && gs[s] == right))
                        continue;
                    aa = ys[fs_imax(s - 1, 0)];
                    bb = ys[fs_imin(s + 1, FS_SCAN_CELLS)];
                    xm = fs_golden_max(aa, bb, span, &cx);
                    xr = fs_refine_max(xm, aa, bb, span, &cx);
                    if (xr == xm) {
                        /* not a smooth maximum: exact only at a cut */
                        fs_real gx = fs_g(xm, &cx);
                        if (s <= 1 && gs[0] >= gx - FS_TOL_SMAX * gx) xr = a;
                        else if (s >= FS_SCAN_CELLS - 1 &&
                                 gs[FS_SCAN_CELLS] >= gx - FS_TOL_SMAX * gx)
                            xr = b;
                    }
                    xm = xr;
                    fs_cand(&cs, xm, fs_g(xm, &cx));
                }
            }
        }
        /* numba: tot / cnt (cnt >= 1: the largest candidate counts) */
        if (mode == 2) return plen > FS_R(0.0) ? pmom / plen : cs.tot / FS_R(cs.cnt);
        if (mode == 3) return fs_min(pmin, cs.lo_pt);
        return fs_max(pmax, cs.hi_pt);
    }
}

/* ======================================================================================
 * the partition fast path (fuzzy/partition.py)
 */

FS_MAYBE_UNUSED static fs_real fs_g2(fs_real y, fs_real m1, fs_real c1, fs_real a, fs_real m2,
                                     fs_real c2, fs_real b, long impl) {
    fs_real f1 = c1 + m1 * y, f2 = c2 + m2 * y;
    if (f1 < FS_R(0.0)) f1 = FS_R(0.0);
    if (f2 < FS_R(0.0)) f2 = FS_R(0.0);
    if (impl == 0) {
        if (FS_FABS(f1 - a) <= FS_TOL_CLIP * (FS_FABS(c1) + FS_FABS(m1 * y))) f1 = a;
        if (FS_FABS(f2 - b) <= FS_TOL_CLIP * (FS_FABS(c2) + FS_FABS(m2 * y))) f2 = b;
        f1 = fs_min(a, f1);
        f2 = fs_min(b, f2);
    } else {
        f1 = a * f1;
        f2 = b * f2;
    }
    return f1 > f2 ? f1 : f2;
}

/* area and first moment of max(impl(a, F), impl(b, R)) on [p, q] (moment of (y - ref) scale) */
FS_MAYBE_UNUSED static void fs_interval(fs_real p, fs_real q, fs_real m1, fs_real c1, fs_real a,
                                        fs_real m2, fs_real c2, fs_real b, long impl, fs_real ref,
                                        fs_real scale, fs_real *cand, fs_real *area_out,
                                        fs_real *mom_out) {
    long n = 1, k, li;
    fs_real y, area = FS_R(0.0), mom = FS_R(0.0), u, gu, v, gv, w, uu, vv, level;
    cand[0] = p;
    if (impl == 0) {
        if (m1 != FS_R(0.0)) {
            for (li = 0; li < 2; ++li) {
                level = li == 0 ? a : b;
                y = (level - c1) / m1;
                if (p < y && y < q) n = fs_insort(cand, n, y);
            }
        }
        if (m2 != FS_R(0.0)) {
            for (li = 0; li < 2; ++li) {
                level = li == 0 ? a : b;
                y = (level - c2) / m2;
                if (p < y && y < q) n = fs_insort(cand, n, y);
            }
        }
        if (m1 != m2 && a > FS_R(0.0) && b > FS_R(0.0)) {
            y = (c2 - c1) / (m1 - m2);
            if (p < y && y < q) n = fs_insort(cand, n, y);
        }
    } else {
        fs_real d = a * m1 - b * m2;
        if (d != FS_R(0.0) && a > FS_R(0.0) && b > FS_R(0.0)) {
            y = (b * c2 - a * c1) / d;
            if (p < y && y < q) n = fs_insort(cand, n, y);
        }
    }
    cand[n] = q;
    n += 1;
    u = cand[0];
    gu = fs_g2(u, m1, c1, a, m2, c2, b, impl);
    for (k = 1; k < n; ++k) {
        v = cand[k];
        gv = fs_g2(v, m1, c1, a, m2, c2, b, impl);
        w = v - u;
        if (w > FS_R(0.0) && (gu > FS_R(0.0) || gv > FS_R(0.0))) {
            uu = (u - ref) * scale;
            vv = (v - ref) * scale;
            area += FS_R(0.5) * w * (gu + gv);
            mom += w * (uu * (FS_R(2.0) * gu + gv) + vv * (gu + FS_R(2.0) * gv)) / FS_R(6.0);
        }
        u = v;
        gu = gv;
    }
    *area_out = area;
    *mom_out = mom;
}

/* centroid of every output at the (clipped) inputs x; NaN where no rule fires */
FS_MAYBE_UNUSED static void fs_eval_partition(const fs_real *x, const int32_t *pi,
                                              const fs_real *pf, fs_real *out, fs_real *work,
                                              int32_t *iw) {
    long n_in = pi[0], n_out = pi[1], gt = pi[2], and_op = pi[3], impl = pi[4], ro = pi[6];
    long pos = n_in, i, o, k, hoff, nh, dig, total, combo, ho;
    fs_real *cand;
    for (i = 0; i < n_in; ++i) {
        long base = pi[8 + i], n_bp = pi[base], xb_off = pi[base + 1], ent_f = pi[base + 3];
        long terms_at = pi[base + 4], lo, hi, mid, k0, cnt = 0;
        fs_real xv = x[i], inv = pf[pi[base + 5]], t;
        if (inv > FS_R(0.0)) {
            t = (xv - pf[xb_off]) * inv;
            /* numba: int(t) + 1 if t >= 0 else 0, then at most n_bp. int(t) of t >= 2^63 (an
             * unclipped input far outside) overflows there; here t >= n_bp gives n_bp, the
             * value every representable t >= n_bp gives */
            if (t >= FS_R(0.0)) lo = t >= FS_R(n_bp) ? n_bp : (long)t + 1;
            else lo = 0;
            if (lo > n_bp) lo = n_bp;
            while (lo > 0 && pf[xb_off + lo - 1] > xv) lo -= 1;
            while (lo < n_bp && pf[xb_off + lo] <= xv) lo += 1;
        } else {
            lo = 0;
            hi = n_bp;
            while (lo < hi) {
                mid = (lo + hi) >> 1;
                if (pf[xb_off + mid] <= xv) lo = mid + 1;
                else hi = mid;
            }
        }
        k0 = pi[base + 6 + 2 * lo];
        for (k = k0; k < k0 + pi[base + 6 + 2 * lo + 1]; ++k) {
            fs_real mval = pf[ent_f + 2 * k] * xv + pf[ent_f + 2 * k + 1];
            if (mval > FS_R(0.0)) {
                iw[pos + cnt] = pi[terms_at + k];
                work[pos + cnt] = mval;
                cnt += 1;
            }
        }
        if (cnt == 0) {
            for (o = 0; o < n_out; ++o) out[o] = FS_NAN;
            return;
        }
        iw[i] = (int32_t)cnt;
        pos += cnt;
    }
    /* heights of the output terms: the largest strength of the fired rules naming each */
    hoff = pos;
    nh = 0;
    for (o = 0; o < n_out; ++o) nh += pi[pi[8 + n_in + o] + 2];
    for (k = 0; k < nh; ++k) work[hoff + k] = FS_R(0.0);
    dig = pos;
    for (i = 0; i < n_in; ++i) iw[dig + i] = 0;
    total = 1;
    for (i = 0; i < n_in; ++i) total *= iw[i];
    for (combo = 0; combo < total; ++combo) {
        long cell = 0, p0 = n_in, ce, st, q;
        fs_real acc = FS_R(1.0), v;
        for (i = 0; i < n_in; ++i) {
            long d = iw[dig + i];
            cell += pi[gt + i] * iw[p0 + d];
            v = work[p0 + d];
            if (and_op == 0) {
                if (v < acc) acc = v;
            } else {
                acc *= v;
            }
            p0 += iw[i];
        }
        ce = gt + n_in + 2 * cell;
        st = pi[ce];
        for (q = 0; q < pi[ce + 1]; ++q) {
            long rr = pi[st + q];
            fs_real wr = acc * pf[rr];
            if (wr > FS_R(0.0)) {
                ho = hoff;
                for (o = 0; o < n_out; ++o) {
                    long j = pi[ro + rr * n_out + o];
                    if (j >= 0 && wr > work[ho + j]) work[ho + j] = wr;
                    ho += pi[pi[8 + n_in + o] + 2];
                }
            }
        }
        for (i = 0; i < n_in; ++i) { /* next combination (odometer) */
            iw[dig + i] += 1;
            if (iw[dig + i] < iw[i]) break;
            iw[dig + i] = 0;
        }
    }
    cand = work + hoff + nh;
    ho = hoff;
    for (o = 0; o < n_out; ++o) {
        long ob = pi[8 + n_in + o], n_int = pi[ob], bp_off = pi[ob + 1], n_t = pi[ob + 2];
        long line_off = pi[ob + 3], pairs = ob + 4, sup = pairs + 3 * n_int, k0 = n_int, k1 = -1, j;
        fs_real area = FS_R(0.0), mom = FS_R(0.0), ref, span, scale;
        for (j = 0; j < n_t; ++j) {
            if (work[ho + j] > FS_R(0.0)) {
                k0 = fs_imin(k0, pi[sup + 2 * j]);
                k1 = fs_imax(k1, pi[sup + 2 * j + 1]);
            }
        }
        ref = pf[bp_off];
        span = pf[bp_off + n_int] - ref;
        scale = FS_R(1.0) / span;
        for (k = k0; k < k1 + 1; ++k) {
            long j1 = pi[pairs + 3 * k], j2 = pi[pairs + 3 * k + 1], lo4;
            fs_real a = j1 >= 0 ? work[ho + j1] : FS_R(0.0);
            fs_real b = j2 >= 0 ? work[ho + j2] : FS_R(0.0), ar, mo;
            if (a <= FS_R(0.0) && b <= FS_R(0.0)) continue;
            if (impl == 0 && pi[pairs + 3 * k + 2] == 1) {
                fs_real p = pf[bp_off + k], w = pf[bp_off + k + 1] - p;
                fs_segment_integrals(a, b, &ar, &mo);
                area += w * ar;
                mom += w * ((p - ref) * scale * ar + (w * scale) * mo);
                continue;
            }
            lo4 = line_off + 4 * k;
            fs_interval(pf[bp_off + k], pf[bp_off + k + 1], pf[lo4], pf[lo4 + 1], a, pf[lo4 + 2],
                        pf[lo4 + 3], b, impl, ref, scale, cand, &ar, &mo);
            area += ar;
            mom += mo;
        }
        out[o] = area > FS_R(0.0) ? ref + span * (mom / area) : FS_NAN;
        ho += n_t;
    }
}

/* ======================================================================================
 * one point (general.eval_point, eval_first2)
 *
 * Scratch (fuzzyservo.export.fuzzy_c.scratch_sizes gives every size):
 * - fs_sys_eval_s: work[] of the evaluator's layout (ints[H_WORK] reals, or only the inputs
 *   and the partition path's scratch when the system takes that path), iwork[] of
 *   ints[H_IWORK] integers, and smooth[] for the smooth path (NULL when the system has no
 *   smooth output). The generated functions call this one: with the tables constant a
 *   compiler sees every offset, and the smooth path's in a work array sized without them
 *   would be refused (-Warray-bounds) although no point takes it.
 * - fs_sys_eval, fs_sys_eval2: one work array: ints[H_WORK] reals, then n_in + n_out (the
 *   point and the outputs of fs_sys_eval2, as eval_first2 keeps them), then the smooth path's.
 */

/* every output at the point x (n_in) into out (n_out); a NaN input gives NaN outputs */
FS_MAYBE_UNUSED static void fs_sys_eval_s(const fs_real *x, fs_real *out, const int32_t *ints,
                                          const fs_real *f, fs_real *work, int32_t *iw,
                                          fs_real *smooth_scr) {
    long n_in = ints[FS_H_NIN], n_out = ints[FS_H_NOUT], fvo = ints[FS_H_FVARS], i, o;
    long n_terms, n_rules, items, pos, nf, ot, impl, agg, dmode, tt;
    fs_real *xin = work, *mu, *w, *stk, *hts, *h, *rest;
    int32_t *lab, *fired, *nz;
    for (i = 0; i < n_in; ++i) {
        if (x[i] != x[i]) {
            for (o = 0; o < n_out; ++o) out[o] = FS_NAN;
            return;
        }
    }
    for (i = 0; i < n_in; ++i) {
        fs_real v = x[i];
        if (f[fvo + 4 * i + 3] != FS_R(0.0)) {
            fs_real lo = f[fvo + 4 * i], hi = f[fvo + 4 * i + 1];
            if (v < lo) v = lo;
            else if (v > hi) v = hi;
        }
        xin[i] = v;
    }
    if (ints[FS_H_PART] >= 0) {
        fs_eval_partition(xin, ints + ints[FS_H_PART], f + ints[FS_H_PARTF], out, work + n_in, iw);
        for (o = 0; o < n_out; ++o) {
            long fv = fvo + 4 * (n_in + o);
            if (out[o] != out[o]) out[o] = f[fv + 2];
            else if (f[fv + 3] != FS_R(0.0)) out[o] = fs_min(fs_max(out[o], f[fv]), f[fv + 1]);
        }
        return;
    }
    n_terms = ints[FS_H_NTERMS];
    n_rules = ints[FS_H_NRULES];
    items = ints[FS_H_MAXITEMS];
    pos = n_in;
    mu = work + pos;
    pos += n_terms;
    w = work + pos;
    pos += n_rules;
    stk = work + pos;
    pos += ints[FS_H_STACK];
    hts = work + pos;
    pos += items;
    h = work + pos;
    pos += items;
    rest = work + pos;
    lab = iw;
    fired = iw + items;
    nz = iw + items + n_rules;
    nf = fs_strengths(ints, f, xin, mu, w, stk, fired, nz);
    ot = ints[FS_H_OUTS];
    impl = ints[FS_H_IMPL];
    agg = ints[FS_H_AGG];
    dmode = ints[FS_H_DEFUZZ];
    tt = ints[FS_H_TERMS];
    for (o = 0; o < n_out; ++o) {
        long mode = ints[ot + FS_OUT_FIELDS * o], fv, n_items, qq;
        fs_real val = FS_NAN;
        if (mode == FS_M_SUGENO) {
            long first = ints[ints[FS_H_VARS] + 2 * (n_in + o)], rt = ints[FS_H_RULES];
            long ct = ints[FS_H_CONS];
            fs_real num = FS_R(0.0), den = FS_R(0.0);
            for (qq = 0; qq < nf; ++qq) {
                long r = fired[qq], c0 = ct + ints[rt + 4 * r + 2], c;
                for (c = 0; c < ints[rt + 4 * r + 3]; ++c) {
                    long t, off, npar;
                    fs_real z;
                    if (ints[c0 + 2 * c] != o) continue;
                    t = first + ints[c0 + 2 * c + 1];
                    off = ints[tt + 3 * t + 1];
                    npar = ints[tt + 3 * t + 2];
                    if (ints[tt + 3 * t] == FS_CONST) {
                        z = f[off];
                    } else {
                        z = f[off + npar - 1];
                        for (i = 0; i < n_in; ++i) z += f[off + i] * xin[i];
                    }
                    num += w[r] * z;
                    den += w[r];
                }
            }
            if (den > FS_R(0.0)) val = dmode == 5 ? num / den : num;
        } else {
            n_items = fs_items(ints, w, fired, nf, o, hts, lab, h);
            if (n_items > 0) {
                if (mode == FS_M_PL) {
                    long base = ot + FS_OUT_FIELDS * o, mi = items;
                    long n_cand = 2 + 2 * mi + 3 * mi * mi, n_bp = ints[base + 2];
                    long n_seg = 2 * fs_imax(n_bp - 1, 1) * n_cand, p, so, k0, k1, ns;
                    fs_real *lc = rest, *m = rest + mi, *hh = rest + 2 * mi, *cand, *su, *sv, *gu,
                            *gv;
                    p = 3 * mi;
                    cand = rest + p;
                    p += n_cand;
                    su = rest + p;
                    sv = rest + p + n_seg;
                    gu = rest + p + 2 * n_seg;
                    gv = rest + p + 3 * n_seg;
                    so = ints[base + 6];
                    k0 = n_bp;
                    k1 = -1;
                    for (i = 0; i < n_items; ++i) {
                        k0 = fs_imin(k0, ints[so + 2 * lab[i]]);
                        k1 = fs_imax(k1, ints[so + 2 * lab[i] + 1]);
                    }
                    ns = fs_pl_segments(n_items, lab, h, f, ints[base + 1], k0, k1, ints[base + 3],
                                        ints[base + 4], ints[base + 5], impl, agg, lc, m, hh,
                                        cand, su, sv, gu, gv);
                    {
                        /* the zero-width items (maxima only) in the candidates' scratch,
                         * which fs_pl_segments is done with (2 + 2 mi + 3 mi^2 >= 2 mi) */
                        fs_real *px = cand, *pv = cand + mi;
                        long n_pt = dmode >= 2 ? fs_pl_points(ints, f, o, n_items, lab, h, px,
                                                              pv) : 0;
                        val = fs_defuzz_segments(ns, su, sv, gu, gv, dmode, px, pv, n_pt);
                    }
                } else if (mode == FS_M_SING) {
                    val = fs_singletons(ints, f, o, n_items, lab, h, hts, dmode);
                } else {
                    val = fs_smooth(ints, f, o, n_items, lab, h, dmode, smooth_scr);
                }
            }
        }
        fv = fvo + 4 * (n_in + o);
        if (val != val) val = f[fv + 2];
        else if (f[fv + 3] != FS_R(0.0)) val = fs_min(fs_max(val, f[fv]), f[fv + 1]);
        out[o] = val;
    }
}

/* as fs_sys_eval_s, with the smooth path's scratch at the end of work */
FS_MAYBE_UNUSED static void fs_sys_eval(const fs_real *x, fs_real *out, const int32_t *ints,
                                        const fs_real *f, fs_real *work, int32_t *iw) {
    fs_sys_eval_s(x, out, ints, f, work, iw,
                  work + ints[FS_H_WORK] + ints[FS_H_NIN] + ints[FS_H_NOUT]);
}

/* the first output of a two-input system at (x1, x2): the controllers' call (eval_first2):
 * the point and the outputs in work after the evaluator's layout, as the Python does */
FS_MAYBE_UNUSED static fs_real fs_sys_eval2(fs_real x1, fs_real x2, const int32_t *ints,
                                            const fs_real *floats, fs_real *work, int32_t *iwork) {
    fs_real *x = work + ints[FS_H_WORK], *out = x + 2;
    x[0] = x1;
    x[1] = x2;
    fs_sys_eval(x, out, ints, floats, work, iwork);
    return out[0];
}

#endif /* FS_FUZZY_FRAGMENT */
