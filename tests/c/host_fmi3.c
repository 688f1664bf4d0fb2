/*
 * Plain C host of the FMI 3.0 native solenoid FMU: dlopen, no Python in the process.
 *
 *   host_fmi3 LIB.so TOKEN N_LONG
 *
 * The long runs of host.c through the FMI 3.0 functions, with the same inputs: N_LONG voltage-driven
 * co-simulation cycles (set U_V and x_m, fmi3DoStep at 1e-4 s, get i_out_A, F_N, psi_Wb), then N_LONG
 * current-driven cycles with G_eddy_S = 0. Prints ns_per_step, ns_per_step_current_G0 and the digests
 * of both runs' outputs (digest_voltage, digest_current: equal to host.c's on the FMI 2.0 FMU of the
 * same maps when FMI 3.0 and FMI 2.0 compute the same bits), then "ok all".
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi3Functions.h"

enum { VR_U = 0, VR_I, VR_X, VR_I_OUT, VR_U_OUT, VR_F, VR_PSI, VR_DPSI, VR_IEDDY, VR_OOM, VR_R, VR_G, VR_DRIVE };

static struct {
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3FreeInstanceTYPE *freeInstance;
    fmi3EnterInitializationModeTYPE *enterInit;
    fmi3ExitInitializationModeTYPE *exitInit;
    fmi3TerminateTYPE *terminate;
    fmi3SetFloat64TYPE *setFloat64;
    fmi3GetFloat64TYPE *getFloat64;
    fmi3SetInt32TYPE *setInt32;
    fmi3DoStepTYPE *doStep;
} F;

#define CHECK(cond, what) do { if (!(cond)) { fprintf(stderr, "FAILED: %s (%s:%d)\n", what, __FILE__, __LINE__); exit(1); } } while (0)

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    (void)env;
    fprintf(stderr, "status %d [%s]: %s\n", (int)status, category, message);
}

static void *sym(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    CHECK(p != NULL, name);
    return p;
}

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

static double tri(long k, long n) { return 1.0 - fabs(2.0 * (double)(k % n) / (double)n - 1.0); }

static const char *TOKEN;

static fmi3Instance start(const char *name, int mode, double x, double G)
{
    fmi3Instance c = F.instantiate(name, TOKEN, "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL,
                                   logger, NULL);
    const fmi3ValueReference vr_in[2] = {mode == 1 ? VR_U : VR_I, VR_X}, vr_g = VR_G, vr_d = VR_DRIVE;
    const double in[2] = {0.0, x};
    const fmi3Int32 m = mode;
    CHECK(c != NULL, "fmi3InstantiateCoSimulation");
    CHECK(F.enterInit(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) == fmi3OK, "enterInitializationMode");
    CHECK(F.setInt32(c, &vr_d, 1, &m, 1) == fmi3OK, "set drive_mode");
    if (G >= 0.0) CHECK(F.setFloat64(c, &vr_g, 1, &G, 1) == fmi3OK, "set G_eddy_S");
    CHECK(F.setFloat64(c, vr_in, 2, in, 2) == fmi3OK, "set inputs");
    CHECK(F.exitInit(c) == fmi3OK, "exitInitializationMode");
    return c;
}

static double run(fmi3Instance c, int mode, long n, double x, uint64_t *dig)
{
    const fmi3ValueReference vr_in[2] = {mode == 1 ? VR_U : VR_I, VR_X}, vr_out[3] = {VR_I_OUT, VR_F, VR_PSI};
    double in[2], y[3], h = 1e-4;
    struct timespec t0, t1;
    fmi3Boolean ev, term, early;
    fmi3Float64 last;
    long k;
    *dig = 0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (k = 0; k < n; k++) {
        in[0] = mode == 1 ? ((k / 500) % 2 ? 0.0 : 24.0) : 2.0 * tri(k, 3142);
        in[1] = x;
        F.setFloat64(c, vr_in, 2, in, 2);
        if (F.doStep(c, k * h, h, fmi3True, &ev, &term, &early, &last) != fmi3OK) CHECK(0, "fmi3DoStep");
        F.getFloat64(c, vr_out, 3, y, 3);
        *dig = digest_add(*dig, y, 3);
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    CHECK(y[2] == y[2] && fabs(y[2]) <= 10.0, "run stays finite");
    return ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / (double)(n > 0 ? n : 1);
}

int main(int argc, char **argv)
{
    void *lib;
    fmi3Instance c;
    uint64_t dig;
    long n;
    double ns, x = 1e-3;
    if (argc != 4) {
        fprintf(stderr, "usage: host_fmi3 LIB.so TOKEN N_LONG\n");
        return 2;
    }
    TOKEN = argv[2];
    n = atol(argv[3]);
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    CHECK(lib != NULL, dlerror());
    *(void **)&F.instantiate = sym(lib, "fmi3InstantiateCoSimulation");
    *(void **)&F.freeInstance = sym(lib, "fmi3FreeInstance");
    *(void **)&F.enterInit = sym(lib, "fmi3EnterInitializationMode");
    *(void **)&F.exitInit = sym(lib, "fmi3ExitInitializationMode");
    *(void **)&F.terminate = sym(lib, "fmi3Terminate");
    *(void **)&F.setFloat64 = sym(lib, "fmi3SetFloat64");
    *(void **)&F.getFloat64 = sym(lib, "fmi3GetFloat64");
    *(void **)&F.setInt32 = sym(lib, "fmi3SetInt32");
    *(void **)&F.doStep = sym(lib, "fmi3DoStep");

    c = start("long", 1, x, -1.0);
    ns = run(c, 1, n, x, &dig);
    printf("ns_per_step %.1f\ndigest_voltage %016" PRIx64 "\n", ns, dig);
    F.terminate(c);
    F.freeInstance(c);
    c = start("long_current", 2, x, 0.0);
    ns = run(c, 2, n, x, &dig);
    printf("ns_per_step_current_G0 %.1f\ndigest_current %016" PRIx64 "\n", ns, dig);
    F.terminate(c);
    F.freeInstance(c);
    dlclose(lib);
    printf("ok all\n");
    return 0;
}
