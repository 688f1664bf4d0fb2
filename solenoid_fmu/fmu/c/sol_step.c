/* sol_step.c: initialization and the co-simulation step without effects (model.py
 * SolenoidModel.initialize, step; integrate.ros2), and the excursion flags with their messages.
 * Part of the model code of solenoid_fmu.c, which includes it (one translation unit). */
#include "sol_core.h"

/* n ROS2 sub-steps of hs for m dPsi/dt = b - c i_f(Psi, x) (model.py integrate.ros2). */
static double ros2(double psi, double v, double d, double m, double b, double c, double hs, long n,
                   int j, double w, int *clamped)
{
    const double g = ROS2_GAMMA, pm = SOL_PSI_MAX;
    long sub;
    *clamped = 0;
    for (sub = 0; sub < n; sub++) {
        double W, k1, k2, p2, v2;
        if (sub) {
            double f;
            eval3(psi, j, w, &v, &d, &f);
        }
        W = m + g * hs * c * d;
        k1 = (b - c * v) / W;
        p2 = psi + hs * k1;
        v2 = if_value(p2, j, w);
        k2 = (b - c * v2 - 2.0 * m * k1) / W;
        psi = psi + 1.5 * hs * k1 + 0.5 * hs * k2;
        if (psi > pm) { psi = pm; *clamped = 1; }
        else if (psi < -pm) { psi = -pm; *clamped = 1; }
    }
    return psi;
}

/* ---- excursion flags and their messages (SolenoidModel._finish, _set_flag) --------------- */
static void set_flag(Inst *in, double *s, int k, int on, double i_f, double x_m, double t_s)
{
    if (on && s[k] == 0.0) {
        if (k == ST_EXCURSION_X)
            say(in, fmi2Warning, "t = %.9g s: x_m = %.6g m is outside the map's gap range [%.6g, %.6g] m; the "
                "lookups use the nearest edge until x returns into the range", t_s, x_m, SOL_X[0],
                SOL_X[SOL_N_X - 1]);
        else if (k == ST_EXCURSION_PSI)
            say(in, fmi2Warning, "t = %.9g s: |Psi| reached the map limit psi_max = %.6g Wb (coil current "
                "beyond the maps' range); Psi is held at the limit until the drive lets it return", t_s,
                SOL_PSI_MAX);
        else
            say(in, fmi2Warning, "t = %.9g s: |i_f| = %.6g A is beyond the current range of the FEM sweep "
                "(%.6g A); the map is linearly extrapolated there", t_s, fabs(i_f), SOL_I_FEM_MAX);
    }
    s[k] = on ? 1.0 : 0.0;
}

static void finish(Inst *in, double *s, int pc, double i_f, double x_m, int xc, double t_s)
{
    const double lim = SOL_I_FEM_MAX * (1.0 + 1e-9);
    int ext = (!pc) && (i_f > lim || -i_f > lim);
    if (xc != (s[ST_EXCURSION_X] != 0.0)) set_flag(in, s, ST_EXCURSION_X, xc, i_f, x_m, t_s);
    if (pc != (s[ST_EXCURSION_PSI] != 0.0)) set_flag(in, s, ST_EXCURSION_PSI, pc, i_f, x_m, t_s);
    if (ext != (s[ST_EXCURSION_EXTRAPOLATED] != 0.0)) set_flag(in, s, ST_EXCURSION_EXTRAPOLATED, ext, i_f, x_m, t_s);
}

/* model.py SolenoidModel.initialize: start state at t0 and the outputs there; 0 on error. */
static int initialize(Inst *in)
{
    Core *c = &in->core;
    double s[N_STATE], u, psi, i_f, dsl, force, dpsi, R, G;
    int j, xc, pc;
    double w;
    c->ready = 0;
    c->dirty = 1;
    if (!apply_params(in, 1)) return 0;
    c->dirty = 1;
    u = c->voltage ? c->u_V : c->i_A;
    if (!is_finite(u)) { say(in, fmi2Error, "initialization: %s must be finite, got %.17g", drive_name(c), u); return 0; }
    if (!is_finite(c->x_m)) { say(in, fmi2Error, "initialization: x_m must be finite, got %.17g", c->x_m); return 0; }
    if (!is_finite(c->t0_s)) { say(in, fmi2Error, "initialization: t0_s must be finite, got %.17g", c->t0_s); return 0; }
    R = c->R;
    G = c->G;
    memset(s, 0, sizeof s);
    s[ST_STATE_LAYOUT] = STATE_LAYOUT;
    x_cell(c->x_m, &j, &w, &xc);
    if (!c->voltage && G == 0.0) {
        psi = solve_psi(u, j, w, 0.0, &pc);
    } else {
        psi = c->Psi0;
        pc = fabs(psi) > SOL_PSI_MAX;
        if (pc) psi = copysign(SOL_PSI_MAX, psi);
    }
    eval3(psi, j, w, &i_f, &dsl, &force);
    if (c->voltage) {
        dpsi = (u - R * i_f) / (1.0 + R * G);
        s[ST_OUT_I_A] = i_f + G * dpsi;
        s[ST_OUT_U_V] = u;
    } else {
        dpsi = G > 0.0 ? (u - i_f) / G : 0.0;
        s[ST_OUT_I_A] = u;
        s[ST_OUT_U_V] = R * u + dpsi;
    }
    s[ST_TIME_S] = c->t0_s;
    s[ST_PSI_WB] = psi;
    s[ST_INITIALIZED] = 1.0;
    s[ST_OUT_F_N] = force;
    s[ST_OUT_DPSI_DT_V] = dpsi;
    s[ST_OUT_I_EDDY_A] = G * dpsi;
    finish(in, s, pc, i_f, c->x_m, xc, c->t0_s);
    memcpy(c->s, s, sizeof s);
    {
        int k;
        for (k = 0; k < N_FX; k++) c->fx[k] = 0.0;
        c->fx[FX_X_PREV_M] = c->x_m;
        for (k = FX_PLAY; k < N_FX; k++) c->fx[k] = psi;   /* plays neutral at the start flux */
    }
    c->me_time_s = c->t0_s;
    c->me_psi_Wb = psi;
    memset(c->me_lad, 0, sizeof c->me_lad);
    c->me_T = 0.0;
    c->ready = 1;
    c->dirty = 0;
    return 1;
}

/* model.py SolenoidModel.step: one communication step of h with inputs held. Inputs checked. */
static void sol_step(Inst *in, double t_s, double h)
{
    Core *c = &in->core;
    double *s = c->s;
    const double u = c->voltage ? c->u_V : c->i_A, x = c->x_m, m = c->m, R = c->R, G = c->G;
    double psi0 = s[ST_PSI_WB], psi, i_f, d_end, force, dpsi, w;
    int j, xc, pc;
    x_cell(x, &j, &w, &xc);
    if (m == 0.0) {
        psi = solve_psi(u, j, w, psi0, &pc);
    } else {
        double v0, d0, f0, nd = ceil(h * c->inv_hsub - 1e-9);
        long n = nd < 1.0 ? 1 : (long)nd;
        eval3(psi0, j, w, &v0, &d0, &f0);
        psi = ros2(psi0, v0, d0, m, u, c->c, h / (double)n, n, j, w, &pc);
    }
    eval3(psi, j, w, &i_f, &d_end, &force);
    if (c->voltage) {
        dpsi = (u - R * i_f) / m;
        s[ST_OUT_I_A] = i_f + G * dpsi;
        s[ST_OUT_U_V] = u;
    } else {
        dpsi = (psi - psi0) / h;
        s[ST_OUT_I_A] = u;
        s[ST_OUT_U_V] = R * u + dpsi;
    }
    s[ST_TIME_S] = t_s + h;
    s[ST_PSI_WB] = psi;
    s[ST_OUT_F_N] = force;
    s[ST_OUT_DPSI_DT_V] = dpsi;
    s[ST_OUT_I_EDDY_A] = G * dpsi;
    finish(in, s, pc, i_f, x, xc, t_s + h);
}
