/* C port of the PID law (fuzzyservo.control.pid: pid_step, _pack, _rest), line by line.
 *
 * The exporter pastes this file after the law's layout, written from its declaration
 * (PID_LAW): FS_P_<NAME> indexes the packed parameters, FS_S_<NAME> the state, FS_G_<NAME>
 * the gains and FS_K_<NAME> the packing constants; fs_real is the arithmetic type. */

/* One sample on packed parameters p and state s (updated in place): pid_step. */
static fs_real fs_law_step(const fs_real *p, fs_real *s, fs_real r, fs_real y,
                           fs_real rd, fs_real rdd)
{
    (void)rd; /* no feed-forward */
    (void)rdd;
    fs_real e = r - y;
    fs_real ed = p[FS_P_C] * r - y;
    fs_real d = p[FS_P_A_D] * s[FS_S_DERIVATIVE] + p[FS_P_B_D] * (ed - s[FS_S_ED_PREV]);
    fs_real i_new = s[FS_S_INTEGRAL] + p[FS_P_KI_H] * e;
    fs_real v = p[FS_P_KP] * (p[FS_P_B] * r - y) + i_new + d;
    fs_real u = v;
    if (u < p[FS_P_U_MIN]) {
        u = p[FS_P_U_MIN];
    }
    if (p[FS_P_U_MAX] < u) {
        u = p[FS_P_U_MAX];
    }
    if (p[FS_P_ANTI_WINDUP] == 1) {
        if ((v > p[FS_P_U_MAX] && e > 0) || (v < p[FS_P_U_MIN] && e < 0)) {
            i_new = s[FS_S_INTEGRAL];
        }
    } else if (p[FS_P_ANTI_WINDUP] == 2) {
        i_new += p[FS_P_KB_H] * (u - v);
    }
    s[FS_S_INTEGRAL] = i_new;
    s[FS_S_DERIVATIVE] = d;
    s[FS_S_ED_PREV] = ed;
    return u;
}

/* The state at rest at y0 [m] holding the command u0 [-], bumpless: _rest. */
static void fs_law_rest(const fs_real *p, fs_real *s, fs_real y0, fs_real u0)
{
    s[FS_S_INTEGRAL] = u0 - p[FS_P_KP] * (p[FS_P_B] - 1) * y0;
    s[FS_S_DERIVATIVE] = 0;
    s[FS_S_ED_PREV] = (p[FS_P_C] - 1) * y0;
}

/* Pack the gains g and the constants k as _pack does, in double. */
static void fs_law_pack(fs_real *p, const double *g, const double *k)
{
    double kp = g[FS_G_KP], ki = g[FS_G_KI], kd = g[FS_G_KD], n = g[FS_G_N];
    double h = k[FS_K_TS];
    double ad, bd, tt, kbh = 0.0;
    if (isinf(n)) {
        ad = 0.0;
        bd = kd / h;
    } else {
        ad = 1.0 / (1.0 + n * h);
        bd = kd * n / (1.0 + n * h);
    }
    if (ki > 0.0) {
        tt = k[FS_K_TRACKING_TIME] > 0.0 ? k[FS_K_TRACKING_TIME]
                                         : (kd > 0.0 ? sqrt(kd / ki) : kp / ki);
        if (tt > 0.0) {
            kbh = h / tt;
            if (!(kbh <= 1.0)) {
                kbh = isnan(kbh) ? 0.0 : 1.0;
            }
        }
    }
    p[FS_P_KP] = (fs_real)kp;
    p[FS_P_KI_H] = (fs_real)(ki * h);
    p[FS_P_A_D] = (fs_real)ad;
    p[FS_P_B_D] = (fs_real)bd;
    p[FS_P_B] = (fs_real)g[FS_G_B];
    p[FS_P_C] = (fs_real)g[FS_G_C];
    p[FS_P_U_MIN] = (fs_real)k[FS_K_U_MIN];
    p[FS_P_U_MAX] = (fs_real)k[FS_K_U_MAX];
    p[FS_P_ANTI_WINDUP] = (fs_real)k[FS_K_ANTI_WINDUP];
    p[FS_P_KB_H] = (fs_real)kbh;
}
