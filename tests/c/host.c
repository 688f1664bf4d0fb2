/*
 * Plain C host of the native solenoid FMU: dlopen, no Python in the process.
 *
 *   host LIB.so FMU_GUID OUT.csv N_LONG [fx]
 *
 * With "fx" the FMU carries the effect variables (solenoid_fmu.fmu.EFFECT_VARIABLES after the base
 * ones) and every instance switches all four effects on (hysteresis, eddy ladder, heating, friction)
 * before initialization; the long voltage run then also moves x (friction), and prints
 * ns_per_step for the model with all effects.
 *
 * 1. ramp: current-driven 10 A/s ramp from 0 A (h = 1e-4 s, 2000 steps, x = 1 mm); writes
 *    OUT.csv (t_s, i_out_A, U_out_V, F_N, psi_Wb, dpsi_dt_V, i_eddy_A; %.17g) for the test to
 *    compare with model.py.
 * 2. two instances: a voltage-driven and a current-driven instance stepped alternately give the
 *    same outputs, bit for bit, as each alone.
 * 3. reset: after fmi2Reset and a new initialization the same run gives the same outputs.
 * 4. FMU state: get/set state round trip, and serialize -> deserialize into another instance.
 * 5. NaN input: fmi2DoStep returns fmi2Error and the outputs are unchanged.
 * 6. long run: N_LONG voltage-driven steps of 1e-4 s with a changing input; no allocation during
 *    the run (counted through the allocateMemory callback); prints ns per step (ns_per_step). Then
 *    N_LONG current-driven steps with G_eddy = 0 (a Newton solve per step): ns_per_step_current_G0.
 *    digest_voltage / digest_current: a digest of the bits of every output of each long run, so two
 *    binaries (linux64, win64 under wine) are compared bit for bit over the whole run.
 *
 * Prints one "ok <check>" line per check and "ns_per_step <value>"; exits 1 on the first failure.
 */
#define _POSIX_C_SOURCE 200809L
#ifdef _WIN32
#include "win_dlfcn.h"   /* the same checks on the win64 binary (mingw-w64 build, run under wine) */
#else
#include <dlfcn.h>
#endif
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

enum { VR_U = 0, VR_I, VR_X, VR_I_OUT, VR_U_OUT, VR_F, VR_PSI, VR_DPSI, VR_IEDDY, VR_OOM, VR_R, VR_G, VR_DRIVE };
/* effect switches (hysteresis_on, eddy_ladder_on, heating_on, friction_on) of an FMU with effects */
static const fmi2ValueReference FX_SWITCH_VR[4] = {17, 19, 20, 24};
static int FX = 0;
#define NOUT 6
static const fmi2ValueReference OUT_VR[NOUT] = {VR_I_OUT, VR_U_OUT, VR_F, VR_PSI, VR_DPSI, VR_IEDDY};

static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *freeInstance;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInit;
    fmi2ExitInitializationModeTYPE *exitInit;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2SetRealTYPE *setReal;
    fmi2GetRealTYPE *getReal;
    fmi2SetIntegerTYPE *setInteger;
    fmi2SetBooleanTYPE *setBoolean;
    fmi2DoStepTYPE *doStep;
    fmi2GetFMUstateTYPE *getState;
    fmi2SetFMUstateTYPE *setState;
    fmi2FreeFMUstateTYPE *freeState;
    fmi2SerializedFMUstateSizeTYPE *serialSize;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} F;

static long n_alloc = 0, n_free = 0, n_errors = 0;

static void *alloc_cb(size_t n, size_t size) { n_alloc++; return calloc(n, size); }
static void free_cb(void *p) { if (p) n_free++; free(p); }

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    va_list ap;
    (void)env;
    (void)category;
    if (status >= fmi2Error) n_errors++;
    fprintf(stderr, "[%s] status %d: ", name, (int)status);
    va_start(ap, message);
    vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

static const fmi2CallbackFunctions CB = {logger, alloc_cb, free_cb, NULL, NULL};

#define CHECK(cond, what) do { if (!(cond)) { fprintf(stderr, "FAILED: %s (%s:%d)\n", what, __FILE__, __LINE__); exit(1); } } while (0)

static void *sym(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    CHECK(p != NULL, name);
    return p;
}

static const char *FMU_GUID;

/* Digest of the bits of a run's outputs: rotate and xor in each double (any single changed bit shows). */
static uint64_t digest_add(uint64_t h, const double *y, int n)
{
    int k;
    for (k = 0; k < n; k++) {
        uint64_t b;
        memcpy(&b, &y[k], sizeof b);
        h = ((h << 7) | (h >> 57)) ^ b;
    }
    return h;
}

/* Instantiate and initialize: mode 1 voltage, 2 current; u0 the drive input, x the gap. */
static fmi2Component start(const char *name, int mode, double u0, double x, double G)
{
    fmi2Component c = F.instantiate(name, fmi2CoSimulation, FMU_GUID, "", &CB, fmi2False, fmi2True);
    fmi2ValueReference vr_in[2] = {mode == 1 ? VR_U : VR_I, VR_X}, vr_g = VR_G, vr_d = VR_DRIVE;
    double in[2] = {u0, x};
    fmi2Integer m = mode;
    CHECK(c != NULL, "fmi2Instantiate");
    CHECK(F.setupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) == fmi2OK, "setupExperiment");
    CHECK(F.enterInit(c) == fmi2OK, "enterInitializationMode");
    CHECK(F.setInteger(c, &vr_d, 1, &m) == fmi2OK, "set drive_mode");
    if (FX) {
        const fmi2Boolean on[4] = {fmi2True, fmi2True, fmi2True, fmi2True};
        CHECK(F.setBoolean(c, FX_SWITCH_VR, 4, on) == fmi2OK, "switch the effects on");
    }
    if (G >= 0.0) CHECK(F.setReal(c, &vr_g, 1, &G) == fmi2OK, "set G_eddy_S");
    CHECK(F.setReal(c, vr_in, 2, in) == fmi2OK, "set inputs");
    CHECK(F.exitInit(c) == fmi2OK, "exitInitializationMode");
    return c;
}

static void step(fmi2Component c, int mode, double t, double h, double u, double x, double out[NOUT])
{
    fmi2ValueReference vr_in[2] = {mode == 1 ? VR_U : VR_I, VR_X};
    double in[2] = {u, x};
    CHECK(F.setReal(c, vr_in, 2, in) == fmi2OK, "setReal inputs");
    CHECK(F.doStep(c, t, h, fmi2True) == fmi2OK, "fmi2DoStep");
    CHECK(F.getReal(c, OUT_VR, NOUT, out) == fmi2OK, "getReal outputs");
}

/* Triangle wave in [0, 1] of period n steps: + - * / only (no libm), so the hosts of every platform feed
 * the FMU the same bits (a libm sin differs between glibc and msvcrt in the last bit). */
static double tri(long k, long n) { return 1.0 - fabs(2.0 * (double)(k % n) / (double)n - 1.0); }

static double volt(int k) { return (k / 500) % 2 ? 0.0 : 24.0; }   /* 50 ms on, 50 ms off at h = 1e-4 */
static double ramp(int k) { return 10.0 * 1e-4 * (k + 1); }           /* 10 A/s, value at the step end */

#define NRUN 300
static double A1[NRUN][NOUT], B1[NRUN][NOUT], A2[NRUN][NOUT], B2[NRUN][NOUT];

int main(int argc, char **argv)
{
    void *lib;
    FILE *csv;
    fmi2Component a, b, c;
    double out[NOUT], h = 1e-4, x = 1e-3;
    int k;
    long n_long;
    if (argc != 5 && !(argc == 6 && strcmp(argv[5], "fx") == 0)) {
        fprintf(stderr, "usage: host LIB.so FMU_GUID OUT.csv N_LONG [fx]\n");
        return 2;
    }
    FX = argc == 6;
    FMU_GUID = argv[2];
    n_long = atol(argv[4]);
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    CHECK(lib != NULL, dlerror());
    *(void **)&F.instantiate = sym(lib, "fmi2Instantiate");
    *(void **)&F.freeInstance = sym(lib, "fmi2FreeInstance");
    *(void **)&F.setupExperiment = sym(lib, "fmi2SetupExperiment");
    *(void **)&F.enterInit = sym(lib, "fmi2EnterInitializationMode");
    *(void **)&F.exitInit = sym(lib, "fmi2ExitInitializationMode");
    *(void **)&F.terminate = sym(lib, "fmi2Terminate");
    *(void **)&F.reset = sym(lib, "fmi2Reset");
    *(void **)&F.setReal = sym(lib, "fmi2SetReal");
    *(void **)&F.getReal = sym(lib, "fmi2GetReal");
    *(void **)&F.setInteger = sym(lib, "fmi2SetInteger");
    *(void **)&F.setBoolean = sym(lib, "fmi2SetBoolean");
    *(void **)&F.doStep = sym(lib, "fmi2DoStep");
    *(void **)&F.getState = sym(lib, "fmi2GetFMUstate");
    *(void **)&F.setState = sym(lib, "fmi2SetFMUstate");
    *(void **)&F.freeState = sym(lib, "fmi2FreeFMUstate");
    *(void **)&F.serialSize = sym(lib, "fmi2SerializedFMUstateSize");
    *(void **)&F.serialize = sym(lib, "fmi2SerializeFMUstate");
    *(void **)&F.deserialize = sym(lib, "fmi2DeSerializeFMUstate");

    /* 1. the 10 A/s ramp, current-driven */
    c = start("ramp", 2, 0.0, x, -1.0);
    csv = fopen(argv[3], "wb");   /* "\n" line ends on every platform */
    CHECK(csv != NULL, "open csv");
    fprintf(csv, "t_s,i_out_A,U_out_V,F_N,psi_Wb,dpsi_dt_V,i_eddy_A\n");
    CHECK(F.getReal(c, OUT_VR, NOUT, out) == fmi2OK, "getReal at t0");
    fprintf(csv, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", 0.0, out[0], out[1], out[2], out[3], out[4], out[5]);
    for (k = 0; k < 2000; k++) {
        step(c, 2, k * h, h, ramp(k), x, out);
        fprintf(csv, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", (k + 1) * h, out[0], out[1], out[2], out[3],
                out[4], out[5]);
    }
    fclose(csv);
    F.terminate(c);
    F.freeInstance(c);
    printf("ok ramp\n");

    /* 2. two instances: alone, then interleaved */
    a = start("a", 1, 24.0, x, -1.0);
    for (k = 0; k < NRUN; k++) step(a, 1, k * h, h, volt(k), x, A1[k]);
    F.freeInstance(a);
    b = start("b", 2, 0.0, 2e-3, 0.0);
    for (k = 0; k < NRUN; k++) step(b, 2, k * h, h, ramp(k), 2e-3, B1[k]);
    F.freeInstance(b);
    a = start("a", 1, 24.0, x, -1.0);
    b = start("b", 2, 0.0, 2e-3, 0.0);
    for (k = 0; k < NRUN; k++) {
        step(a, 1, k * h, h, volt(k), x, A2[k]);
        step(b, 2, k * h, h, ramp(k), 2e-3, B2[k]);
    }
    CHECK(memcmp(A1, A2, sizeof A1) == 0 && memcmp(B1, B2, sizeof B1) == 0, "two instances independent");
    CHECK(A1[NRUN - 1][3] > 0.0 && B1[NRUN - 1][3] > 0.0, "the runs build up flux");
    F.freeInstance(b);
    printf("ok two_instances\n");

    /* 3. reset */
    CHECK(F.reset(a) == fmi2OK, "fmi2Reset");
    {
        fmi2ValueReference vr_in[2] = {VR_U, VR_X}, vr_d = VR_DRIVE;
        double in[2] = {24.0, x};
        fmi2Integer m = 1;
        CHECK(F.setupExperiment(a, fmi2False, 0.0, 0.0, fmi2False, 0.0) == fmi2OK, "setupExperiment after reset");
        CHECK(F.enterInit(a) == fmi2OK, "enterInitializationMode after reset");
        CHECK(F.setInteger(a, &vr_d, 1, &m) == fmi2OK, "drive after reset");
        if (FX) {
            const fmi2Boolean on[4] = {fmi2True, fmi2True, fmi2True, fmi2True};
            CHECK(F.setBoolean(a, FX_SWITCH_VR, 4, on) == fmi2OK, "effects after reset");
        }
        CHECK(F.setReal(a, vr_in, 2, in) == fmi2OK, "inputs after reset");
        CHECK(F.exitInit(a) == fmi2OK, "exitInitializationMode after reset");
    }
    for (k = 0; k < NRUN; k++) step(a, 1, k * h, h, volt(k), x, A2[k]);
    CHECK(memcmp(A1, A2, sizeof A1) == 0, "reset reproduces the run");
    printf("ok reset\n");

    /* 4. FMU state round trip (continue a from t = NRUN h) */
    {
        fmi2FMUstate s = NULL, s2 = NULL;
        size_t size = 0;
        fmi2Byte *blob;
        double ahead[50][NOUT], again[50][NOUT], other[50][NOUT];
        double t0 = NRUN * h;
        CHECK(F.getState(a, &s) == fmi2OK, "fmi2GetFMUstate");
        for (k = 0; k < 50; k++) step(a, 1, t0 + k * h, h, k < 20 ? 24.0 : 0.0, x, ahead[k]);
        CHECK(F.setState(a, s) == fmi2OK, "fmi2SetFMUstate");
        for (k = 0; k < 50; k++) step(a, 1, t0 + k * h, h, k < 20 ? 24.0 : 0.0, x, again[k]);
        CHECK(memcmp(ahead, again, sizeof ahead) == 0, "get/set state round trip");
        CHECK(ahead[49][3] != ahead[0][3], "the state run changes the flux");
        CHECK(F.serialSize(a, s, &size) == fmi2OK && size > 0, "serialized size");
        blob = (fmi2Byte *)malloc(size);
        CHECK(blob != NULL, "malloc");
        CHECK(F.serialize(a, s, blob, size) == fmi2OK, "serialize");
        b = start("other", 1, 0.0, x, -1.0);
        CHECK(F.deserialize(b, blob, size, &s2) == fmi2OK, "deserialize");
        CHECK(F.setState(b, s2) == fmi2OK, "set deserialized state");
        for (k = 0; k < 50; k++) step(b, 1, t0 + k * h, h, k < 20 ? 24.0 : 0.0, x, other[k]);
        CHECK(memcmp(ahead, other, sizeof ahead) == 0, "serialized state continues identically");
        blob[0] ^= 0x55;
        CHECK(F.deserialize(b, blob, size, &s2) == fmi2Error, "corrupt blob refused");
        free(blob);
        F.freeState(a, &s);
        F.freeState(b, &s2);
        F.freeInstance(b);
        printf("ok state\n");
    }

    /* 5. NaN input: fmi2Error, outputs unchanged, instance usable afterwards */
    {
        fmi2ValueReference vr_u = VR_U;
        double nan_v = nan(""), before[NOUT], after[NOUT];
        long e0 = n_errors;
        double t0 = (NRUN + 50) * h;
        CHECK(F.getReal(a, OUT_VR, NOUT, before) == fmi2OK, "getReal before NaN");
        CHECK(F.setReal(a, &vr_u, 1, &nan_v) == fmi2OK, "setReal NaN");
        CHECK(F.doStep(a, t0, h, fmi2True) == fmi2Error, "NaN input returns fmi2Error");
        CHECK(n_errors == e0 + 1, "one error message logged");
        CHECK(F.getReal(a, OUT_VR, NOUT, after) == fmi2OK && memcmp(before, after, sizeof before) == 0,
              "outputs unchanged after NaN");
        step(a, 1, t0, h, 24.0, x, after);
        printf("ok nan\n");
    }
    F.freeInstance(a);

    /* 6. long run: no allocation in fmi2DoStep; time per step */
    {
        struct timespec t0, t1;
        long alloc0;
        double u = 24.0, y[3];
        fmi2ValueReference vr_in[2] = {VR_U, VR_X}, vr_out[3] = {VR_I_OUT, VR_F, VR_PSI};
        double in[2];
        double ns;
        uint64_t dig = 0;
        c = start("long", 1, 0.0, x, -1.0);
        alloc0 = n_alloc;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (k = 0; k < n_long; k++) {
            u = (k / 500) % 2 ? 0.0 : 24.0;
            in[0] = u;
            in[1] = FX ? x + 0.3e-3 * (2.0 * tri(k, 3142) - 1.0) : x;   /* with effects: a moving armature */
            F.setReal(c, vr_in, 2, in);
            if (F.doStep(c, k * h, h, fmi2True) != fmi2OK) CHECK(0, "long run doStep");
            F.getReal(c, vr_out, 3, y);
            dig = digest_add(dig, y, 3);
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        CHECK(n_alloc == alloc0, "no allocation during the long run");
        CHECK(y[2] == y[2] && fabs(y[2]) <= 10.0, "long run stays finite");
        ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / (double)(n_long > 0 ? n_long : 1);
        printf("ok long_run %ld steps\n", n_long);
        printf("ns_per_step %.1f\n", ns);
        printf("digest_voltage %016" PRIx64 "\n", dig);
        F.terminate(c);
        F.freeInstance(c);

        /* the algebraic case (current mode, G = 0): a Newton solve per step, its worst-case path */
        c = start("long_current", 2, 0.0, x, 0.0);
        vr_in[0] = VR_I;
        dig = 0;
        alloc0 = n_alloc;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (k = 0; k < n_long; k++) {
            in[0] = 2.0 * tri(k, 3142);
            in[1] = x;
            F.setReal(c, vr_in, 2, in);
            if (F.doStep(c, k * h, h, fmi2True) != fmi2OK) CHECK(0, "long current run doStep");
            F.getReal(c, vr_out, 3, y);
            dig = digest_add(dig, y, 3);
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        CHECK(n_alloc == alloc0, "no allocation during the current-mode run");
        ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / (double)(n_long > 0 ? n_long : 1);
        printf("ns_per_step_current_G0 %.1f\n", ns);
        printf("digest_current %016" PRIx64 "\n", dig);
        F.terminate(c);
        F.freeInstance(c);
    }
    CHECK(n_alloc == n_free, "every allocation freed");
    dlclose(lib);
    printf("ok all\n");
    return 0;
}
