/* sol_sim.c: the native model run over a whole recording in one call, for solenoid_fmu.fmu.native_sim (the fast
 * path of simulate_model). Not part of any FMU: it includes the FMU's model source (solenoid_fmu.c) with a
 * solenoid_maps.h whose maps and effect data are pointers bound at run time (sim_bind, generated), and drives
 * the FMI 2.0 functions exactly as solenoid_fmu.fmu.simulate_recording drives an FMU: setup, initialization
 * mode, the settings in the given order, the first inputs, then per sample the held inputs, fmi2DoStep and
 * fmi2GetReal. The numbers are those of the native FMU, which equal the Python model's bit for bit
 * (tests/test_backends_equal.py). Returns 0, or the sample index + 1 where the model refused (msg says why). */
#include <stdlib.h>

#include "solenoid_fmu.c"

typedef struct {
    char *text;
    int len;
} SimLog;

static void sim_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                       fmi2String message, ...)
{
    SimLog *log = (SimLog *)env;
    va_list ap;
    (void)name;
    (void)category;
    if (log == NULL || log->text == NULL || log->len <= 0 || status < fmi2Error) return;
    va_start(ap, message);
    vsnprintf(log->text, (size_t)log->len, message, ap);
    va_end(ap);
}

static void *sim_alloc(size_t n, size_t size) { return calloc(n, size); }

/* kind 0: Real, 1: Integer, 2: Boolean (the value as a double). */
static fmi2Status sim_set(fmi2Component comp, int kind, fmi2ValueReference vr, double value)
{
    if (kind == 1) {
        fmi2Integer v = (fmi2Integer)value;
        return fmi2SetInteger(comp, &vr, 1, &v);
    }
    if (kind == 2) {
        fmi2Boolean v = value != 0.0;
        return fmi2SetBoolean(comp, &vr, 1, &v);
    }
    return fmi2SetReal(comp, &vr, 1, &value);
}

int sol_sim_run(const int *dims, const double *scalars, const double *const *arrays,
                int n_set, const int *set_kind, const unsigned *set_vr, const double *set_value,
                const unsigned *in_vr, int n_out, const unsigned *out_vr,
                long n, const double *t, const double *x, const double *u0, const double *u_step,
                double *out, char *msg, int msg_len)
{
    SimLog log;
    fmi2CallbackFunctions cb;
    fmi2Component comp;
    fmi2ValueReference ivr[2];
    fmi2ValueReference *ovr;
    fmi2Real in[2];
    long k;
    int i, failed = 0;
    log.text = msg;
    log.len = msg_len;
    if (msg != NULL && msg_len > 0) msg[0] = '\0';
    cb.logger = sim_logger;
    cb.allocateMemory = sim_alloc;
    cb.freeMemory = free;
    cb.stepFinished = NULL;
    cb.componentEnvironment = &log;
    sim_bind(dims, scalars, arrays);
    ovr = (fmi2ValueReference *)calloc((size_t)(n_out > 0 ? n_out : 1), sizeof *ovr);
    if (ovr == NULL) return 1;
    for (i = 0; i < n_out; i++) ovr[i] = (fmi2ValueReference)out_vr[i];
    ivr[0] = (fmi2ValueReference)in_vr[0];
    ivr[1] = (fmi2ValueReference)in_vr[1];
    comp = fmi2Instantiate("simulate", fmi2CoSimulation, SOL_GUID, "", &cb, fmi2False, fmi2True);
    if (comp == NULL) { free(ovr); return 1; }
    failed = fmi2SetupExperiment(comp, fmi2False, 0.0, t[0], fmi2False, 0.0) > fmi2Warning
        || fmi2EnterInitializationMode(comp) > fmi2Warning;
    for (i = 0; i < n_set && !failed; i++)
        failed = sim_set(comp, set_kind[i], (fmi2ValueReference)set_vr[i], set_value[i]) > fmi2Warning;
    in[0] = u0[0];
    in[1] = x[0];
    failed = failed || fmi2SetReal(comp, ivr, 2, in) > fmi2Warning || fmi2ExitInitializationMode(comp) > fmi2Warning
        || fmi2GetReal(comp, ovr, (size_t)n_out, out) > fmi2Warning;
    if (failed) { fmi2FreeInstance(comp); free(ovr); return 1; }
    for (k = 0; k + 1 < n; k++) {
        in[0] = u_step[k];
        in[1] = x[k + 1];
        if (fmi2SetReal(comp, ivr, 2, in) > fmi2Warning || fmi2DoStep(comp, t[k], t[k + 1] - t[k], fmi2True) > fmi2Warning
            || fmi2GetReal(comp, ovr, (size_t)n_out, out + (k + 1) * n_out) > fmi2Warning) {
            fmi2FreeInstance(comp);
            free(ovr);
            return (int)(k + 2 > 2147483647L ? 2147483647L : k + 2);
        }
    }
    fmi2Terminate(comp);
    fmi2FreeInstance(comp);
    free(ovr);
    return 0;
}
