/*
 * solenoid-fmu native FMU: FMI 2.0 co-simulation and model exchange in one binary.
 *
 * The real-time lumped solenoid model of solenoid_fmu/realtime/model/ (paper eqs. 1-3, SI units):
 *
 *     U = R i + dPsi/dt                               paper eq. (1)
 *     i = i_f(Psi, x) + G dPsi/dt                     paper eq. (2), G = G_eddy [S]
 *     F = F(Psi, x)                                   paper eq. (3)
 *
 * The model code is split by job into files this one includes (one translation unit, so the build
 * compiles solenoid_fmu.c alone): sol_core.h (Core, Inst, logging), sol_lookup.c (map lookup, Newton),
 * sol_params.c (parameters), sol_step.c (initialization, the step, excursion flags), sol_effects.c (the
 * effects' step), sol_me.c (model-exchange evaluation); this file holds the FMI 2.0 functions.
 * It reproduces the Python model step for step (same lookups, same ROS2 sub-steps, same Newton
 * iteration, same arithmetic order), so that the co-simulation outputs equal the Python model's bit for
 * bit (tests/test_backends_equal.py compares them over random maps, parameters and inputs). It is written in C99 without allocation outside fmi2Instantiate / fmi2GetFMUstate /
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
 * Effect sub-models (maps.json effects; SolenoidModel._step_fx): hysteresis (play operators on Psi),
 * eddy ladder (R-L sections beside G), heating (R(T), first-order thermal model) and friction (Dahl in
 * x), switched by Boolean parameters; their data are the SOL_LAD_* / SOL_PLAY_* / SOL_SHAPE_* arrays
 * of solenoid_maps.h and their states Core.fx (model.py EFFECT_STATE_NAMES, ladder_k, play_k). With
 * any switch on, fmi2DoStep runs sol_step_fx (same arithmetic and order as model.py). Model exchange
 * with effects: continuous states Psi, the ladder currents and the temperature rise; hysteresis and
 * friction evaluated from their memory committed at accepted steps (see me_eval). New states go to
 * Core (the FMU state copies Core as a whole, so get/set/serialize follow automatically).
 */
#include "sol_core.h"

/* What this file implements. solenoid_model.h is generated from model.py (constants, enum ST_* of
 * STATE_NAMES, enum FX_* of EFFECT_STATE_NAMES, enum VR_* of the interface table): when model.py has
 * moved on (new states, parameters or effects), solenoid_fmu.fmu.c_sources.check_implemented refuses to
 * build, and so does the compiler. Port the new effects here (struct Core, sol_step), then update these. */
#define IMPLEMENTS_STATE_LAYOUT 1
#define IMPLEMENTS_N_PARAMS 16
#define IMPLEMENTS_N_EFFECTS 4
#define IMPLEMENTS_N_EFFECT_STATES 4
#if STATE_LAYOUT != IMPLEMENTS_STATE_LAYOUT || SOL_N_PARAMS != IMPLEMENTS_N_PARAMS \
    || SOL_N_EFFECTS != IMPLEMENTS_N_EFFECTS || SOL_N_EFFECT_STATES != IMPLEMENTS_N_EFFECT_STATES
#error "solenoid_model.h (model.py) has states, parameters or effects this file lacks: port the new effects"
#endif

/* The model, by job (one translation unit: the build compiles this file only). */
#include "sol_lookup.c"
#include "sol_params.c"
#include "sol_step.c"
#include "sol_effects.c"
#include "sol_me.c"

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
    c->T0_set = SOL_T_START_EXCESS_K_DEFAULT;
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
        case VR_T_START_EXCESS_K: value[k] = c->T0_set; break;
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
        case VR_T_START_EXCESS_K:
            if (!is_fixed_phase(in)) {
                say(in, fmi2Error, "fmi2SetReal: %s is a fixed parameter; set it before fmi2ExitInitializationMode",
                    vr[k] == VR_C_TH_J_PER_K ? "C_th_J_per_K" : vr[k] == VR_R_TH_K_PER_W ? "R_th_K_per_W"
                    : vr[k] == VR_ALPHA_PER_K ? "alpha_per_K" : vr[k] == VR_PRESLIDING_M ? "presliding_m"
                    : "T_start_excess_K");
                return fmi2Error;
            }
            if (vr[k] == VR_C_TH_J_PER_K) c->Cth_set = v;
            else if (vr[k] == VR_R_TH_K_PER_W) c->Rth_set = v;
            else if (vr[k] == VR_ALPHA_PER_K) c->alpha_set = v;
            else if (vr[k] == VR_PRESLIDING_M) c->presl_set = v;
            else c->T0_set = v;
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
                            c->fricN, c->presl, c->T0, c->me_time_s, c->me_psi_Wb, c->me_T };
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
