/* C port of the test-only lead-lag law (tests/control/leadlag.py), line by line. */

static fs_real fs_law_step(const fs_real *p, fs_real *s, fs_real r, fs_real y,
                           fs_real rd, fs_real rdd)
{
    (void)rd; /* no feed-forward */
    (void)rdd;
    fs_real e = r - y;
    fs_real v = p[FS_P_B0] * e + p[FS_P_B1] * s[FS_S_E_PREV] - p[FS_P_A1] * s[FS_S_V_PREV];
    fs_real u = s[FS_S_U_OFF] + v;
    if (u < p[FS_P_U_MIN]) {
        u = p[FS_P_U_MIN];
    }
    if (p[FS_P_U_MAX] < u) {
        u = p[FS_P_U_MAX];
    }
    s[FS_S_E_PREV] = e;
    s[FS_S_V_PREV] = v;
    return u;
}

static void fs_law_rest(const fs_real *p, fs_real *s, fs_real y0, fs_real u0)
{
    (void)p;
    (void)y0;
    s[FS_S_E_PREV] = 0;
    s[FS_S_V_PREV] = 0;
    s[FS_S_U_OFF] = u0;
}

static void fs_law_pack(fs_real *p, const double *g, const double *k)
{
    double h = k[FS_K_TS];
    double den = 1.0 + 2.0 * g[FS_G_T2] / h;
    p[FS_P_B0] = (fs_real)(g[FS_G_K] * (1.0 + 2.0 * g[FS_G_T1] / h) / den);
    p[FS_P_B1] = (fs_real)(g[FS_G_K] * (1.0 - 2.0 * g[FS_G_T1] / h) / den);
    p[FS_P_A1] = (fs_real)((1.0 - 2.0 * g[FS_G_T2] / h) / den);
    p[FS_P_U_MIN] = (fs_real)k[FS_K_U_MIN];
    p[FS_P_U_MAX] = (fs_real)k[FS_K_U_MAX];
}
