/* sol_me.c: the model-exchange evaluation: outputs and derivatives at (states, inputs), memory
 * of the rate-independent effects committed at accepted steps.
 * Part of the model code of solenoid_fmu.c, which includes it (one translation unit). */
#include "sol_core.h"

/* ---- model exchange evaluation ------------------------------------------------------------- */
typedef struct { double i, U, F, psi, dpsi, ieddy, der[NX]; int pc, xc; double i_f, ih, T; } MeOut;

/* Model exchange: outputs and derivatives of the continuous states at (states, inputs).
 * Paper eqs. (1)-(3) with the effects solved for e = dPsi/dt (R = R(T) with heating):
 *   voltage:          e = (U - R (i_f + i_h + sum i_k)) / (1 + R G),  i = i_f + i_h + G e + sum i_k
 *   current, G > 0:   e = (i - i_f - i_h - sum i_k) / G,               U = R i + e
 *   current, G = 0 (no ladder): i_f(Psi, x) = i - i_h algebraic, e = 0, U = R i
 *   der(i_k) = (G_k e - i_k) / tau_k,   der(T) = (R i^2 - (T + T_0) / R_th) / C_th
 * Hysteresis and friction are rate independent: i_h is the play operator moved from its committed
 * state to the current Psi, F_fr the Dahl force moved from the committed (F_fr, x) to the current x;
 * both are exact for monotone Psi and x between accepted steps and continuous in the states, so no
 * events are needed. fmi2CompletedIntegratorStep commits them (me_commit). Current mode with G = 0
 * (no ladder) solves i_f(Psi, x) = i - i_h with the committed i_h (one accepted step behind). */
static void me_eval(const Core *c, MeOut *o)
{
    const double u = c->voltage ? c->u_V : c->i_A, G = c->G, pm = SOL_PSI_MAX;
    const int nl = c->lad_on ? SOL_N_LAD : 0;
    double psi = c->me_psi_Wb, i_f, d, f, w, sik = 0.0, ih = c->fx[FX_I_HYST_A], T = c->heat_on ? c->me_T : 0.0, R;
    int j, k;
    R = c->heat_on ? c->R * (1.0 + c->alpha * T) : c->R;
    for (k = 0; k < NX; k++) o->der[k] = 0.0;
    for (k = 0; k < nl; k++) sik += c->me_lad[k];
    x_cell(c->x_m, &j, &w, &o->xc);
    if (!c->voltage && G == 0.0 && nl == 0) {
        psi = solve_psi(u - ih, j, w, 0.0, &o->pc);
        eval3(psi, j, w, &i_f, &d, &f);
        o->dpsi = 0.0;
        o->i = u;
        o->U = R * u;
    } else {
        o->pc = fabs(psi) >= pm;
        if (psi > pm) psi = pm;
        else if (psi < -pm) psi = -pm;
        eval3(psi, j, w, &i_f, &d, &f);
        if (c->hyst_on) {
            double plays[PLAY_ALLOC];
            memcpy(plays, c->fx + FX_PLAY, sizeof plays);
            ih = c->gain * play_step(plays, psi);
        }
        if (c->voltage) {
            o->dpsi = (u - R * (i_f + ih + sik)) / (1.0 + R * G);
            o->i = i_f + ih + G * o->dpsi + sik;
            o->U = u;
        } else {
            o->dpsi = (u - i_f - ih - sik) / G;   /* G = 0 with the ladder is refused in me_prepare */
            o->i = u;
            o->U = R * u + o->dpsi;
        }
        o->der[0] = o->dpsi;
        if (o->pc && ((psi > 0.0 && o->der[0] > 0.0) || (psi < 0.0 && o->der[0] < 0.0))) o->der[0] = 0.0;
    }
    for (k = 0; k < nl; k++) o->der[ME_LAD + k] = (SOL_LAD_G[k] * o->dpsi - c->me_lad[k]) / SOL_LAD_TAU[k];
    if (SOL_FX_HEAT && c->heat_on) o->der[NX - 1] = (R * o->i * o->i - (T + c->T0) / c->Rth) / c->Cth;
    o->psi = psi;
    o->F = f + c->fx[FX_F_FRICTION_N];
    if (c->fric_on && c->x_m != c->fx[FX_X_PREV_M]) {
        double dx = c->x_m - c->fx[FX_X_PREV_M], target = dx > 0.0 ? c->fricN : -c->fricN;
        o->F = f + (target + (c->fx[FX_F_FRICTION_N] - target) * exp(-fabs(dx) / c->presl));
    }
    o->ieddy = G * o->dpsi + sik;
    o->i_f = i_f;
    o->ih = ih;
    o->T = T;
}

static int me_mode(const Inst *in)
{
    return in->type == fmi2ModelExchange && (in->phase == PH_EVENT || in->phase == PH_CONT)
        && in->core.ready;
}

/* Check the inputs and apply changed tunable parameters before a model-exchange evaluation. */
static fmi2Status me_prepare(Inst *in, const char *where)
{
    Core *c = &in->core;
    double u = c->voltage ? c->u_V : c->i_A;
    if (!is_finite(u)) { say(in, fmi2Error, "%s at t = %.17g s: input %s = %.17g is not finite", where, c->me_time_s, drive_name(c), u); return fmi2Error; }
    if (!is_finite(c->x_m)) { say(in, fmi2Error, "%s at t = %.17g s: input x_m = %.17g is not finite", where, c->me_time_s, c->x_m); return fmi2Error; }
    if (c->dirty && !apply_params(in, 0)) return fmi2Error;
    if (!c->voltage && c->G == 0.0 && c->lad_on) {
        say(in, fmi2Error, "%s: model exchange does not support current mode with G_eddy_S = 0 and the eddy ladder on "
            "(a differential-algebraic system); use co-simulation, G_eddy_S > 0 or eddy_ladder_on = false", where);
        return fmi2Error;
    }
    return fmi2OK;
}

/* Commit the hysteresis and friction memory at an accepted model-exchange point (see me_eval): the
 * play operators move to the current Psi, the friction force and x_prev to the current x. The
 * outputs do not change by this (the operators are idempotent), so no event is needed. */
static void me_commit(Core *c)
{
    MeOut o;
    if (!SOL_HAS_FX) return;
    me_eval(c, &o);
    if (c->hyst_on) c->fx[FX_I_HYST_A] = c->gain * play_step(c->fx + FX_PLAY, o.psi);
    if (c->fric_on) {
        double dx = c->x_m - c->fx[FX_X_PREV_M];
        if (dx != 0.0) {
            double target = dx > 0.0 ? c->fricN : -c->fricN;
            c->fx[FX_F_FRICTION_N] = target + (c->fx[FX_F_FRICTION_N] - target) * exp(-fabs(dx) / c->presl);
        }
    }
    c->fx[FX_X_PREV_M] = c->x_m;
}

/* Update the excursion flags at an accepted model-exchange point (logs once per excursion). */
static void me_flags(Inst *in)
{
    MeOut o;
    me_eval(&in->core, &o);
    finish(in, in->core.s, o.pc, o.i_f, in->core.x_m, o.xc, in->core.me_time_s);
}
