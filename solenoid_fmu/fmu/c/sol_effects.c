/* sol_effects.c: the effect sub-models' step (model.py play.play_step, integrate.ros2_ladder,
 * integrate.fx_substeps, SolenoidModel._step_fx).
 * Part of the model code of solenoid_fmu.c, which includes it (one translation unit). */
#include "sol_core.h"

/* ---- effect sub-models (model.py play.play_step, SolenoidModel._step_fx) ------------------- */
/* Advance the play operators to b [Wb] (in place) and return g(b) sum w_j (b - p_j) [A]. */
static double play_step(double *plays, double b)
{
    double acc = 0.0, g;
    int k;
    for (k = 0; k < SOL_N_PLAY; k++) {
        double lo = b - SOL_PLAY_R[k], hi = b + SOL_PLAY_R[k], q = plays[k];
        if (q < lo) q = lo;
        else if (q > hi) q = hi;
        plays[k] = q;
        acc += SOL_PLAY_W[k] * (b - q);
    }
    if (SOL_N_SHAPE == 0) return acc;
    if (b <= SOL_SHAPE_B[0]) g = SOL_SHAPE_G[0];
    else if (b >= SOL_SHAPE_B[SOL_N_SHAPE - 1]) g = SOL_SHAPE_G[SOL_N_SHAPE - 1];
    else {
        int lo = 0, hi = SOL_N_SHAPE - 1;   /* SOL_SHAPE_B[lo] <= b < SOL_SHAPE_B[hi] (bisect_right - 1) */
        while (hi - lo > 1) {
            int mid = (lo + hi) / 2;
            if (SOL_SHAPE_B[mid] <= b) lo = mid; else hi = mid;
        }
        g = SOL_SHAPE_G[lo] + (b - SOL_SHAPE_B[lo]) / (SOL_SHAPE_B[lo + 1] - SOL_SHAPE_B[lo])
            * (SOL_SHAPE_G[lo + 1] - SOL_SHAPE_G[lo]);
    }
    return g * acc;
}

/* One ROS2 sub-step of hs of the flux and the nl eddy-ladder currents ik (updated in place) in mass-matrix
 * form (model.py integrate.ros2_ladder): m dPsi/dt = b - cc (i_f(Psi) + ih + sum_k i_k),
 * tau_k di_k/dt = G_k dPsi/dt - i_k; the arrow system is solved in O(sections). Sets *pc when clamped. */
static double ros2_ladder(double psi, double *ik, double u, double cc, double m, double ih, double hs, double gh,
                          int nl, int j, double w, int *pc)
{
    const double pm = SOL_PSI_MAX;
    double a[LAD_ALLOC], z[LAD_ALLOC], i2[LAD_ALLOC], r[LAD_ALLOC], q[LAD_ALLOC];
    double v, d, f, den, f0, z0, p2, v2, q0, acc;
    int k;
    eval3(psi, j, w, &v, &d, &f);
    for (k = 0; k < nl; k++) a[k] = SOL_LAD_TAU[k] + gh;
    acc = 0.0;
    for (k = 0; k < nl; k++) acc += gh * cc * SOL_LAD_G[k] / a[k];
    den = m + gh * cc * d + acc;
    acc = 0.0;
    for (k = 0; k < nl; k++) acc += ik[k];
    f0 = u - cc * (v + ih + acc);
    for (k = 0; k < nl; k++) r[k] = -ik[k];
    acc = 0.0;
    for (k = 0; k < nl; k++) acc += r[k] / a[k];
    z0 = (f0 - gh * cc * acc) / den;
    for (k = 0; k < nl; k++) z[k] = (r[k] + SOL_LAD_G[k] * z0) / a[k];
    p2 = psi + hs * z0;
    for (k = 0; k < nl; k++) i2[k] = ik[k] + hs * z[k];
    v2 = if_value(p2, j, w);
    acc = 0.0;
    for (k = 0; k < nl; k++) acc += i2[k];
    f0 = u - cc * (v2 + ih + acc) - 2.0 * m * z0;
    for (k = 0; k < nl; k++) r[k] = -i2[k] - 2.0 * (SOL_LAD_TAU[k] * z[k] - SOL_LAD_G[k] * z0);
    acc = 0.0;
    for (k = 0; k < nl; k++) acc += r[k] / a[k];
    q0 = (f0 - gh * cc * acc) / den;
    for (k = 0; k < nl; k++) q[k] = (r[k] + SOL_LAD_G[k] * q0) / a[k];
    psi = psi + 1.5 * hs * z0 + 0.5 * hs * q0;
    for (k = 0; k < nl; k++) ik[k] = ik[k] + 1.5 * hs * z[k] + 0.5 * hs * q[k];
    if (psi > pm) { psi = pm; *pc = 1; }
    else if (psi < -pm) { psi = -pm; *pc = 1; }
    return psi;
}

/* One communication step with effect sub-models on (model.py SolenoidModel._step_fx, same arithmetic
 * and order). Equations (SI):
 *     U = R(T) i + e,  e = dPsi/dt,  R(T) = R (1 + alpha T)
 *     i = i_f(Psi, x) + i_h + G e + sum_k i_k,   tau_k di_k/dt = G_k e - i_k   (eddy ladder)
 *     i_h = gain g(Psi) sum_j w_j (Psi - play_j(Psi))                              (hysteresis)
 *     C_th dT/dt = R(T) i^2 - (T + T_0) / R_th      (heating; T_0 = T_start_excess_K above ambient)
 *     F = F(Psi, x) + F_fr,  F_fr -> +-F_c over |dx| ~ presliding                  (Dahl friction)
 * Flux and ladder currents: ROS2 in mass-matrix form (arrow system, O(sections)); hysteresis and
 * temperature explicitly after every sub-step; friction once per step. Inputs checked. */
static void sol_step_fx(Inst *in, double t_s, double h)
{
    Core *c = &in->core;
    double *s = c->s, *fx = c->fx, *plays = c->fx + FX_PLAY;
    const int voltage = c->voltage, heat = c->heat_on, hy = c->hyst_on, nl = c->lad_on ? SOL_N_LAD : 0;
    const double u = voltage ? c->u_V : c->i_A, x = c->x_m, R0 = c->R, G0 = c->G;
    const double alpha = c->alpha, Cth = c->Cth, Rth = c->Rth, T0 = c->T0, gain = c->gain;
    double ik[LAD_ALLOC] = {0.0};  /* initialized: with one section gcc -Werror=maybe-uninitialized refused it */
    double T = fx[FX_T_RISE_K], ih = fx[FX_I_HYST_A], psi0 = s[ST_PSI_WB], psi = psi0, hs, gh, nd, w, R, sik, i_f, d_end, force;
    double dpsi, ffr;
    long n, sub;
    int j, xc, pc = 0, k;
    x_cell(x, &j, &w, &xc);
    for (k = 0; k < nl; k++) ik[k] = fx[FX_LAD + k];
    nd = ceil(h / c->hsub - 1e-9);
    n = nd < 1.0 ? 1 : (long)nd;
    hs = h / (double)n;
    gh = ROS2_GAMMA * hs;
    for (sub = 0; sub < n; sub++) {
        double m, cc, psi_a = psi;
        R = heat ? R0 * (1.0 + alpha * T) : R0;
        m = voltage ? 1.0 + R * G0 : G0;
        cc = voltage ? R : 1.0;
        if (m == 0.0 && nl == 0) {
            psi = solve_psi(u - ih, j, w, psi, &pc);
        } else {
            psi = ros2_ladder(psi, ik, u, cc, m, ih, hs, gh, nl, j, w, &pc);
        }
        if (heat) {
            double i_sub = voltage ? (u - (psi - psi_a) / hs) / R : u;
            T += hs * (R * i_sub * i_sub - (T + T0) / Rth) / Cth;
        }
        if (hy) ih = gain * play_step(plays, psi);
    }
    eval3(psi, j, w, &i_f, &d_end, &force);
    R = heat ? R0 * (1.0 + alpha * T) : R0;
    sik = 0.0;
    for (k = 0; k < nl; k++) sik += ik[k];
    if (voltage) {
        dpsi = (u - R * (i_f + ih + sik)) / (1.0 + R * G0);
        s[ST_OUT_I_A] = i_f + ih + G0 * dpsi + sik;
        s[ST_OUT_U_V] = u;
    } else {
        dpsi = (psi - psi0) / h;
        s[ST_OUT_I_A] = u;
        s[ST_OUT_U_V] = R * u + dpsi;
    }
    ffr = fx[FX_F_FRICTION_N];
    if (c->fric_on) {
        double dx = x - fx[FX_X_PREV_M];
        if (dx != 0.0) {
            double target = dx > 0.0 ? c->fricN : -c->fricN;
            ffr = target + (ffr - target) * exp(-fabs(dx) / c->presl);
        }
    }
    s[ST_TIME_S] = t_s + h;
    s[ST_PSI_WB] = psi;
    s[ST_OUT_F_N] = force + ffr;
    s[ST_OUT_DPSI_DT_V] = dpsi;
    s[ST_OUT_I_EDDY_A] = G0 * dpsi + sik;
    fx[FX_T_RISE_K] = T;
    fx[FX_F_FRICTION_N] = ffr;
    fx[FX_X_PREV_M] = x;
    fx[FX_I_HYST_A] = ih;
    for (k = 0; k < nl; k++) fx[FX_LAD + k] = ik[k];
    finish(in, s, pc, i_f, x, xc, t_s + h);
}
