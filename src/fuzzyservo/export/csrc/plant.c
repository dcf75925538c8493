/*
 * fuzzyservo servo plant: C99 port of the plant models and of their sample-to-sample advance.
 *
 * A fragment pasted verbatim into a generated source (fuzzyservo.export.plant_c.emit_servo
 * adds the constants and the fs_servo_* API after it). Each function is a line-by-line port
 * of its Python original, with the same operations in the same order, so that a build with
 * IEEE double semantics (no -ffast-math; -ffp-contract=off, which gcc -std=c99 implies;
 * SSE2, not x87) gives the numba kernels' results bit for bit:
 *
 *   fs_nl_*       fuzzyservo.plant.nonlinear (rhs, rk4_advance_ws and the helpers)
 *   fs_delayed    fuzzyservo.sim.closed_loop._delayed (the command ring buffer)
 *   fs_lin_*      the plant part of fuzzyservo.sim.loops.linear_one
 *   fs_lin_force_* the load force's part of a linear plant,
 *                 fuzzyservo.sim.closed_loop.LinearPlant.force_response (superposition)
 *   fs_nl_sample  the plant part of fuzzyservo.sim.loops.nonlinear_one
 *
 * Standard library only (math.h); no heap, no global state: the callers own every array.
 * The functions are static inline so that those a plant kind does not use draw no
 * -Wunused-function warning.
 */
#include <math.h>

/* Indices of the packed parameter vector (fuzzyservo.plant.nonlinear.P_*, pack()). */
enum {
    FS_NL_P_AF = 0, FS_NL_P_AN = 1, FS_NL_P_L = 2, FS_NL_P_V0F = 3, FS_NL_P_V0N = 4,
    FS_NL_P_CLI = 5, FS_NL_P_KSTOP = 6, FS_NL_P_CSTOP = 7, FS_NL_P_G = 8, FS_NL_P_WV = 9,
    FS_NL_P_ZV = 10, FS_NL_P_TAU = 11, FS_NL_P_KL0 = 12, FS_NL_P_PCR = 13, FS_NL_P_BC = 14,
    FS_NL_P_CH = 15, FS_NL_P_PFLOOR = 16, FS_NL_P_M = 17, FS_NL_P_B = 18, FS_NL_P_FC = 19,
    FS_NL_P_FS = 20, FS_NL_P_VS = 21, FS_NL_P_EPS = 22, FS_NL_P_FEXT = 23, FS_NL_P_PS = 24,
    FS_NL_P_PT = 25, FS_NL_P_RIPA = 26, FS_NL_P_RIPF = 27, FS_NL_P_DELAY = 28,
    FS_NL_P_NOISE = 29, FS_NL_P_RES = 30, FS_NL_N_PARAMS = 31
};

/* Indices of the nonlinear state (fuzzyservo.plant.nonlinear.STATE_NAMES). */
enum {
    FS_NL_S_LAG = 0, FS_NL_S_SPOOL = 1, FS_NL_S_RATE = 2, FS_NL_S_PF = 3, FS_NL_S_PN = 4,
    FS_NL_S_X = 5, FS_NL_S_V = 6, FS_NL_N_STATE = 7
};

/* COMMAND_LIMIT [1], PRESSURE_FLOOR_BAND [Pa] and math.pi, as the Python has them. */
#define FS_NL_COMMAND_LIMIT 1.0
#define FS_NL_PRESSURE_FLOOR_BAND 100000.0
#define FS_NL_PI 0x1.921fb54442d18p+1

/* orifice_root: sgn(dp) sqrt|dp| with the laminar regularisation [Pa^0.5]. */
static inline double fs_nl_orifice_root(double dp, double p_cr)
{
    return dp / sqrt(sqrt(dp * dp + p_cr * p_cr));
}

/* supply_pressure: P_s(t) = P_s + ripple sin(2 pi f t) [Pa]. */
static inline double fs_nl_supply_pressure(double t, const double *p)
{
    return p[FS_NL_P_PS] + p[FS_NL_P_RIPA] * sin(2.0 * FS_NL_PI * p[FS_NL_P_RIPF] * t);
}

/* valve_flows: flow into the full-bore side *qf and out of the annulus side *qn [m^3/s]. */
static inline void fs_nl_valve_flows(double xv, double pf, double pn, double ps,
                                     const double *p, double *qf_out, double *qn_out)
{
    double g = p[FS_NL_P_G];
    double pcr = p[FS_NL_P_PCR];
    double pt = p[FS_NL_P_PT];
    double qf, qn, kl;
    if (xv >= 0.0) {
        qf = g * xv * fs_nl_orifice_root(ps - pf, pcr);
        qn = g * xv * fs_nl_orifice_root(pn - pt, pcr);
    } else {
        qf = g * xv * fs_nl_orifice_root(pf - pt, pcr);
        qn = g * xv * fs_nl_orifice_root(ps - pn, pcr);
    }
    kl = p[FS_NL_P_KL0];
    qf += kl * (ps - pf) - kl * (pf - pt);
    qn -= kl * (ps - pn) - kl * (pn - pt);
    *qf_out = qf;
    *qn_out = qn;
}

/* friction_force: viscous plus smoothed Stribeck/Coulomb friction opposing v [N]. */
static inline double fs_nl_friction_force(double v, const double *p)
{
    double f = p[FS_NL_P_B] * v;
    if (p[FS_NL_P_FS] > 0.0) {
        double a = v / p[FS_NL_P_VS];
        f += (p[FS_NL_P_FC] + (p[FS_NL_P_FS] - p[FS_NL_P_FC]) * exp(-a * a))
             * tanh(v / p[FS_NL_P_EPS]);
    }
    return f;
}

/* stop_force: end-stop cushion (spring-damper beyond 0 and L, pushing only) [N]. */
static inline double fs_nl_stop_force(double x, double v, const double *p)
{
    double f;
    if (x < 0.0) {
        f = -p[FS_NL_P_KSTOP] * x - p[FS_NL_P_CSTOP] * v;
        return f > 0.0 ? f : 0.0;
    }
    if (x > p[FS_NL_P_L]) {
        f = -p[FS_NL_P_KSTOP] * (x - p[FS_NL_P_L]) - p[FS_NL_P_CSTOP] * v;
        return f < 0.0 ? f : 0.0;
    }
    return 0.0;
}

/* floor_factor: 0 at the pressure floor, 1 from floor + band up (smoothstep) [1]. */
static inline double fs_nl_floor_factor(double pressure, double floor_)
{
    double z = (pressure - floor_) / FS_NL_PRESSURE_FLOOR_BAND;
    if (z <= 0.0) {
        return 0.0;
    }
    if (z >= 1.0) {
        return 1.0;
    }
    return z * z * (3.0 - 2.0 * z);
}

/* rhs: dx/dt of the nonlinear servo at time t [s], state x, valve command u (already
 * delayed; limited to [-1, 1] here), packed parameters p; written into dx. */
static inline void fs_nl_rhs(double t, const double *x, double u, const double *p, double *dx)
{
    double tau, s_in, wv, pf, pn, xp, vp, ps, qf, qn, qi, af, an, vcf, vcn, cf, cn, dpf, dpn;
    double force;
    if (u > FS_NL_COMMAND_LIMIT) {
        u = FS_NL_COMMAND_LIMIT;
    } else if (u < -FS_NL_COMMAND_LIMIT) {
        u = -FS_NL_COMMAND_LIMIT;
    }
    /* eq. (1): optional first-order stage, then the second-order spool */
    tau = p[FS_NL_P_TAU];
    if (tau > 0.0) {
        dx[FS_NL_S_LAG] = (u - x[FS_NL_S_LAG]) / tau;
        s_in = x[FS_NL_S_LAG];
    } else {
        dx[FS_NL_S_LAG] = 0.0;
        s_in = u;
    }
    wv = p[FS_NL_P_WV];
    dx[FS_NL_S_SPOOL] = x[FS_NL_S_RATE];
    dx[FS_NL_S_RATE] = wv * wv * (s_in - x[FS_NL_S_SPOOL])
                       - 2.0 * p[FS_NL_P_ZV] * wv * x[FS_NL_S_RATE];

    pf = x[FS_NL_S_PF];
    pn = x[FS_NL_S_PN];
    xp = x[FS_NL_S_X];
    vp = x[FS_NL_S_V];
    ps = fs_nl_supply_pressure(t, p);
    fs_nl_valve_flows(x[FS_NL_S_SPOOL], pf, pn, ps, p, &qf, &qn);
    qi = p[FS_NL_P_CLI] * (pf - pn);

    af = p[FS_NL_P_AF];
    an = p[FS_NL_P_AN];
    vcf = p[FS_NL_P_V0F] + af * xp;
    vcn = p[FS_NL_P_V0N] + an * (p[FS_NL_P_L] - xp);
    if (vcf < 0.0) {
        vcf = 0.0;
    }
    if (vcn < 0.0) {
        vcn = 0.0;
    }
    cf = vcf / p[FS_NL_P_BC] + p[FS_NL_P_CH];
    cn = vcn / p[FS_NL_P_BC] + p[FS_NL_P_CH];
    dpf = (qf - af * vp - qi) / cf;
    dpn = (-qn + an * vp + qi) / cn;
    if (dpf < 0.0) {
        dpf *= fs_nl_floor_factor(pf, p[FS_NL_P_PFLOOR]);
    }
    if (dpn < 0.0) {
        dpn *= fs_nl_floor_factor(pn, p[FS_NL_P_PFLOOR]);
    }
    dx[FS_NL_S_PF] = dpf;
    dx[FS_NL_S_PN] = dpn;

    force = af * pf - an * pn - fs_nl_friction_force(vp, p) - p[FS_NL_P_FEXT]
            + fs_nl_stop_force(xp, vp, p);
    dx[FS_NL_S_X] = vp;
    dx[FS_NL_S_V] = force / p[FS_NL_P_M];
}

/* rk4_advance_ws: advance x in place over dt [s] from t [s] with n_sub classical RK4
 * substeps, u held; work holds 5 * FS_NL_N_STATE doubles. Returns 1, or 0 when the state
 * became non-finite (checked once, after the last substep, as the Python does). */
static inline int fs_nl_rk4(double t, double *x, double u, const double *p, double dt,
                            int n_sub, double *work)
{
    double h = dt / (double)n_sub;
    double *k1 = work;
    double *k2 = work + FS_NL_N_STATE;
    double *k3 = work + 2 * FS_NL_N_STATE;
    double *k4 = work + 3 * FS_NL_N_STATE;
    double *xt = work + 4 * FS_NL_N_STATE;
    int i, j;
    for (j = 0; j < n_sub; j++) {
        double tj = t + (double)j * h;
        fs_nl_rhs(tj, x, u, p, k1);
        for (i = 0; i < FS_NL_N_STATE; i++) {
            xt[i] = x[i] + 0.5 * h * k1[i];
        }
        fs_nl_rhs(tj + 0.5 * h, xt, u, p, k2);
        for (i = 0; i < FS_NL_N_STATE; i++) {
            xt[i] = x[i] + 0.5 * h * k2[i];
        }
        fs_nl_rhs(tj + 0.5 * h, xt, u, p, k3);
        for (i = 0; i < FS_NL_N_STATE; i++) {
            xt[i] = x[i] + h * k3[i];
        }
        fs_nl_rhs(tj + h, xt, u, p, k4);
        for (i = 0; i < FS_NL_N_STATE; i++) {
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    for (i = 0; i < FS_NL_N_STATE; i++) {
        if (!isfinite(x[i])) {
            return 0;
        }
    }
    return 1;
}

/* The measured position [m]: x rounded to the transducer resolution p[RES] (none when 0),
 * as nonlinear_one rounds y (|x / res| must stay below 2^63, as numba's int floor needs). */
static inline double fs_nl_measure(const double *x, const double *p)
{
    double y = x[FS_NL_S_X];
    double res = p[FS_NL_P_RES];
    if (res > 0.0) {
        y = res * floor(y / res + 0.5);
    }
    return y;
}

/* _delayed: the commands u_{k-d} (*u0) and u_{k-d-1} (*u1) from the ring buffer ubuf of nbuf
 * >= d + 2 commands whose slot w holds u_k; u_init before t_0. */
static inline void fs_delayed(const double *ubuf, int nbuf, int w, long long k, int d,
                              double u_init, double *u0, double *u1)
{
    int j0 = w - d;
    int j1;
    if (j0 < 0) {
        j0 += nbuf;
    }
    j1 = j0 - 1;
    if (j1 < 0) {
        j1 += nbuf;
    }
    *u0 = k - d >= 0 ? ubuf[j0] : u_init;
    *u1 = k - d - 1 >= 0 ? ubuf[j1] : u_init;
}

/* Store the command u_k in the ring (slot *w), fetch the delayed commands, move *w on:
 * the ring step of linear_one and nonlinear_one. */
static inline void fs_ring_push(double *ubuf, int nbuf, int *w, long long k, int d,
                                double u, double u_init, double *u0, double *u1)
{
    ubuf[*w] = u;
    fs_delayed(ubuf, nbuf, *w, k, d, u_init, u0, u1);
    *w += 1;
    if (*w == nbuf) {
        *w = 0;
    }
}

/* linear_one's output: y = y0 + C x, summed in state order [m]. */
static inline double fs_lin_output(int n, const double *c, double y0, const double *x)
{
    double y = y0;
    int i;
    for (i = 0; i < n; i++) {
        y += c[i] * x[i];
    }
    return y;
}

/* One sample of linear_one's plant: command u_k at sample k; the deviation x (n states,
 * row-major phi n x n) advances to sample k + 1 (x_{k+1} = phi x_k + g0 (u_{k-d} - u_op)
 * + g1 (u_{k-d-1} - u_op)); xn is n doubles of scratch. Returns 0, or 1 when the new state
 * is not finite. */
static inline int fs_lin_sample(int n, const double *phi, const double *g0, const double *g1,
                                double u_op, int d, double *ubuf, int nbuf, int *w,
                                long long k, double u, double *x, double *xn)
{
    double u0, u1;
    int i, j, bad = 0;
    fs_ring_push(ubuf, nbuf, w, k, d, u, u_op, &u0, &u1);
    u0 -= u_op;
    u1 -= u_op;
    for (i = 0; i < n; i++) {
        double acc = g0[i] * u0 + g1[i] * u1;
        const double *row = phi + i * n;
        for (j = 0; j < n; j++) {
            acc += row[j] * x[j];
        }
        xn[i] = acc;
    }
    for (i = 0; i < n; i++) {
        x[i] = xn[i];
        if (!isfinite(x[i])) {
            bad = 1;
        }
    }
    return bad;
}

/* One sample of LinearPlant.force_response: the force's deviation xf (n states) advances
 * under the force deviation df = F_k - F_op [N], held over the sample (no delay: the force
 * acts on the piston): xf_{k+1} = phi_e xf_k + ge df, summed as the Python sums (ge df first,
 * then phi_e's columns in order); xn is n doubles of scratch. Returns 0, or 1 when the new
 * state is not finite. */
static inline int fs_lin_force_sample(int n, const double *phi, const double *ge, double df,
                                      double *xf, double *xn)
{
    int i, j, bad = 0;
    for (i = 0; i < n; i++) {
        double acc = ge[i] * df;
        const double *row = phi + i * n;
        for (j = 0; j < n; j++) {
            acc = acc + row[j] * xf[j];
        }
        xn[i] = acc;
    }
    for (i = 0; i < n; i++) {
        xf[i] = xn[i];
        if (!isfinite(xf[i])) {
            bad = 1;
        }
    }
    return bad;
}

/* The force's part of the output, y_F = C xf, summed from 0 in state order [m]
 * (force_response's ys). */
static inline double fs_lin_force_output(int n, const double *c, const double *xf)
{
    double y = 0.0;
    int i;
    for (i = 0; i < n; i++) {
        y = y + c[i] * xf[i];
    }
    return y;
}

/* One sample of nonlinear_one's plant: command u_k at sample k (t_k = k ts [s]); x advances
 * to t_{k+1} under u_{k-d-1} over [t_k, t_k + f) (n1 substeps) and u_{k-d} over
 * [t_k + f, t_{k+1}) (n0 substeps), or u_{k-d} throughout (n_sub substeps) when f = 0.
 * Returns 0, or 1 when the state became non-finite. */
static inline int fs_nl_sample(const double *p, double ts, int d, double f, int n_sub, int n1,
                               int n0, double u_init, double *ubuf, int nbuf, int *w,
                               long long k, double u, double *x, double *work)
{
    double t = (double)k * ts;
    double u0, u1;
    int ok;
    fs_ring_push(ubuf, nbuf, w, k, d, u, u_init, &u0, &u1);
    if (f > 0.0) {
        ok = fs_nl_rk4(t, x, u1, p, f, n1, work);
        ok = ok && fs_nl_rk4(t + f, x, u0, p, ts - f, n0, work);
    } else {
        ok = fs_nl_rk4(t, x, u0, p, ts, n_sub, work);
    }
    return ok ? 0 : 1;
}
