/* sol_params.c: the parameters as set, checked and applied (model.py params.checked_param).
 * Part of the model code of solenoid_fmu.c, which includes it (one translation unit). */
#include "sol_core.h"

/* ---- parameters ----------------------------------------------------------------------------- */
/* An effect scalar: finite and >= 0 (> 0 when positive); 0 (logged) otherwise (model.py params.checked_param). */
static int fx_scalar_ok(Inst *in, const char *name, double v, int positive)
{
    if (!is_finite(v)) { say(in, fmi2Error, "%s must be finite, got %.17g", name, v); return 0; }
    if (v < 0.0 || (positive && v == 0.0)) {
        say(in, fmi2Error, "%s must be > 0 (>= 0 for alpha and friction), got %.17g", name, v);
        return 0;
    }
    return 1;
}

/* A switch may only be on when the maps carry that effect (model.py params.checked_param). */
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
        if (!(c->T0_set >= SOL_T_START_EXCESS_MIN_K && c->T0_set <= SOL_T_START_EXCESS_MAX_K)) {
            say(in, fmi2Error, "T_start_excess_K must lie in [%g, %g] K, got %.17g", SOL_T_START_EXCESS_MIN_K,
                SOL_T_START_EXCESS_MAX_K, c->T0_set);
            return 0;
        }
        if (!(1.0 + c->alpha_set * c->T0_set > 0.0)) {
            say(in, fmi2Error, "alpha_per_K %.17g and T_start_excess_K %.17g give the coil no positive resistance at "
                "ambient (1 + alpha T_0 <= 0)", c->alpha_set, c->T0_set);
            return 0;
        }
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
        c->alpha = c->alpha_set / (1.0 + c->alpha_set * c->T0_set);   /* model.py heating_alpha */
        c->presl = c->presl_set;
        c->T0 = c->T0_set;
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
