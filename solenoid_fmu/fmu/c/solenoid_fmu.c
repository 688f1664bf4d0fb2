/*
 * solenoid-fmu native FMU: FMI 2.0 co-simulation and model exchange in one binary.
 *
 * The real-time lumped solenoid model of solenoid_fmu/realtime/model.py (paper eqs. 1-3, SI units):
 *
 *     U = R i + dPsi/dt                               paper eq. (1)
 *     i = i_f(Psi, x) + G dPsi/dt                     paper eq. (2), G = G_eddy [S]
 *     F = F(Psi, x)                                   paper eq. (3)
 *
 * This file reproduces model.py step for step (same lookups, same ROS2 sub-steps, same Newton
 * iteration, same arithmetic order), so that the co-simulation outputs agree with model.py to
 * rounding. It is written in C99 without allocation outside fmi2Instantiate / fmi2GetFMUstate /
 * fmi2DeSerializeFMUstate (all through the importer's allocateMemory callback); the maps are the
 * constant arrays of the generated header solenoid_maps.h (cell cubics of model.MapTables.tables(),
 * never recomputed here). Compile: cc -std=c99 -O2 -shared -fPIC -ffp-contract=off solenoid_fmu.c -lm
 *
 * Model exchange: one continuous state psi_state_Wb (vr 15) with derivative der(psi_state_Wb)
 * (vr 16). Voltage mode: dPsi/dt = (U - R i_f) / (1 + R G). Current mode, G > 0:
 * dPsi/dt = (i - i_f) / G. Current mode with G = 0 is algebraic (i_f(Psi, x) = i): the state is
 * then frozen (derivative 0) and Psi is solved from the input at every evaluation by the same
 * safeguarded Newton iteration as co-simulation; dpsi_dt_V and i_eddy_A are 0 and U_out_V = R i
 * (an FMU gets no di/dt in model exchange). |Psi| at psi_max: the derivative is held at 0 while it
 * points outwards (the state does not wind up), as in co-simulation.
 *
 * Effect sub-models (maps.json effects; model.py _step_fx): hysteresis (play operators on Psi),
 * eddy ladder (R-L sections beside G), heating (R(T), first-order thermal model) and friction (Dahl in
 * x), switched by Boolean parameters; their data are the SOL_LAD_* / SOL_PLAY_* / SOL_SHAPE_* arrays
 * of solenoid_maps.h and their states Core.fx (model.py EFFECT_STATE_NAMES, ladder_k, play_k). With
 * any switch on, fmi2DoStep runs sol_step_fx (same arithmetic and order as model.py). Model exchange
 * with effects: continuous states Psi, the ladder currents and the temperature rise; hysteresis and
 * friction evaluated from their memory committed at accepted steps (see me_eval). New states go to
 * Core (the FMU state copies Core as a whole, so get/set/serialize follow automatically).
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "solenoid_model.h"
#include "solenoid_maps.h"

/* What this file implements. solenoid_model.h is generated from model.py (constants, enum ST_* of
 * STATE_NAMES, enum FX_* of EFFECT_STATE_NAMES, enum VR_* of the interface table): when model.py has
 * moved on (new states, parameters or effects), solenoid_fmu.fmu.c_sources.check_implemented refuses to
 * build, and so does the compiler. Port the new effects here (struct Core, sol_step), then update these. */
#define IMPLEMENTS_STATE_LAYOUT 1
#define IMPLEMENTS_N_PARAMS 15
#define IMPLEMENTS_N_EFFECTS 4
#define IMPLEMENTS_N_EFFECT_STATES 4
#if STATE_LAYOUT != IMPLEMENTS_STATE_LAYOUT || SOL_N_PARAMS != IMPLEMENTS_N_PARAMS \
    || SOL_N_EFFECTS != IMPLEMENTS_N_EFFECTS || SOL_N_EFFECT_STATES != IMPLEMENTS_N_EFFECT_STATES
#error "solenoid_model.h (model.py) has states, parameters or effects this file lacks: port the new effects"
#endif

#define FX_PLAY (FX_LAD + SOL_N_LAD)
#define N_FX (FX_PLAY + SOL_N_PLAY)
#define LAD_ALLOC (SOL_N_LAD > 0 ? SOL_N_LAD : 1)
#define PLAY_ALLOC (SOL_N_PLAY > 0 ? SOL_N_PLAY : 1)

/* Value references: enum VR_* of solenoid_model.h (positions in solenoid_fmu.fmu.interface.interface_for:
 * VARIABLES, then EFFECT_VARIABLES when the maps carry effects); then the model-exchange locals. */
#define N_VR_IFACE (SOL_HAS_FX ? SOL_N_VR_FX : SOL_N_VR)
#define VR_PSI_STATE ((fmi2ValueReference)N_VR_IFACE)
/* Model exchange continuous states: Psi, the eddy-ladder currents, the temperature rise. */
#define ME_LAD 1
#define ME_T (ME_LAD + SOL_N_LAD)
#define NX (ME_T + SOL_FX_HEAT)
#define VR_DER_PSI_STATE ((fmi2ValueReference)(N_VR_IFACE + NX))

enum { PH_INSTANTIATED, PH_INIT, PH_STEP, PH_EVENT, PH_CONT, PH_TERMINATED };

/* Everything that makes up the FMU state (copied whole by fmi2GetFMUstate; plain data only). */
typedef struct {
    double u_V, i_A, x_m;                       /* inputs as set */
    double R_set, G_set, Psi0_set, hsub_set;    /* parameters as set */
    int drive_set;
    int voltage;                                /* parameters in use (model.py _fast) */
    double R, G, m, c, inv_hsub, Psi0, hsub;
    double t0_s;
    int dirty, ready;
    double s[N_STATE];                          /* model.py's state vector */
    /* effect sub-models: switches and scalars as set, then in use (model.py params) */
    int hyst_set, lad_set, heat_set, fric_set;
    double gain_set, Cth_set, Rth_set, alpha_set, fricN_set, presl_set;
    int fx_on, hyst_on, lad_on, heat_on, fric_on;
    double gain, Cth, Rth, alpha, fricN, presl;
    double fx[N_FX];                            /* effect states (model.py SolenoidModel._fx) */
    double me_time_s, me_psi_Wb;                /* model exchange: time and continuous state */
    double me_lad[LAD_ALLOC], me_T;             /* model exchange: ladder currents [A], T rise [K] */
} Core;

typedef struct {
    Core core;
    fmi2CallbackFunctions cb;
    char *name;
    int logging_on;
    int type;   /* fmi2ModelExchange or fmi2CoSimulation */
    int phase;
    void **states;   /* the FMU states this instance allocated and has not freed (GetFMUstate, DeSerialize) */
    size_t n_states, cap_states;
} Inst;

#define SERIAL_MAGIC "SOLFMUS1"

/* ---- logging ------------------------------------------------------------------------------ */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
static void say(Inst *in, fmi2Status st, const char *fmt, ...)
{
    char buf[600];
    va_list ap;
    const char *cat;
    if (in == NULL || in->cb.logger == NULL) return;
    if (st < fmi2Error && !in->logging_on) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    cat = st == fmi2Warning ? "logStatusWarning" : st == fmi2Discard ? "logStatusDiscard"
        : st == fmi2Error ? "logStatusError" : st == fmi2Fatal ? "logStatusFatal" : "logAll";
    in->cb.logger(in->cb.componentEnvironment, in->name, st, cat, "%s", buf);
}

static int is_finite(double v) { return v - v == 0.0; }   /* false for NaN and +-inf */

/* ---- map lookup (model.py MapTables.x_cell, _eval, _cubic) --------------------------------- */
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

/* i_f [A], d i_f / d Psi [A/Wb] and F [N] at (psi, x cell (j, w)); model.py _eval. */
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

/* i_f and its slope for Psi >= 0 (model.py MapTables._cubic on CI). */
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

/* Solve i_f(Psi, x) = i_A (safeguarded Newton, model.py _solve_psi); returns Psi, sets *clamped. */
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
        if (!(lo < y_new && y_new < hi)) y_new = 0.5 * (lo + hi);
        step = fabs(y_new - y);
        y = y_new;
        if (step <= tol) break;
    }
    return sign * y;
}

/* n ROS2 sub-steps of hs for m dPsi/dt = b - c i_f(Psi, x) (model.py _ros2). */
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

/* ---- excursion flags and their messages (model.py _finish / _set_flag) --------------------- */
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

/* ---- parameters ----------------------------------------------------------------------------- */
/* An effect scalar: finite and >= 0 (> 0 when positive); 0 (logged) otherwise (model.py set_params). */
static int fx_scalar_ok(Inst *in, const char *name, double v, int positive)
{
    if (!is_finite(v)) { say(in, fmi2Error, "%s must be finite, got %.17g", name, v); return 0; }
    if (v < 0.0 || (positive && v == 0.0)) {
        say(in, fmi2Error, "%s must be > 0 (>= 0 for alpha and friction), got %.17g", name, v);
        return 0;
    }
    return 1;
}

/* A switch may only be on when the maps carry that effect (model.py set_params). */
static int fx_switch_ok(Inst *in, const char *name, const char *effect, int on, int available)
{
    if (on && !available) {
        say(in, fmi2Error, "%s: the maps carry no '%s' effect (maps.json 'effects')", name, effect);
        return 0;
    }
    return 1;
}

/* Validate and apply the parameters as set (all, or only the tunable R, G, hyst_gain, friction_N);
 * 0 on error (nothing applied). */
static int apply_params(Inst *in, int all)
{
    Core *c = &in->core;
    double R = c->R_set, G = c->G_set;
    int drive = all ? c->drive_set : (c->voltage ? DRIVE_VOLTAGE : DRIVE_CURRENT);
    if (!is_finite(R)) { say(in, fmi2Error, "R_ohm must be finite, got %.17g", R); return 0; }
    if (R <= 0.0) { say(in, fmi2Error, "R_ohm must be > 0 ohm, got %.17g", R); return 0; }
    if (!is_finite(G)) { say(in, fmi2Error, "G_eddy_S must be finite, got %.17g", G); return 0; }
    if (G < 0.0) { say(in, fmi2Error, "G_eddy_S must be >= 0 S, got %.17g", G); return 0; }
    if (SOL_HAS_FX) {
        if (!is_finite(c->gain_set)) { say(in, fmi2Error, "hyst_gain must be finite, got %.17g", c->gain_set); return 0; }
        if (c->gain_set < 0.0) { say(in, fmi2Error, "hyst_gain must be >= 0, got %.17g", c->gain_set); return 0; }
        if (!fx_scalar_ok(in, "friction_N", c->fricN_set, 0)) return 0;
    }
    if (all && SOL_HAS_FX) {
        if (!fx_switch_ok(in, "hysteresis_on", "hysteresis", c->hyst_set, SOL_FX_HYST)
            || !fx_switch_ok(in, "eddy_ladder_on", "eddy_ladder", c->lad_set, SOL_FX_LAD)
            || !fx_switch_ok(in, "heating_on", "heating", c->heat_set, SOL_FX_HEAT)
            || !fx_switch_ok(in, "friction_on", "friction", c->fric_set, SOL_FX_FRIC)
            || !fx_scalar_ok(in, "C_th_J_per_K", c->Cth_set, 1) || !fx_scalar_ok(in, "R_th_K_per_W", c->Rth_set, 1)
            || !fx_scalar_ok(in, "alpha_per_K", c->alpha_set, 0) || !fx_scalar_ok(in, "presliding_m", c->presl_set, 1))
            return 0;
    }
    if (all) {
        if (drive != DRIVE_VOLTAGE && drive != DRIVE_CURRENT) {
            say(in, fmi2Error, "drive_mode must be 1 (voltage) or 2 (current), got %d", drive);
            return 0;
        }
        if (!is_finite(c->Psi0_set)) { say(in, fmi2Error, "Psi0_Wb must be finite, got %.17g", c->Psi0_set); return 0; }
        if (!is_finite(c->hsub_set) || c->hsub_set <= 0.0) {
            say(in, fmi2Error, "h_sub_max_s must be finite and > 0 s, got %.17g", c->hsub_set);
            return 0;
        }
        c->Psi0 = c->Psi0_set;
        c->hsub = c->hsub_set;
        c->inv_hsub = 1.0 / c->hsub;
        c->hyst_on = c->hyst_set;
        c->lad_on = c->lad_set;
        c->heat_on = c->heat_set;
        c->fric_on = c->fric_set;
        c->fx_on = c->hyst_on || c->lad_on || c->heat_on || c->fric_on;
        c->Cth = c->Cth_set;
        c->Rth = c->Rth_set;
        c->alpha = c->alpha_set;
        c->presl = c->presl_set;
    }
    c->gain = c->gain_set;
    c->fricN = c->fricN_set;
    c->voltage = drive == DRIVE_VOLTAGE;
    c->R = R;
    c->G = G;
    c->m = c->voltage ? 1.0 + R * G : G;
    c->c = c->voltage ? R : 1.0;
    c->dirty = 0;
    return 1;
}

static const char *drive_name(const Core *c) { return c->voltage ? "U_V" : "i_A"; }

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

/* ---- effect sub-models (model.py play_step, SolenoidModel._step_fx) ------------------------ */
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

/* One communication step with effect sub-models on (model.py SolenoidModel._step_fx, same arithmetic
 * and order). Equations (SI):
 *     U = R(T) i + e,  e = dPsi/dt,  R(T) = R (1 + alpha T)
 *     i = i_f(Psi, x) + i_h + G e + sum_k i_k,   tau_k di_k/dt = G_k e - i_k   (eddy ladder)
 *     i_h = gain g(Psi) sum_j w_j (Psi - play_j(Psi))                              (hysteresis)
 *     C_th dT/dt = R(T) i^2 - T / R_th                                             (heating)
 *     F = F(Psi, x) + F_fr,  F_fr -> +-F_c over |dx| ~ presliding                  (Dahl friction)
 * Flux and ladder currents: ROS2 in mass-matrix form (arrow system, O(sections)); hysteresis and
 * temperature explicitly after every sub-step; friction once per step. Inputs checked. */
static void sol_step_fx(Inst *in, double t_s, double h)
{
    Core *c = &in->core;
    double *s = c->s, *fx = c->fx, *plays = c->fx + FX_PLAY;
    const int voltage = c->voltage, heat = c->heat_on, hy = c->hyst_on, nl = c->lad_on ? SOL_N_LAD : 0;
    const double u = voltage ? c->u_V : c->i_A, x = c->x_m, R0 = c->R, G0 = c->G;
    const double alpha = c->alpha, Cth = c->Cth, Rth = c->Rth, gain = c->gain, pm = SOL_PSI_MAX;
    double ik[LAD_ALLOC], a[LAD_ALLOC], z[LAD_ALLOC], i2[LAD_ALLOC], r[LAD_ALLOC], q[LAD_ALLOC];
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
            double v, d, f, den, f0, z0, p2, v2, q0, acc;
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
            if (psi > pm) { psi = pm; pc = 1; }
            else if (psi < -pm) { psi = -pm; pc = 1; }
        }
        if (heat) {
            double i_sub = voltage ? (u - (psi - psi_a) / hs) / R : u;
            T += hs * (R * i_sub * i_sub - T / Rth) / Cth;
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

/* ---- model exchange evaluation ------------------------------------------------------------- */
typedef struct { double i, U, F, psi, dpsi, ieddy, der[NX]; int pc, xc; double i_f, ih, T; } MeOut;

/* Model exchange: outputs and derivatives of the continuous states at (states, inputs).
 * Paper eqs. (1)-(3) with the effects solved for e = dPsi/dt (R = R(T) with heating):
 *   voltage:          e = (U - R (i_f + i_h + sum i_k)) / (1 + R G),  i = i_f + i_h + G e + sum i_k
 *   current, G > 0:   e = (i - i_f - i_h - sum i_k) / G,               U = R i + e
 *   current, G = 0 (no ladder): i_f(Psi, x) = i - i_h algebraic, e = 0, U = R i
 *   der(i_k) = (G_k e - i_k) / tau_k,   der(T) = (R i^2 - T / R_th) / C_th
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
    if (SOL_FX_HEAT && c->heat_on) o->der[NX - 1] = (R * o->i * o->i - T / c->Rth) / c->Cth;
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

/* ---- instance life cycle -------------------------------------------------------------------- */
static void reset_core(Core *c)
{
    memset(c, 0, sizeof *c);
    c->u_V = 0.0;
    c->i_A = 0.0;
    c->x_m = SOL_X_START;
    c->R_set = SOL_R_OHM_DEFAULT;
    c->G_set = SOL_G_EDDY_S_DEFAULT;
    c->Psi0_set = SOL_PSI0_WB_DEFAULT;
    c->hsub_set = SOL_H_SUB_MAX_S_DEFAULT;
    c->drive_set = SOL_DRIVE_MODE_DEFAULT;
    c->voltage = SOL_DRIVE_MODE_DEFAULT == DRIVE_VOLTAGE;
    c->R = SOL_R_OHM_DEFAULT;
    c->G = SOL_G_EDDY_S_DEFAULT;
    c->m = c->voltage ? 1.0 + c->R * c->G : c->G;
    c->c = c->voltage ? c->R : 1.0;
    c->hsub = SOL_H_SUB_MAX_S_DEFAULT;
    c->inv_hsub = 1.0 / SOL_H_SUB_MAX_S_DEFAULT;
    c->hyst_set = SOL_HYSTERESIS_ON_DEFAULT;
    c->lad_set = SOL_EDDY_LADDER_ON_DEFAULT;
    c->heat_set = SOL_HEATING_ON_DEFAULT;
    c->fric_set = SOL_FRICTION_ON_DEFAULT;
    c->gain_set = SOL_HYST_GAIN_DEFAULT;
    c->Cth_set = SOL_C_TH_J_PER_K_DEFAULT;
    c->Rth_set = SOL_R_TH_K_PER_W_DEFAULT;
    c->alpha_set = SOL_ALPHA_PER_K_DEFAULT;
    c->fricN_set = SOL_FRICTION_N_DEFAULT;
    c->presl_set = SOL_PRESLIDING_M_DEFAULT;
    c->dirty = 1;
    c->ready = 0;
    c->s[ST_STATE_LAYOUT] = STATE_LAYOUT;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Inst *in;
    size_t len;
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL || functions->freeMemory == NULL) return NULL;
    if (fmuGUID == NULL || strcmp(fmuGUID, SOL_GUID) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "GUID %s does not match this FMU's %s", fmuGUID ? fmuGUID : "(null)", SOL_GUID);
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) return NULL;
    in = (Inst *)functions->allocateMemory(1, sizeof(Inst));
    if (in == NULL) return NULL;
    len = instanceName ? strlen(instanceName) : 0;
    in->name = (char *)functions->allocateMemory(len + 1, 1);
    if (in->name == NULL) { functions->freeMemory(in); return NULL; }
    if (len) memcpy(in->name, instanceName, len);
    in->name[len] = '\0';
    in->cb = *functions;
    in->logging_on = loggingOn ? 1 : 0;
    in->type = fmuType;
    in->states = NULL;
    in->n_states = in->cap_states = 0;
    in->phase = PH_INSTANTIATED;
    reset_core(&in->core);
    return in;
}

void fmi2FreeInstance(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    fmi2CallbackFreeMemory fr;
    if (in == NULL) return;
    fr = in->cb.freeMemory;
    if (in->states != NULL) fr(in->states);
    fr(in->name);
    fr(in);
}

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    Inst *in = (Inst *)comp;
    (void)nCategories;
    (void)categories;
    if (in == NULL) return fmi2Error;
    in->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Inst *in = (Inst *)comp;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (in == NULL) return fmi2Error;
    if (in->phase != PH_INSTANTIATED) { say(in, fmi2Error, "fmi2SetupExperiment only after fmi2Instantiate"); return fmi2Error; }
    in->core.t0_s = startTime;
    in->core.me_time_s = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    if (in->phase != PH_INSTANTIATED) { say(in, fmi2Error, "fmi2EnterInitializationMode only after fmi2Instantiate"); return fmi2Error; }
    in->phase = PH_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    if (in->phase != PH_INIT) { say(in, fmi2Error, "fmi2ExitInitializationMode outside initialization mode"); return fmi2Error; }
    in->phase = in->type == fmi2CoSimulation ? PH_STEP : PH_EVENT;
    return initialize(in) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    in->phase = PH_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    reset_core(&in->core);
    in->phase = PH_INSTANTIATED;
    return fmi2OK;
}

/* ---- variable access -------------------------------------------------------------------- */
static int is_fixed_phase(const Inst *in) { return in->phase == PH_INSTANTIATED || in->phase == PH_INIT; }

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Inst *in = (Inst *)comp;
    Core *c;
    MeOut o;
    size_t k;
    int me;
    if (in == NULL || (nvr && (vr == NULL || value == NULL))) return fmi2Error;
    c = &in->core;
    me = me_mode(in);
    if (me) {
        if (me_prepare(in, "fmi2GetReal") != fmi2OK) return fmi2Error;
        me_eval(c, &o);
    }
    for (k = 0; k < nvr; k++) {
        switch (vr[k]) {
        case VR_U_V: value[k] = c->u_V; break;
        case VR_I_A: value[k] = c->i_A; break;
        case VR_X_M: value[k] = c->x_m; break;
        case VR_I_OUT_A: value[k] = me ? o.i : c->s[ST_OUT_I_A]; break;
        case VR_U_OUT_V: value[k] = me ? o.U : c->s[ST_OUT_U_V]; break;
        case VR_F_N: value[k] = me ? o.F : c->s[ST_OUT_F_N]; break;
        case VR_PSI_WB: value[k] = me ? o.psi : c->s[ST_PSI_WB]; break;
        case VR_DPSI_DT_V: value[k] = me ? o.dpsi : c->s[ST_OUT_DPSI_DT_V]; break;
        case VR_I_EDDY_A: value[k] = me ? o.ieddy : c->s[ST_OUT_I_EDDY_A]; break;
        case VR_R_OHM: value[k] = c->R_set; break;
        case VR_G_EDDY_S: value[k] = c->G_set; break;
        case VR_PSI0_WB: value[k] = c->Psi0_set; break;
        case VR_H_SUB_MAX_S: value[k] = c->hsub_set; break;
#if SOL_HAS_FX
        case VR_I_HYST_A: value[k] = me ? o.ih : c->fx[FX_I_HYST_A]; break;
        case VR_T_RISE_K: value[k] = me ? o.T : c->fx[FX_T_RISE_K]; break;
        case VR_HYST_GAIN: value[k] = c->gain_set; break;
        case VR_C_TH_J_PER_K: value[k] = c->Cth_set; break;
        case VR_R_TH_K_PER_W: value[k] = c->Rth_set; break;
        case VR_ALPHA_PER_K: value[k] = c->alpha_set; break;
        case VR_FRICTION_N: value[k] = c->fricN_set; break;
        case VR_PRESLIDING_M: value[k] = c->presl_set; break;
#endif
        default:
            if (vr[k] >= VR_PSI_STATE && vr[k] < VR_PSI_STATE + 2 * NX) {
                /* model-exchange locals: states, then derivatives. In co-simulation: Psi and the effect
                 * states of the last step; derivatives: dPsi/dt of the last step, 0 for the others. */
                int kk = (int)(vr[k] - VR_PSI_STATE);
                if (kk < NX) {
                    double xs = kk == 0 ? c->me_psi_Wb : kk < ME_T ? c->me_lad[kk - ME_LAD] : c->me_T;
                    double cs = kk == 0 ? c->s[ST_PSI_WB] : kk < ME_T ? c->fx[FX_LAD + kk - ME_LAD] : c->fx[FX_T_RISE_K];
                    value[k] = me ? xs : cs;
                } else {
                    value[k] = me ? o.der[kk - NX] : kk == NX ? c->s[ST_OUT_DPSI_DT_V] : 0.0;
                }
                break;
            }
            say(in, fmi2Error, "fmi2GetReal: no Real variable with value reference %u", (unsigned)vr[k]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Inst *in = (Inst *)comp;
    size_t k;
    if (in == NULL || (nvr && (vr == NULL || value == NULL))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_DRIVE_MODE) {
            say(in, fmi2Error, "fmi2GetInteger: no Integer/Enumeration variable with value reference %u",
                (unsigned)vr[k]);
            return fmi2Error;
        }
        value[k] = in->core.drive_set;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    Inst *in = (Inst *)comp;
    size_t k;
    if (in == NULL || (nvr && (vr == NULL || value == NULL))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        const Core *c = &in->core;
        switch (vr[k]) {
        case VR_OUT_OF_MAP: value[k] = (c->s[ST_EXCURSION_PSI] != 0.0 || c->s[ST_EXCURSION_X] != 0.0) ? fmi2True : fmi2False; break;
#if SOL_HAS_FX
        case VR_HYSTERESIS_ON: value[k] = c->hyst_set ? fmi2True : fmi2False; break;
        case VR_EDDY_LADDER_ON: value[k] = c->lad_set ? fmi2True : fmi2False; break;
        case VR_HEATING_ON: value[k] = c->heat_set ? fmi2True : fmi2False; break;
        case VR_FRICTION_ON: value[k] = c->fric_set ? fmi2True : fmi2False; break;
#endif
        default:
            say(in, fmi2Error, "fmi2GetBoolean: no Boolean variable with value reference %u", (unsigned)vr[k]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    Inst *in = (Inst *)comp;
    (void)vr;
    (void)value;
    if (in == NULL) return fmi2Error;
    if (nvr) { say(in, fmi2Error, "fmi2GetString: this FMU has no String variables"); return fmi2Error; }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Inst *in = (Inst *)comp;
    Core *c;
    size_t k;
    if (in == NULL || (nvr && (vr == NULL || value == NULL))) return fmi2Error;
    c = &in->core;
    for (k = 0; k < nvr; k++) {
        double v = value[k];
        switch (vr[k]) {
        case VR_U_V: c->u_V = v; break;
        case VR_I_A: c->i_A = v; break;
        case VR_X_M: c->x_m = v; break;
        case VR_R_OHM: c->R_set = v; c->dirty = 1; break;
        case VR_G_EDDY_S: c->G_set = v; c->dirty = 1; break;
        case VR_PSI0_WB:
        case VR_H_SUB_MAX_S:
            if (!is_fixed_phase(in)) {
                say(in, fmi2Error, "fmi2SetReal: %s is a fixed parameter; set it before fmi2ExitInitializationMode",
                    vr[k] == VR_PSI0_WB ? "Psi0_Wb" : "h_sub_max_s");
                return fmi2Error;
            }
            if (vr[k] == VR_PSI0_WB) c->Psi0_set = v; else c->hsub_set = v;
            c->dirty = 1;
            break;
#if SOL_HAS_FX
        case VR_HYST_GAIN: c->gain_set = v; c->dirty = 1; break;   /* tunable */
        case VR_FRICTION_N: c->fricN_set = v; c->dirty = 1; break;     /* tunable */
        case VR_C_TH_J_PER_K:
        case VR_R_TH_K_PER_W:
        case VR_ALPHA_PER_K:
        case VR_PRESLIDING_M:
            if (!is_fixed_phase(in)) {
                say(in, fmi2Error, "fmi2SetReal: %s is a fixed parameter; set it before fmi2ExitInitializationMode",
                    vr[k] == VR_C_TH_J_PER_K ? "C_th_J_per_K" : vr[k] == VR_R_TH_K_PER_W ? "R_th_K_per_W"
                    : vr[k] == VR_ALPHA_PER_K ? "alpha_per_K" : "presliding_m");
                return fmi2Error;
            }
            if (vr[k] == VR_C_TH_J_PER_K) c->Cth_set = v;
            else if (vr[k] == VR_R_TH_K_PER_W) c->Rth_set = v;
            else if (vr[k] == VR_ALPHA_PER_K) c->alpha_set = v;
            else c->presl_set = v;
            c->dirty = 1;
            break;
#endif
        default:
            say(in, fmi2Error, "fmi2SetReal: value reference %u is not a Real input or parameter", (unsigned)vr[k]);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Inst *in = (Inst *)comp;
    size_t k;
    if (in == NULL || (nvr && (vr == NULL || value == NULL))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_DRIVE_MODE) {
            say(in, fmi2Error, "fmi2SetInteger: value reference %u is not an Integer/Enumeration parameter",
                (unsigned)vr[k]);
            return fmi2Error;
        }
        if (!is_fixed_phase(in)) {
            say(in, fmi2Error, "fmi2SetInteger: drive_mode is fixed; set it before fmi2ExitInitializationMode");
            return fmi2Error;
        }
        if (value[k] != DRIVE_VOLTAGE && value[k] != DRIVE_CURRENT) {
            say(in, fmi2Error, "drive_mode must be 1 (voltage) or 2 (current), got %d", (int)value[k]);
            return fmi2Error;
        }
        in->core.drive_set = value[k];
        in->core.dirty = 1;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    Inst *in = (Inst *)comp;
    size_t k;
    if (in == NULL || (nvr && (vr == NULL || value == NULL))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        Core *c = &in->core;
        int on = value[k] ? 1 : 0;
        if (!SOL_HAS_FX || (vr[k] != VR_HYSTERESIS_ON && vr[k] != VR_EDDY_LADDER_ON && vr[k] != VR_HEATING_ON && vr[k] != VR_FRICTION_ON)) {
            say(in, fmi2Error, "fmi2SetBoolean: value reference %u is not a Boolean parameter", (unsigned)vr[k]);
            return fmi2Error;
        }
        if (!is_fixed_phase(in)) {
            say(in, fmi2Error, "fmi2SetBoolean: the effect switches are fixed; set them before "
                "fmi2ExitInitializationMode");
            return fmi2Error;
        }
        if (vr[k] == VR_HYSTERESIS_ON) c->hyst_set = on;
        else if (vr[k] == VR_EDDY_LADDER_ON) c->lad_set = on;
        else if (vr[k] == VR_HEATING_ON) c->heat_set = on;
        else c->fric_set = on;
        c->dirty = 1;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    Inst *in = (Inst *)comp;
    (void)vr;
    (void)value;
    if (in == NULL) return fmi2Error;
    if (nvr) { say(in, fmi2Error, "fmi2SetString: this FMU has no String variables"); return fmi2Error; }
    return fmi2OK;
}

/* ---- FMU state ---------------------------------------------------------------------------- */
/* Why a state (from fmi2SetFMUstate or fmi2DeSerializeFMUstate) is not one this FMU can continue
 * from, or NULL: layout, finite model and effect states, parameters in use as apply_params leaves
 * them (finite; h_sub_max_s > 0 with inv_hsub = 1 / h_sub_max_s, so the sub-step cap holds; m = 1 + R G
 * is left out: it overflows to inf for an absurd G), flags 0 or 1, drive mode 1 or 2. Inputs and
 * parameters as set may be anything: they are checked when used. */
static const char *core_problem(const Core *c)
{
    const int flags[] = { c->voltage, c->dirty, c->ready, c->hyst_set, c->lad_set, c->heat_set, c->fric_set,
                          c->fx_on, c->hyst_on, c->lad_on, c->heat_on, c->fric_on };
    const double used[] = { c->R, c->G, c->Psi0, c->t0_s, c->gain, c->Cth, c->Rth, c->alpha,
                            c->fricN, c->presl, c->me_time_s, c->me_psi_Wb, c->me_T };
    size_t k;
    if (c->s[ST_STATE_LAYOUT] != STATE_LAYOUT) return "state layout";
    for (k = 0; k < N_STATE; k++) if (!is_finite(c->s[k])) return "model state not finite";
    for (k = 0; k < N_FX; k++) if (!is_finite(c->fx[k])) return "effect state not finite";
    for (k = 0; k < LAD_ALLOC; k++) if (!is_finite(c->me_lad[k])) return "eddy-ladder state not finite";
    for (k = 0; k < sizeof used / sizeof used[0]; k++) if (!is_finite(used[k])) return "parameter in use not finite";
    for (k = 0; k < sizeof flags / sizeof flags[0]; k++) if (flags[k] != 0 && flags[k] != 1) return "flag not 0 or 1";
    if (c->drive_set != DRIVE_VOLTAGE && c->drive_set != DRIVE_CURRENT) return "drive_mode not 1 or 2";
    if (!(is_finite(c->hsub) && c->hsub > 0.0 && c->inv_hsub == 1.0 / c->hsub)) return "h_sub_max_s in use";
    if (c->fx_on != (c->hyst_on || c->lad_on || c->heat_on || c->fric_on)) return "effect switches";
    return NULL;
}

/* The states this instance handed out: only those may be written, set or freed. A pointer from
 * elsewhere (another FMU's or another backend's state, a freed one) is refused with fmi2Error instead of
 * being read, overwritten or freed (a double free). */
static int state_index(const Inst *in, const void *state)
{
    size_t k;
    for (k = 0; k < in->n_states; k++) if (in->states[k] == state) return (int)k;
    return -1;
}

/* A new state (registered), or NULL with the reason logged. */
static void *new_state(Inst *in, const char *fn)
{
    void *st;
    if (in->n_states == in->cap_states) {
        size_t cap = in->cap_states ? 2 * in->cap_states : 8;
        void **grown = (void **)in->cb.allocateMemory(cap, sizeof(void *));
        if (grown == NULL) { say(in, fmi2Error, "%s: out of memory", fn); return NULL; }
        if (in->n_states) memcpy(grown, in->states, in->n_states * sizeof(void *));
        if (in->states != NULL) in->cb.freeMemory(in->states);
        in->states = grown;
        in->cap_states = cap;
    }
    st = in->cb.allocateMemory(1, sizeof(Core));
    if (st == NULL) { say(in, fmi2Error, "%s: out of memory", fn); return NULL; }
    in->states[in->n_states++] = st;
    return st;
}

/* *state is NULL (allocate) or one of this instance's states (reuse); else refused. */
static int writable_state(Inst *in, fmi2FMUstate *state, const char *fn)
{
    if (*state == NULL) return (*state = new_state(in, fn)) != NULL;
    if (state_index(in, *state) >= 0) return 1;
    say(in, fmi2Error, "%s: the given state was not allocated by this FMU instance; not written", fn);
    return 0;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    Inst *in = (Inst *)comp;
    if (in == NULL || state == NULL) return fmi2Error;
    if (!writable_state(in, state, "fmi2GetFMUstate")) return fmi2Error;
    memcpy(*state, &in->core, sizeof(Core));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state)
{
    Inst *in = (Inst *)comp;
    const Core *c = (const Core *)state;
    const char *why;
    if (in == NULL) return fmi2Error;
    if (c == NULL) { say(in, fmi2Error, "fmi2SetFMUstate: no state given"); return fmi2Error; }
    if (state_index(in, c) < 0) {
        say(in, fmi2Error, "fmi2SetFMUstate: not a state of this FMU instance (not allocated by it); the state is kept");
        return fmi2Error;
    }
    why = core_problem(c);
    if (why != NULL) { say(in, fmi2Error, "fmi2SetFMUstate: not a state of this FMU (%s); the state is kept", why); return fmi2Error; }
    memcpy(&in->core, c, sizeof(Core));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    Inst *in = (Inst *)comp;
    int k;
    if (in == NULL || state == NULL) return fmi2Error;
    if (*state == NULL) return fmi2OK;
    k = state_index(in, *state);
    if (k < 0) {
        say(in, fmi2Error, "fmi2FreeFMUstate: the given state was not allocated by this FMU instance; not freed");
        return fmi2Error;
    }
    in->states[k] = in->states[--in->n_states];
    in->cb.freeMemory(*state);
    *state = NULL;
    return fmi2OK;
}

#define SERIAL_HEADER 16   /* 8-byte magic, 4-byte layout, 4-byte payload size */

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size)
{
    (void)comp;
    (void)state;
    if (size == NULL) return fmi2Error;
    *size = SERIAL_HEADER + sizeof(Core);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte serializedState[], size_t size)
{
    Inst *in = (Inst *)comp;
    unsigned int head[2];
    if (in == NULL || state == NULL || serializedState == NULL) return fmi2Error;
    if (state_index(in, state) < 0) {
        say(in, fmi2Error, "fmi2SerializeFMUstate: the given state was not allocated by this FMU instance");
        return fmi2Error;
    }
    if (size < SERIAL_HEADER + sizeof(Core)) { say(in, fmi2Error, "fmi2SerializeFMUstate: buffer too small"); return fmi2Error; }
    head[0] = (unsigned int)STATE_LAYOUT;
    head[1] = (unsigned int)sizeof(Core);
    memcpy(serializedState, SERIAL_MAGIC, 8);
    memcpy(serializedState + 8, head, 8);
    memcpy(serializedState + SERIAL_HEADER, state, sizeof(Core));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *state)
{
    Inst *in = (Inst *)comp;
    unsigned int head[2];
    Core tmp;
    const char *why;
    if (in == NULL || state == NULL || serializedState == NULL) return fmi2Error;
    if (size != SERIAL_HEADER + sizeof(Core) || memcmp(serializedState, SERIAL_MAGIC, 8) != 0) {
        say(in, fmi2Error, "fmi2DeSerializeFMUstate: not a serialized state of this FMU (%lu bytes)", (unsigned long)size);
        return fmi2Error;
    }
    memcpy(head, serializedState + 8, 8);
    memcpy(&tmp, serializedState + SERIAL_HEADER, sizeof(Core));
    if (head[0] != (unsigned int)STATE_LAYOUT || head[1] != sizeof(Core)) {
        say(in, fmi2Error, "fmi2DeSerializeFMUstate: state layout %u does not match this FMU's %u", head[0],
            (unsigned int)STATE_LAYOUT);
        return fmi2Error;
    }
    why = core_problem(&tmp);
    if (why != NULL) {
        say(in, fmi2Error, "fmi2DeSerializeFMUstate: not a valid state of this FMU (%s)", why);
        return fmi2Error;
    }
    if (!writable_state(in, state, "fmi2DeSerializeFMUstate")) return fmi2Error;
    memcpy(*state, &tmp, sizeof(Core));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    say((Inst *)comp, fmi2Error, "fmi2GetDirectionalDerivative is not provided");
    return fmi2Error;
}

/* ---- co-simulation ------------------------------------------------------------------------ */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    say((Inst *)comp, fmi2Error, "fmi2SetRealInputDerivatives: inputs are held (canInterpolateInputs=false)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    say((Inst *)comp, fmi2Error, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder=0)");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Inst *in = (Inst *)comp;
    Core *c;
    double u;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (in == NULL) return fmi2Error;
    c = &in->core;
    if (in->phase != PH_STEP) { say(in, fmi2Error, "fmi2DoStep outside step mode (after initialization)"); return fmi2Error; }
    u = c->voltage ? c->u_V : c->i_A;
    if (!(h > 0.0 && is_finite(h))) { say(in, fmi2Error, "doStep at t = %.17g s: communication step must be finite and > 0 s, got %.17g", t, h); return fmi2Error; }
    if (!is_finite(t)) { say(in, fmi2Error, "doStep: step start time %.17g is not finite", t); return fmi2Error; }
    if (c->ready && ceil(h * c->inv_hsub - 1e-9) > MAX_SUBSTEPS) {
        say(in, fmi2Error, "doStep at t = %.17g s: step h = %.17g s needs more than %.0f sub-steps of h_sub_max_s "
            "= %.17g s; take shorter communication steps or raise h_sub_max_s", t, h, MAX_SUBSTEPS, c->hsub);
        return fmi2Error;
    }
    if (c->dirty) {
        if (c->ready) {
            if (!apply_params(in, 0)) return fmi2Error;
        } else if (!initialize(in)) {
            return fmi2Error;
        }
        u = c->voltage ? c->u_V : c->i_A;
    }
    if (!(ceil(h * c->inv_hsub - 1e-9) <= MAX_SUBSTEPS)) {  /* again after a first initialization, and NaN */
        say(in, fmi2Error, "doStep at t = %.17g s: step h = %.17g s needs more than %.0f sub-steps of h_sub_max_s "
            "= %.17g s; take shorter communication steps or raise h_sub_max_s", t, h, MAX_SUBSTEPS, c->hsub);
        return fmi2Error;
    }
    if (!is_finite(u)) { say(in, fmi2Error, "doStep at t = %.17g s: input %s = %.17g is not finite", t, drive_name(c), u); return fmi2Error; }
    if (!is_finite(c->x_m)) { say(in, fmi2Error, "doStep at t = %.17g s: input x_m = %.17g is not finite", t, c->x_m); return fmi2Error; }
    {
        double s_keep[N_STATE], fx_keep[N_FX];
        int k;
        for (k = 0; k < N_STATE; k++) s_keep[k] = c->s[k];
        for (k = 0; k < N_FX; k++) fx_keep[k] = c->fx[k];
        if (c->fx_on) sol_step_fx(in, t, h);
        else sol_step(in, t, h);
        for (k = 0; k < N_STATE; k++) if (!is_finite(c->s[k])) break;
        if (k < N_STATE || !is_finite(c->fx[FX_T_RISE_K]) || !is_finite(c->fx[FX_I_HYST_A])) {
            for (k = 0; k < N_STATE; k++) c->s[k] = s_keep[k];
            for (k = 0; k < N_FX; k++) c->fx[k] = fx_keep[k];
            say(in, fmi2Error, "doStep at t = %.17g s: the state became non-finite (inputs or parameters far "
                "outside the maps: %s = %.17g, G_eddy_S = %.17g); the step is refused and the state kept",
                t, drive_name(c), u, c->G);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp)
{
    say((Inst *)comp, fmi2Error, "fmi2CancelStep: fmi2DoStep is synchronous");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    (void)value;
    say((Inst *)comp, fmi2Discard, "fmi2GetStatus: fmi2DoStep is synchronous; no status to report");
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    Inst *in = (Inst *)comp;
    if (in == NULL || value == NULL) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) { *value = in->core.s[ST_TIME_S]; return fmi2OK; }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)comp; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)comp; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value)
{
    (void)comp; (void)s; (void)value;
    return fmi2Discard;
}

/* ---- model exchange ----------------------------------------------------------------------- */
fmi2Status fmi2EnterEventMode(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    if (in->phase != PH_CONT && in->phase != PH_EVENT) { say(in, fmi2Error, "fmi2EnterEventMode in wrong mode"); return fmi2Error; }
    in->phase = PH_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *info)
{
    Inst *in = (Inst *)comp;
    if (in == NULL || info == NULL) return fmi2Error;
    if (in->phase != PH_EVENT) { say(in, fmi2Error, "fmi2NewDiscreteStates outside event mode"); return fmi2Error; }
    if (me_prepare(in, "fmi2NewDiscreteStates") != fmi2OK) return fmi2Error;
    me_commit(&in->core);
    me_flags(in);
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    if (in->phase != PH_EVENT) { say(in, fmi2Error, "fmi2EnterContinuousTimeMode outside event mode"); return fmi2Error; }
    in->phase = PH_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    Inst *in = (Inst *)comp;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (in == NULL || enterEventMode == NULL || terminateSimulation == NULL) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    if (me_prepare(in, "fmi2CompletedIntegratorStep") != fmi2OK) return fmi2Error;
    me_flags(in);
    in->core.s[ST_TIME_S] = in->core.me_time_s;
    me_commit(&in->core);
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real time)
{
    Inst *in = (Inst *)comp;
    if (in == NULL) return fmi2Error;
    if (!is_finite(time)) { say(in, fmi2Error, "fmi2SetTime: time %.17g is not finite", time); return fmi2Error; }
    in->core.me_time_s = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx)
{
    Inst *in = (Inst *)comp;
    size_t k;
    if (in == NULL || x == NULL || nx != NX) return fmi2Error;
    for (k = 0; k < nx; k++)
        if (!is_finite(x[k])) { say(in, fmi2Error, "fmi2SetContinuousStates: state %u = %.17g is not finite", (unsigned)k, x[k]); return fmi2Error; }
    in->core.me_psi_Wb = x[0];
    for (k = ME_LAD; k < ME_T; k++) in->core.me_lad[k - ME_LAD] = x[k];
    if (NX > ME_T) in->core.me_T = x[NX - 1];
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real derivatives[], size_t nx)
{
    Inst *in = (Inst *)comp;
    MeOut o;
    size_t k;
    if (in == NULL || derivatives == NULL || nx != NX) return fmi2Error;
    if (!in->core.ready) { say(in, fmi2Error, "fmi2GetDerivatives before a successful initialization"); return fmi2Error; }
    if (me_prepare(in, "fmi2GetDerivatives") != fmi2OK) return fmi2Error;
    me_eval(&in->core, &o);
    for (k = 0; k < nx; k++) derivatives[k] = o.der[k];
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real eventIndicators[], size_t ni)
{
    (void)eventIndicators;
    return comp != NULL && ni == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx)
{
    Inst *in = (Inst *)comp;
    size_t k;
    if (in == NULL || x == NULL || nx != NX) return fmi2Error;
    x[0] = in->core.me_psi_Wb;
    for (k = ME_LAD; k < ME_T; k++) x[k] = in->core.me_lad[k - ME_LAD];
    if (NX > ME_T) x[NX - 1] = in->core.me_T;
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[], size_t nx)
{
    size_t k;
    if (comp == NULL || x_nominal == NULL || nx != NX) return fmi2Error;
    x_nominal[0] = SOL_PSI_MAX;
    for (k = 1; k < nx; k++) x_nominal[k] = 1.0;   /* ladder currents [A], temperature rise [K] */
    return fmi2OK;
}
