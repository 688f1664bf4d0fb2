/* sol_lookup.c: the map lookup (model.py tables: x_cell, cell_cubic) and the safeguarded Newton
 * iteration of the algebraic case (tables.solve_psi).
 * Part of the model code of solenoid_fmu.c, which includes it (one translation unit). */
#include "sol_core.h"

/* ---- map lookup (model.py tables: MapTables.x_cell, cell_cubic, eval_cell) ----------------- */
static void x_cell(double x, int *j, double *w, int *clamped)
{
    int lo, hi;
    if (x <= SOL_X[0]) { *j = 0; *w = 0.0; *clamped = x < SOL_X[0]; return; }
    if (x >= SOL_X[SOL_N_X - 1]) { *j = SOL_N_X - 2; *w = 1.0; *clamped = x > SOL_X[SOL_N_X - 1]; return; }
    lo = 0;
    hi = SOL_N_X - 1;       /* SOL_X[lo] <= x < SOL_X[hi] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (SOL_X[mid] <= x) lo = mid; else hi = mid;
    }
    if (lo > SOL_N_X - 2) lo = SOL_N_X - 2;
    *j = lo;
    *w = (x - SOL_X[lo]) * SOL_INV_DX[lo];
    *clamped = 0;
}

/* Cell index and position t for |Psi| = a (clamped to psi_max). */
static int psi_cell(double a, double *t)
{
    double sc;
    int k;
    if (!(a <= SOL_PSI_MAX)) a = SOL_PSI_MAX;   /* also NaN: never a NaN table index */
    if (!(a >= 0.0)) a = 0.0;
    sc = a * SOL_INV_DPSI;
    k = (int)sc;
    if (k > SOL_N_PSI - 2) k = SOL_N_PSI - 2;
    if (k < 0) k = 0;
    *t = sc - k;
    return k;
}

/* i_f [A], d i_f / d Psi [A/Wb] and F [N] at (psi, x cell (j, w)); model.py tables.eval_cell. */
static void eval3(double psi, int j, double w, double *v, double *d, double *f)
{
    double t, c1, c2, c3, val;
    int k = psi_cell(psi < 0.0 ? -psi : psi, &t);
    const double *q = SOL_CI[k * (SOL_N_X - 1) + j];
    const double *r = SOL_CF[k * (SOL_N_X - 1) + j];
    c1 = q[1] + w * q[5];
    c2 = q[2] + w * q[6];
    c3 = q[3] + w * q[7];
    val = (q[0] + w * q[4]) + t * (c1 + t * (c2 + t * c3));
    *d = (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * SOL_INV_DPSI;
    *f = (r[0] + w * r[4]) + t * ((r[1] + w * r[5]) + t * ((r[2] + w * r[6]) + t * (r[3] + w * r[7])));
    *v = psi < 0.0 ? -val : val;
}

/* i_f and its slope for Psi >= 0 (model.py tables.cell_cubic on CI). */
static void if_slope(double a, int j, double w, double *v, double *d)
{
    double t, c0, c1, c2, c3;
    int k = psi_cell(a, &t);
    const double *q = SOL_CI[k * (SOL_N_X - 1) + j];
    c0 = q[0] + w * q[4];
    c1 = q[1] + w * q[5];
    c2 = q[2] + w * q[6];
    c3 = q[3] + w * q[7];
    *v = c0 + t * (c1 + t * (c2 + t * c3));
    *d = (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * SOL_INV_DPSI;
}

/* i_f value only (stage 2 of ROS2), same arithmetic as eval3's value. */
static double if_value(double p, int j, double w)
{
    double t, v;
    int k = psi_cell(p < 0.0 ? -p : p, &t);
    const double *q = SOL_CI[k * (SOL_N_X - 1) + j];
    v = (q[0] + w * q[4]) + t * ((q[1] + w * q[5]) + t * ((q[2] + w * q[6]) + t * (q[3] + w * q[7])));
    return p < 0.0 ? -v : v;
}

/* Solve i_f(Psi, x) = i_A (safeguarded Newton, model.py tables.solve_psi); returns Psi, sets *clamped. */
static double solve_psi(double i_A, int j, double w, double psi_guess, int *clamped)
{
    double target, sign, hi, lo, y, tol, v, d, g, g_hi;
    int it;
    *clamped = 0;
    if (i_A == 0.0) return 0.0;
    target = fabs(i_A);
    sign = i_A < 0.0 ? -1.0 : 1.0;
    hi = SOL_PSI_MAX;
    if_slope(hi, j, w, &v, &d);
    g_hi = v - target;
    if (g_hi <= 0.0) { *clamped = g_hi < 0.0; return sign * hi; }
    lo = 0.0;
    y = fabs(psi_guess);
    if (!(lo < y && y < hi)) y = 0.5 * hi;
    tol = NEWTON_TOL_REL * hi;
    for (it = 0; it < NEWTON_MAX_ITER; it++) {
        double y_new, step;
        if_slope(y, j, w, &v, &d);
        g = v - target;
        if (g == 0.0) break;
        if (g < 0.0) lo = y; else hi = y;
        y_new = d > 0.0 ? y - g / d : 0.5 * (lo + hi);
        if (!(lo < y_new && y_new < hi)) {
            if (fabs(y_new - y) <= tol) break; /* converged onto the bracket's end by rounding: y is the root */
            y_new = 0.5 * (lo + hi);
        }
        step = fabs(y_new - y);
        y = y_new;
        if (step <= tol) break;
    }
    return sign * y;
}
