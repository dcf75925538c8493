/* C port of the test-only feed-forward law (tests/export/feedforward_law.py), line by line. */

static fs_real fs_law_step(const fs_real *p, fs_real *s, fs_real r, fs_real y,
                           fs_real rd, fs_real rdd)
{
    fs_real v = p[FS_P_KV] * rd + p[FS_P_KA] * rdd + p[FS_P_KP] * (r - y);
    fs_real u = s[FS_S_U_OFF] + v;
    if (u < p[FS_P_U_MIN]) {
        u = p[FS_P_U_MIN];
    }
    if (p[FS_P_U_MAX] < u) {
        u = p[FS_P_U_MAX];
    }
    return u;
}

static void fs_law_rest(const fs_real *p, fs_real *s, fs_real y0, fs_real u0)
{
    (void)p;
    (void)y0;
    s[FS_S_U_OFF] = u0;
}

static void fs_law_pack(fs_real *p, const double *g, const double *k)
{
    p[FS_P_KP] = (fs_real)g[FS_G_KP];
    p[FS_P_KV] = (fs_real)g[FS_G_KV];
    p[FS_P_KA] = (fs_real)g[FS_G_KA];
    p[FS_P_U_MIN] = (fs_real)k[FS_K_U_MIN];
    p[FS_P_U_MAX] = (fs_real)k[FS_K_U_MAX];
}
