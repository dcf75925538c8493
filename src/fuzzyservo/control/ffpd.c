/* C port of the position controller with feed-forward (fuzzyservo.control.ffpd: ffpd_step,
 * _pack, _rest), line by line: the same operations in the same order.
 *
 * The exporter pastes this file after the law's layout, written from its declaration
 * (FFPD_LAW): FS_P_<NAME> indexes the packed parameters, FS_S_<NAME> the state, FS_G_<NAME>
 * the gains and FS_K_<NAME> the packing constants; fs_real is the arithmetic type. */

/* One sample on packed parameters p and state s (updated in place): ffpd_step. rd [m/s] and
 * rdd [m/s^2] are the reference's velocity and acceleration. */
static fs_real fs_law_step(const fs_real *p, fs_real *s, fs_real r, fs_real y,
                           fs_real rd, fs_real rdd)
{
    fs_real e = r - y;
    fs_real v_est = p[FS_P_A_F] * s[FS_S_V_EST] + p[FS_P_B_F] * (y - s[FS_S_Y_PREV]);
    fs_real a_est = p[FS_P_A_F] * s[FS_S_A_EST] + p[FS_P_B_F] * (v_est - s[FS_S_V_EST]);
    fs_real i_new = s[FS_S_INTEGRAL] + p[FS_P_KI_H] * e;
    fs_real w = p[FS_P_KX] * e + p[FS_P_KV_FF] * rd + p[FS_P_KA_FF] * rdd
                + p[FS_P_KA_FB] * (rdd - a_est) + i_new;
    fs_real u = w;
    if (u < p[FS_P_U_MIN]) {
        u = p[FS_P_U_MIN];
    }
    if (p[FS_P_U_MAX] < u) {
        u = p[FS_P_U_MAX];
    }
    if ((w > p[FS_P_U_MAX] && e > 0) || (w < p[FS_P_U_MIN] && e < 0)) {
        i_new = s[FS_S_INTEGRAL]; /* clamping anti-windup */
    }
    s[FS_S_INTEGRAL] = i_new;
    s[FS_S_Y_PREV] = y;
    s[FS_S_V_EST] = v_est;
    s[FS_S_A_EST] = a_est;
    return u;
}

/* The state at rest at y0 [m] holding the command u0 [-], bumpless: _rest. */
static void fs_law_rest(const fs_real *p, fs_real *s, fs_real y0, fs_real u0)
{
    (void)p;
    s[FS_S_INTEGRAL] = u0;
    s[FS_S_Y_PREV] = y0;
    s[FS_S_V_EST] = 0;
    s[FS_S_A_EST] = 0;
}

/* Pack the gains g and the constants k as _pack does, in double. */
static void fs_law_pack(fs_real *p, const double *g, const double *k)
{
    double h = k[FS_K_TS];
    double tf = g[FS_G_TF];
    p[FS_P_KX] = (fs_real)g[FS_G_KX];
    p[FS_P_KI_H] = (fs_real)(g[FS_G_KI] * h);
    p[FS_P_KV_FF] = (fs_real)g[FS_G_KV_FF];
    p[FS_P_KA_FF] = (fs_real)g[FS_G_KA_FF];
    p[FS_P_KA_FB] = (fs_real)g[FS_G_KA_FB];
    p[FS_P_A_F] = (fs_real)(tf / (tf + h));
    p[FS_P_B_F] = (fs_real)(1.0 / (tf + h));
    p[FS_P_U_MIN] = (fs_real)k[FS_K_U_MIN];
    p[FS_P_U_MAX] = (fs_real)k[FS_K_U_MAX];
}
