/* C port of the fuzzy PI law, with and without self-tuning: the alpha rule base (Mudi & Pal)
 * or Woo et al.'s functions of |e_n| (fuzzyservo.control.fuzzy_pi: fuzzy_pi_step, _pack,
 * _pack_woo, _rest), line by line.
 *
 * The exporter pastes this file after the law's layout, written from its declaration
 * (FUZZY_PI_LAW: FS_P_<NAME>, FS_S_<NAME>, FS_G_<NAME>, FS_K_<NAME>) and after the
 * controller's fuzzy systems: fs_sys_du(x1, x2), and when self-tuning by the alpha rule base
 * (FS_SYS_ALPHA defined) fs_sys(x1, x2, &du, &alpha), which evaluates both as the Python does.
 * The Woo law (WOO_FPI_LAW) has the same layout and seven gains (FS_G_PHI_A defined). */

/* One sample on packed parameters p and state s (updated in place): fuzzy_pi_step. */
static fs_real fs_law_step(const fs_real *p, fs_real *s, fs_real r, fs_real y,
                           fs_real rd, fs_real rdd)
{
    (void)rd; /* no feed-forward */
    (void)rdd;
    fs_real yf, e, e_prev, de, en, den, dun, alpha, u;
    if (s[FS_S_STARTED] == 0) {
        yf = y;
        e = r - yf;
        e_prev = p[FS_P_E_INIT] == 1 ? e : 0;
        s[FS_S_STARTED] = 1;
    } else {
        fs_real a = p[FS_P_FILTER_A];
        yf = a * s[FS_S_Y_FILTERED] + (1 - a) * y;
        e = r - yf;
        e_prev = s[FS_S_E_PREV];
    }
    de = (e - e_prev) * p[FS_P_DE_SCALE];
    en = p[FS_P_KE] * e;
    den = p[FS_P_KDE] * de;
    if (p[FS_P_SELF_TUNING] == 2) {
        /* Woo et al. (2000): phi(|e_n|) scales the error change, psi(|e_n|) is alpha */
        fs_real m = en < 0 ? -en : en;
        if (1 < m) {
            m = 1;
        }
        den = den * (p[FS_P_PHI_A] * m + p[FS_P_PHI_B]);
        dun = fs_sys_du(en, den);
        alpha = p[FS_P_PSI_C] * (1 - m) + p[FS_P_PSI_D];
    } else {
#ifdef FS_SYS_ALPHA
        fs_sys(en, den, &dun, &alpha);
#else
        dun = fs_sys_du(en, den);
        alpha = 1;
#endif
    }
    u = s[FS_S_U_PREV] + alpha * p[FS_P_KDU] * dun;
    if (u < p[FS_P_U_MIN]) {
        u = p[FS_P_U_MIN];
    }
    if (p[FS_P_U_MAX] < u) {
        u = p[FS_P_U_MAX];
    }
    s[FS_S_U_PREV] = u;
    s[FS_S_E_PREV] = e;
    s[FS_S_Y_FILTERED] = yf;
    s[FS_S_ALPHA] = alpha;
    return u;
}

/* The state before the first sample holding the command u0 [-] (y0 is not needed: the
 * first sample sets e(-1) and y_f): _rest. */
static void fs_law_rest(const fs_real *p, fs_real *s, fs_real y0, fs_real u0)
{
    (void)p;
    (void)y0;
    s[FS_S_U_PREV] = u0;
    s[FS_S_E_PREV] = 0;
    s[FS_S_Y_FILTERED] = 0;
    s[FS_S_STARTED] = 0;
    s[FS_S_ALPHA] = 1;
}

/* Pack the gains g and the constants k (already in packed form) as _pack does. */
static void fs_law_pack(fs_real *p, const double *g, const double *k)
{
    p[FS_P_KE] = (fs_real)g[FS_G_KE];
    p[FS_P_KDE] = (fs_real)g[FS_G_KDE];
    p[FS_P_KDU] = (fs_real)g[FS_G_KDU];
    p[FS_P_U_MIN] = (fs_real)k[FS_K_U_MIN];
    p[FS_P_U_MAX] = (fs_real)k[FS_K_U_MAX];
    p[FS_P_DE_SCALE] = (fs_real)k[FS_K_DE_SCALE];
    p[FS_P_E_INIT] = (fs_real)k[FS_K_E_INIT];
    p[FS_P_FILTER_A] = (fs_real)k[FS_K_FILTER_A];
    p[FS_P_SELF_TUNING] = (fs_real)k[FS_K_SELF_TUNING];
#ifdef FS_G_PHI_A /* the Woo law's gains (_pack_woo) */
    p[FS_P_PHI_A] = (fs_real)g[FS_G_PHI_A];
    p[FS_P_PHI_B] = (fs_real)g[FS_G_PHI_B];
    p[FS_P_PSI_C] = (fs_real)g[FS_G_PSI_C];
    p[FS_P_PSI_D] = (fs_real)g[FS_G_PSI_D];
#else /* phi = psi = 1: unused without the Woo mode (_pack) */
    p[FS_P_PHI_A] = 0;
    p[FS_P_PHI_B] = 1;
    p[FS_P_PSI_C] = 0;
    p[FS_P_PSI_D] = 1;
#endif
}
