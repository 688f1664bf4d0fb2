/* sol_core.h: the native FMU's types (Core: everything that makes up the FMU state; Inst: an instance),
 * its sizes and value-reference macros, and logging. Part of the model code that solenoid_fmu.c includes
 * (one translation unit: sol_core.h, sol_lookup.c, sol_params.c, sol_step.c, sol_effects.c, sol_me.c). */
#ifndef SOL_CORE_H
#define SOL_CORE_H

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "solenoid_model.h"
#include "solenoid_maps.h"

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
    double gain_set, Cth_set, Rth_set, alpha_set, fricN_set, presl_set, T0_set;
    int fx_on, hyst_on, lad_on, heat_on, fric_on;
    double gain, Cth, Rth, alpha, fricN, presl, T0;   /* T0: T_start_excess_K [K] */
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

#endif
