/* C port of the sliding-mode law (fuzzyservo.control.smc: smc_step, _pack, _rest), line by
 * line.
 *
 * The exporter pastes this file after the law's layout, written from its declaration
 * (SMC_LAW): FS_P_<NAME> indexes the packed parameters, FS_S_<NAME> the state, FS_G_<NAME>
 * the gains and FS_K_<NAME> the packing constants; fs_real is the arithmetic type. */

/* One sample on packed parameters p and state s (updated in place): smc_step. */
static fs_real fs_law_step(const fs_real *p, fs_real *s, fs_real r, fs_real y,
                           fs_real rd, fs_real rdd)
{
    fs_real yf, vf, rdd_prev;
    if (s[FS_S_STARTED] == 0) {
        yf = y;
        vf = 0;
        rdd_prev = rdd;
        s[FS_S_STARTED] = 1;
    } else {
        fs_real d = (y - s[FS_S_Y_F]) + (s[FS_S_Y_PREV] - s[FS_S_Y_F]);
        yf = s[FS_S_Y_F] + p[FS_P_M12] * s[FS_S_V_F] + p[FS_P_N1] * d;
        vf = p[FS_P_M22] * s[FS_S_V_F] + p[FS_P_N2] * d;
        rdd_prev = s[FS_S_RDD_PREV];
    }
    fs_real acc = p[FS_P_WF2] * (y - yf) - p[FS_P_CV] * vf;
    fs_real e = r - y;
    fs_real ed = rd - vf;
    fs_real edd = rdd - acc;
    fs_real jerk = p[FS_P_JERK_GAIN] * (rdd - rdd_prev);
    fs_real ei = s[FS_S_E_INT] + p[FS_P_H_INT] * e;
    fs_real sv = edd + p[FS_P_C2] * ed + p[FS_P_C1] * e + p[FS_P_C0] * ei;
    fs_real ueq = p[FS_P_INV_B] * (jerk + p[FS_P_A2] * acc + p[FS_P_A1] * vf
                                   + p[FS_P_C2] * edd + p[FS_P_C1] * ed + p[FS_P_C0] * e);
    fs_real phi = p[FS_P_PHI];
    fs_real sw;
    if (sv > phi) {
        sw = 1;
    } else if (sv < -phi) {
        sw = -1;
    } else if (phi > 0) {
        sw = sv / phi;
    } else {
        sw = 0;
    }
    fs_real v = s[FS_S_U_OFF] + ueq + p[FS_P_KS_B] * sw;
    fs_real u = v;
    if (u < p[FS_P_U_MIN]) {
        u = p[FS_P_U_MIN];
    }
    if (p[FS_P_U_MAX] < u) {
        u = p[FS_P_U_MAX];
    }
    if ((v > p[FS_P_U_MAX] && e > 0) || (v < p[FS_P_U_MIN] && e < 0)) {
        ei = s[FS_S_E_INT]; /* clamping: conditional integration */
    }
    s[FS_S_Y_F] = yf;
    s[FS_S_V_F] = vf;
    s[FS_S_Y_PREV] = y;
    s[FS_S_E_INT] = ei;
    s[FS_S_RDD_PREV] = rdd;
    s[FS_S_SIGMA] = sv;
    return u;
}

/* The state before the first sample, holding the command u0 [-]: _rest (the first sample
 * starts the filter at its measurement, so y0 is not needed). */
static void fs_law_rest(const fs_real *p, fs_real *s, fs_real y0, fs_real u0)
{
    (void)p;
    (void)y0;
    s[FS_S_STARTED] = 0;
    s[FS_S_Y_F] = 0;
    s[FS_S_V_F] = 0;
    s[FS_S_Y_PREV] = 0;
    s[FS_S_E_INT] = 0;
    s[FS_S_RDD_PREV] = 0;
    s[FS_S_U_OFF] = u0;
    s[FS_S_SIGMA] = 0;
}

/* Pack the gains g and the constants k as _pack does, in double. */
static void fs_law_pack(fs_real *p, const double *g, const double *k)
{
    double lam = g[FS_G_LAM], wf = g[FS_G_OMEGA_F], zf = g[FS_G_ZETA_F];
    double ko = g[FS_G_K_O], w0 = g[FS_G_OMEGA_0];
    double h = k[FS_K_TS];
    if (k[FS_K_INTEGRAL] == 1.0) {
        p[FS_P_C2] = (fs_real)(3.0 * lam);
        p[FS_P_C1] = (fs_real)(3.0 * (lam * lam));
        p[FS_P_C0] = (fs_real)(lam * lam * lam);
        p[FS_P_H_INT] = (fs_real)h;
    } else {
        p[FS_P_C2] = (fs_real)(2.0 * lam);
        p[FS_P_C1] = (fs_real)(lam * lam);
        p[FS_P_C0] = 0;
        p[FS_P_H_INT] = 0;
    }
    double b = ko * (w0 * w0);
    p[FS_P_INV_B] = (fs_real)(1.0 / b);
    p[FS_P_A1] = (fs_real)(w0 * w0);
    p[FS_P_A2] = (fs_real)(2.0 * g[FS_G_DELTA] * w0);
    p[FS_P_KS_B] = (fs_real)(g[FS_G_KS] / b);
    p[FS_P_PHI] = (fs_real)g[FS_G_PHI];
    p[FS_P_JERK_GAIN] = (fs_real)(k[FS_K_JERK] == 1.0 ? 1.0 / h : 0.0);
    double wf2 = wf * wf;
    double cv = 2.0 * zf * wf;
    double hh = 0.5 * h;
    double q = wf2 * hh * hh;
    double det = 1.0 + cv * hh + q;
    p[FS_P_WF2] = (fs_real)wf2;
    p[FS_P_CV] = (fs_real)cv;
    p[FS_P_M12] = (fs_real)(h / det);
    p[FS_P_M22] = (fs_real)((1.0 - cv * hh - q) / det);
    p[FS_P_N1] = (fs_real)(q / det);
    p[FS_P_N2] = (fs_real)((wf2 * hh) / det);
    p[FS_P_U_MIN] = (fs_real)k[FS_K_U_MIN];
    p[FS_P_U_MAX] = (fs_real)k[FS_K_U_MAX];
}
