/* win_dlfcn.h: the few POSIX calls of host.c on Windows (dlopen/dlsym/dlerror/dlclose through
 * LoadLibrary/GetProcAddress, clock_gettime through QueryPerformanceCounter), so the same host.c
 * checks the win64 binary of the FMU (built with mingw-w64, run under wine by tests/test_fmu_c_win64.py). */
#ifndef WIN_DLFCN_H
#define WIN_DLFCN_H
#define WIN32_LEAN_AND_MEAN
#include <windows.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#define RTLD_NOW 0
#define RTLD_LOCAL 0

static void *dlopen(const char *path, int flags)
{
    (void)flags;
    return (void *)LoadLibraryA(path);
}

static void *dlsym(void *lib, const char *name)
{
    FARPROC f = GetProcAddress((HMODULE)lib, name);
    void *p;
    memcpy(&p, &f, sizeof p);   /* a function pointer as void *, as dlsym returns it */
    return p;
}

static const char *dlerror(void)
{
    static char buf[64];
    snprintf(buf, sizeof buf, "LoadLibrary failed, error %lu", (unsigned long)GetLastError());
    return buf;
}

static int dlclose(void *lib) { return FreeLibrary((HMODULE)lib) ? 0 : 1; }

#ifndef CLOCK_MONOTONIC
#define CLOCK_MONOTONIC 1
#endif
#define clock_gettime host_clock_gettime
static int host_clock_gettime(int clk, struct timespec *ts)
{
    LARGE_INTEGER f, c;
    (void)clk;
    QueryPerformanceFrequency(&f);
    QueryPerformanceCounter(&c);
    ts->tv_sec = (time_t)(c.QuadPart / f.QuadPart);
    ts->tv_nsec = (long)((c.QuadPart % f.QuadPart) * 1000000000LL / f.QuadPart);
    return 0;
}
#endif
