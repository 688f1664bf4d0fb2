/*
 * solenoid-fmu native FMU, FMI 3.0: co-simulation and model exchange from the same model code.
 *
 * This file includes solenoid_fmu.c (the FMI 2.0 implementation, unchanged) with its fmi2 functions
 * renamed sol2_fmi2* (not exported: the binary exports only fmi3*) and maps every
 * FMI 3.0 function onto them, so FMI 3.0 and FMI 2.0 FMUs compute with the same code and give the
 * same numbers. Variables: the FMI 2.0 value references (Float64 for Real, Int32 for drive_mode,
 * Boolean), plus the independent variable "time" (VR_TIME). Allocation: calloc/free (FMI 3.0 has no
 * memory callbacks), only in fmi3Instantiate*, fmi3GetFMUState and fmi3DeserializeFMUState; fmi3DoStep
 * allocates nothing.
 *
 * Not provided (declared so in modelDescription.xml): event mode in co-simulation, intermediate
 * updates, early return, clocks, scheduled execution, configuration mode, directional and adjoint
 * derivatives, output derivatives; those functions return fmi3Error with a message.
 *
 * Compile: cc -std=c99 -O2 -shared -fPIC -fvisibility=hidden -ffp-contract=off solenoid_fmi3.c -lm
 */
#include "fmi2Functions.h"
/* The fmi2 functions of solenoid_fmu.c get the names sol2_fmi2*: fmi2Functions.h (as fmpy ships it) adds no
 * FMI2_FUNCTION_PREFIX, so they are renamed here, after its declarations and before the definitions (its
 * include guard keeps solenoid_fmu.c from declaring them again). Built with -fvisibility=hidden (and on
 * Windows without dllexport), the binary exports none of them: only the fmi3 functions. */
#undef fmi2GetTypesPlatform
#define fmi2GetTypesPlatform sol2_fmi2GetTypesPlatform
#undef fmi2GetVersion
#define fmi2GetVersion sol2_fmi2GetVersion
#undef fmi2SetDebugLogging
#define fmi2SetDebugLogging sol2_fmi2SetDebugLogging
#undef fmi2Instantiate
#define fmi2Instantiate sol2_fmi2Instantiate
#undef fmi2FreeInstance
#define fmi2FreeInstance sol2_fmi2FreeInstance
#undef fmi2SetupExperiment
#define fmi2SetupExperiment sol2_fmi2SetupExperiment
#undef fmi2EnterInitializationMode
#define fmi2EnterInitializationMode sol2_fmi2EnterInitializationMode
#undef fmi2ExitInitializationMode
#define fmi2ExitInitializationMode sol2_fmi2ExitInitializationMode
#undef fmi2Terminate
#define fmi2Terminate sol2_fmi2Terminate
#undef fmi2Reset
#define fmi2Reset sol2_fmi2Reset
#undef fmi2GetReal
#define fmi2GetReal sol2_fmi2GetReal
#undef fmi2GetInteger
#define fmi2GetInteger sol2_fmi2GetInteger
#undef fmi2GetBoolean
#define fmi2GetBoolean sol2_fmi2GetBoolean
#undef fmi2GetString
#define fmi2GetString sol2_fmi2GetString
#undef fmi2SetReal
#define fmi2SetReal sol2_fmi2SetReal
#undef fmi2SetInteger
#define fmi2SetInteger sol2_fmi2SetInteger
#undef fmi2SetBoolean
#define fmi2SetBoolean sol2_fmi2SetBoolean
#undef fmi2SetString
#define fmi2SetString sol2_fmi2SetString
#undef fmi2GetFMUstate
#define fmi2GetFMUstate sol2_fmi2GetFMUstate
#undef fmi2SetFMUstate
#define fmi2SetFMUstate sol2_fmi2SetFMUstate
#undef fmi2FreeFMUstate
#define fmi2FreeFMUstate sol2_fmi2FreeFMUstate
#undef fmi2SerializedFMUstateSize
#define fmi2SerializedFMUstateSize sol2_fmi2SerializedFMUstateSize
#undef fmi2SerializeFMUstate
#define fmi2SerializeFMUstate sol2_fmi2SerializeFMUstate
#undef fmi2DeSerializeFMUstate
#define fmi2DeSerializeFMUstate sol2_fmi2DeSerializeFMUstate
#undef fmi2GetDirectionalDerivative
#define fmi2GetDirectionalDerivative sol2_fmi2GetDirectionalDerivative
#undef fmi2EnterEventMode
#define fmi2EnterEventMode sol2_fmi2EnterEventMode
#undef fmi2NewDiscreteStates
#define fmi2NewDiscreteStates sol2_fmi2NewDiscreteStates
#undef fmi2EnterContinuousTimeMode
#define fmi2EnterContinuousTimeMode sol2_fmi2EnterContinuousTimeMode
#undef fmi2CompletedIntegratorStep
#define fmi2CompletedIntegratorStep sol2_fmi2CompletedIntegratorStep
#undef fmi2SetTime
#define fmi2SetTime sol2_fmi2SetTime
#undef fmi2SetContinuousStates
#define fmi2SetContinuousStates sol2_fmi2SetContinuousStates
#undef fmi2GetDerivatives
#define fmi2GetDerivatives sol2_fmi2GetDerivatives
#undef fmi2GetEventIndicators
#define fmi2GetEventIndicators sol2_fmi2GetEventIndicators
#undef fmi2GetContinuousStates
#define fmi2GetContinuousStates sol2_fmi2GetContinuousStates
#undef fmi2GetNominalsOfContinuousStates
#define fmi2GetNominalsOfContinuousStates sol2_fmi2GetNominalsOfContinuousStates
#undef fmi2SetRealInputDerivatives
#define fmi2SetRealInputDerivatives sol2_fmi2SetRealInputDerivatives
#undef fmi2GetRealOutputDerivatives
#define fmi2GetRealOutputDerivatives sol2_fmi2GetRealOutputDerivatives
#undef fmi2DoStep
#define fmi2DoStep sol2_fmi2DoStep
#undef fmi2CancelStep
#define fmi2CancelStep sol2_fmi2CancelStep
#undef fmi2GetStatus
#define fmi2GetStatus sol2_fmi2GetStatus
#undef fmi2GetRealStatus
#define fmi2GetRealStatus sol2_fmi2GetRealStatus
#undef fmi2GetIntegerStatus
#define fmi2GetIntegerStatus sol2_fmi2GetIntegerStatus
#undef fmi2GetBooleanStatus
#define fmi2GetBooleanStatus sol2_fmi2GetBooleanStatus
#undef fmi2GetStringStatus
#define fmi2GetStringStatus sol2_fmi2GetStringStatus
#include "solenoid_fmu.c"

#include <stdlib.h>

#include "fmi3Functions.h"

/* The independent variable time [s]: the value reference after the interface and the ME locals. */
#define VR_TIME ((fmi3ValueReference)(N_VR_IFACE + 2 * NX))

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    fmi2Component c;          /* the FMI 2.0 instance (Inst) */
} W3;

#define INST(w) ((Inst *)((W3 *)(w))->c)

/* fmi2 logger -> fmi3 logMessage: the message is formatted here (fmi3 takes a plain string). */
static void log3(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                 fmi2String message, ...)
{
    W3 *w = (W3 *)env;
    char buf[800];
    va_list ap;
    (void)name;
    if (w == NULL || w->log == NULL) return;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    w->log(w->env, (fmi3Status)status, category, buf);   /* fmi2Status and fmi3Status share OK..Fatal */
}

static void *calloc3(size_t n, size_t size) { return calloc(n, size); }
static void free3(void *p) { free(p); }

static fmi3Instance instantiate3(fmi3String instanceName, fmi3String token, fmi3Boolean loggingOn,
                                 fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage, fmi2Type type)
{
    W3 *w = (W3 *)calloc(1, sizeof(W3));
    fmi2CallbackFunctions cb;
    if (w == NULL) return NULL;
    w->env = env;
    w->log = logMessage;
    cb.logger = log3;
    cb.allocateMemory = calloc3;
    cb.freeMemory = free3;
    cb.stepFinished = NULL;
    cb.componentEnvironment = w;
    w->c = sol2_fmi2Instantiate(instanceName, type, token, "", &cb, fmi2False, loggingOn ? fmi2True : fmi2False);
    if (w->c == NULL) { free(w); return NULL; }
    return w;
}

static fmi3Status refuse(fmi3Instance instance, const char *what)
{
    if (instance != NULL) say(INST(instance), fmi2Error, "%s is not provided by this FMU", what);
    return fmi3Error;
}

static double time_now(const Inst *in) { return in->type == fmi2ModelExchange ? in->core.me_time_s : in->core.s[ST_TIME_S]; }

/* ---- common functions ------------------------------------------------------------------------ */
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2SetDebugLogging(INST(instance), loggingOn ? fmi2True : fmi2False, nCategories,
                                                 categories);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)resourcePath;
    (void)visible;
    return instantiate3(instanceName, instantiationToken, loggingOn, instanceEnvironment, logMessage,
                        fmi2ModelExchange);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)resourcePath;
    (void)visible;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (eventModeUsed) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                                   "event mode in co-simulation is not provided (hasEventMode=false)");
        return NULL;
    }
    return instantiate3(instanceName, instantiationToken, loggingOn, instanceEnvironment, logMessage,
                        fmi2CoSimulation);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "scheduled execution is not provided");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    if (instance == NULL) return;
    sol2_fmi2FreeInstance(INST(instance));
    free(instance);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    fmi2Status st;
    if (instance == NULL) return fmi3Error;
    st = sol2_fmi2SetupExperiment(INST(instance), toleranceDefined ? fmi2True : fmi2False, tolerance, startTime,
                                  stopTimeDefined ? fmi2True : fmi2False, stopTime);
    if (st != fmi2OK) return (fmi3Status)st;
    return (fmi3Status)sol2_fmi2EnterInitializationMode(INST(instance));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2ExitInitializationMode(INST(instance));
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    if (instance == NULL) return fmi3Error;
    if (INST(instance)->type != fmi2ModelExchange) return refuse(instance, "fmi3EnterEventMode in co-simulation");
    return (fmi3Status)sol2_fmi2EnterEventMode(INST(instance));
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2Terminate(INST(instance));
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2Reset(INST(instance));
}

/* ---- variable access: Float64, Int32, Boolean (the FMI 2.0 Real, Integer, Boolean) ----------- */
static int has_vr(const fmi3ValueReference vr[], size_t n, fmi3ValueReference which)
{
    size_t k;
    for (k = 0; k < n; k++) if (vr[k] == which) return 1;
    return 0;
}

static int counts_ok(fmi3Instance instance, const char *fn, size_t nvr, size_t nValues)
{
    if (nvr == nValues) return 1;
    say(INST(instance), fmi2Error, "%s: %lu values for %lu scalar variables", fn, (unsigned long)nValues,
        (unsigned long)nvr);
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues)
{
    size_t k;
    if (instance == NULL || (nValueReferences && (valueReferences == NULL || values == NULL))) return fmi3Error;
    if (!counts_ok(instance, "fmi3GetFloat64", nValueReferences, nValues)) return fmi3Error;
    if (!has_vr(valueReferences, nValueReferences, VR_TIME))
        return (fmi3Status)sol2_fmi2GetReal(INST(instance), valueReferences, nValueReferences, values);
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == VR_TIME) values[k] = time_now(INST(instance));
        else if (sol2_fmi2GetReal(INST(instance), valueReferences + k, 1, values + k) != fmi2OK) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues)
{
    if (instance == NULL || (nValueReferences && (valueReferences == NULL || values == NULL))) return fmi3Error;
    if (!counts_ok(instance, "fmi3SetFloat64", nValueReferences, nValues)) return fmi3Error;
    if (has_vr(valueReferences, nValueReferences, VR_TIME)) {
        say(INST(instance), fmi2Error, "fmi3SetFloat64: time is the independent variable; it cannot be set");
        return fmi3Error;
    }
    return (fmi3Status)sol2_fmi2SetReal(INST(instance), valueReferences, nValueReferences, values);
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues)
{
    fmi2Integer buf[16];
    size_t k, n;
    if (instance == NULL || (nValueReferences && (valueReferences == NULL || values == NULL))) return fmi3Error;
    if (!counts_ok(instance, "fmi3GetInt32", nValueReferences, nValues)) return fmi3Error;
    for (k = 0; k < nValueReferences; k += n) {
        size_t j;
        n = nValueReferences - k < 16 ? nValueReferences - k : 16;
        if (sol2_fmi2GetInteger(INST(instance), valueReferences + k, n, buf) != fmi2OK) return fmi3Error;
        for (j = 0; j < n; j++) values[k + j] = (fmi3Int32)buf[j];
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues)
{
    fmi2Integer buf[16];
    size_t k, n;
    if (instance == NULL || (nValueReferences && (valueReferences == NULL || values == NULL))) return fmi3Error;
    if (!counts_ok(instance, "fmi3SetInt32", nValueReferences, nValues)) return fmi3Error;
    for (k = 0; k < nValueReferences; k += n) {
        size_t j;
        n = nValueReferences - k < 16 ? nValueReferences - k : 16;
        for (j = 0; j < n; j++) buf[j] = (fmi2Integer)values[k + j];
        if (sol2_fmi2SetInteger(INST(instance), valueReferences + k, n, buf) != fmi2OK) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Boolean values[], size_t nValues)
{
    fmi2Boolean buf[16];
    size_t k, n;
    if (instance == NULL || (nValueReferences && (valueReferences == NULL || values == NULL))) return fmi3Error;
    if (!counts_ok(instance, "fmi3GetBoolean", nValueReferences, nValues)) return fmi3Error;
    for (k = 0; k < nValueReferences; k += n) {
        size_t j;
        n = nValueReferences - k < 16 ? nValueReferences - k : 16;
        if (sol2_fmi2GetBoolean(INST(instance), valueReferences + k, n, buf) != fmi2OK) return fmi3Error;
        for (j = 0; j < n; j++) values[k + j] = buf[j] ? true : false;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Boolean values[], size_t nValues)
{
    fmi2Boolean buf[16];
    size_t k, n;
    if (instance == NULL || (nValueReferences && (valueReferences == NULL || values == NULL))) return fmi3Error;
    if (!counts_ok(instance, "fmi3SetBoolean", nValueReferences, nValues)) return fmi3Error;
    for (k = 0; k < nValueReferences; k += n) {
        size_t j;
        n = nValueReferences - k < 16 ? nValueReferences - k : 16;
        for (j = 0; j < n; j++) buf[j] = values[k + j] ? fmi2True : fmi2False;
        if (sol2_fmi2SetBoolean(INST(instance), valueReferences + k, n, buf) != fmi2OK) return fmi3Error;
    }
    return fmi3OK;
}

/* Types this FMU has no variables of: only empty calls succeed. */
#define NO_VARIABLES(NAME, CONST, TYPE)                                                                        \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    CONST TYPE values[], size_t nValues)                                                       \
    {                                                                                                          \
        (void)valueReferences; (void)values; (void)nValues;                                                    \
        if (instance == NULL) return fmi3Error;                                                                \
        if (nValueReferences == 0) return fmi3OK;                                                              \
        say(INST(instance), fmi2Error, "%s: this FMU has no such variables", #NAME);                           \
        return fmi3Error;                                                                                      \
    }
#define NOCONST
NO_VARIABLES(fmi3GetFloat32, NOCONST, fmi3Float32)
NO_VARIABLES(fmi3GetInt8, NOCONST, fmi3Int8)
NO_VARIABLES(fmi3GetUInt8, NOCONST, fmi3UInt8)
NO_VARIABLES(fmi3GetInt16, NOCONST, fmi3Int16)
NO_VARIABLES(fmi3GetUInt16, NOCONST, fmi3UInt16)
NO_VARIABLES(fmi3GetUInt32, NOCONST, fmi3UInt32)
NO_VARIABLES(fmi3GetInt64, NOCONST, fmi3Int64)
NO_VARIABLES(fmi3GetUInt64, NOCONST, fmi3UInt64)
NO_VARIABLES(fmi3GetString, NOCONST, fmi3String)
NO_VARIABLES(fmi3SetFloat32, const, fmi3Float32)
NO_VARIABLES(fmi3SetInt8, const, fmi3Int8)
NO_VARIABLES(fmi3SetUInt8, const, fmi3UInt8)
NO_VARIABLES(fmi3SetInt16, const, fmi3Int16)
NO_VARIABLES(fmi3SetUInt16, const, fmi3UInt16)
NO_VARIABLES(fmi3SetUInt32, const, fmi3UInt32)
NO_VARIABLES(fmi3SetInt64, const, fmi3Int64)
NO_VARIABLES(fmi3SetUInt64, const, fmi3UInt64)
NO_VARIABLES(fmi3SetString, const, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    return instance != NULL && nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3GetBinary (no Binary variables)");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    return instance != NULL && nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3SetBinary (no Binary variables)");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[])
{
    (void)valueReferences; (void)values;
    return instance != NULL && nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3GetClock (no clocks)");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[])
{
    (void)valueReferences; (void)values;
    return instance != NULL && nValueReferences == 0 ? fmi3OK : refuse(instance, "fmi3SetClock (no clocks)");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference; (void)nDependencies;
    return refuse(instance, "fmi3GetNumberOfVariableDependencies (ModelStructure has them)");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    return refuse(instance, "fmi3GetVariableDependencies (ModelStructure has them)");
}

/* ---- FMU state ------------------------------------------------------------------------------- */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2GetFMUstate(INST(instance), (fmi2FMUstate *)FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2SetFMUstate(INST(instance), (fmi2FMUstate)FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2FreeFMUstate(INST(instance), (fmi2FMUstate *)FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2SerializedFMUstateSize(INST(instance), (fmi2FMUstate)FMUState, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2SerializeFMUstate(INST(instance), (fmi2FMUstate)FMUState, (fmi2Byte *)serializedState,
                                                   size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2DeSerializeFMUstate(INST(instance), (const fmi2Byte *)serializedState, size,
                                                     (fmi2FMUstate *)FMUState);
}

/* ---- not provided ---------------------------------------------------------------------------- */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return refuse(instance, "fmi3GetDirectionalDerivative");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return refuse(instance, "fmi3GetAdjointDerivative");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { return refuse(instance, "fmi3EnterConfigurationMode (no structural parameters)"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { return refuse(instance, "fmi3ExitConfigurationMode (no structural parameters)"); }

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences; (void)nValueReferences; (void)intervals; (void)qualifiers;
    return refuse(instance, "fmi3GetIntervalDecimal (no clocks)");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions; (void)qualifiers;
    return refuse(instance, "fmi3GetIntervalFraction (no clocks)");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return refuse(instance, "fmi3GetShiftDecimal (no clocks)");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return refuse(instance, "fmi3GetShiftFraction (no clocks)");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    (void)valueReferences; (void)nValueReferences; (void)intervals;
    return refuse(instance, "fmi3SetIntervalDecimal (no clocks)");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return refuse(instance, "fmi3SetIntervalFraction (no clocks)");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    (void)valueReferences; (void)nValueReferences; (void)shifts;
    return refuse(instance, "fmi3SetShiftDecimal (no clocks)");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)valueReferences; (void)nValueReferences; (void)counters; (void)resolutions;
    return refuse(instance, "fmi3SetShiftFraction (no clocks)");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { return refuse(instance, "fmi3EvaluateDiscreteStates"); }

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference; (void)activationTime;
    return refuse(instance, "fmi3ActivateModelPartition (no scheduled execution)");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    (void)valueReferences; (void)nValueReferences; (void)orders; (void)values; (void)nValues;
    return refuse(instance, "fmi3GetOutputDerivatives (maxOutputDerivativeOrder=0)");
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) { return refuse(instance, "fmi3EnterStepMode (hasEventMode=false)"); }

/* ---- model exchange -------------------------------------------------------------------------- */
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    fmi2EventInfo info;
    fmi2Status st;
    if (instance == NULL) return fmi3Error;
    st = sol2_fmi2NewDiscreteStates(INST(instance), &info);
    if (st != fmi2OK) return (fmi3Status)st;
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = info.newDiscreteStatesNeeded ? true : false;
    if (terminateSimulation) *terminateSimulation = info.terminateSimulation ? true : false;
    if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = info.nominalsOfContinuousStatesChanged ? true : false;
    if (valuesOfContinuousStatesChanged) *valuesOfContinuousStatesChanged = info.valuesOfContinuousStatesChanged ? true : false;
    if (nextEventTimeDefined) *nextEventTimeDefined = info.nextEventTimeDefined ? true : false;
    if (nextEventTime) *nextEventTime = info.nextEventTime;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2EnterContinuousTimeMode(INST(instance));
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    fmi2Boolean ev = fmi2False, term = fmi2False;
    fmi2Status st;
    if (instance == NULL || enterEventMode == NULL || terminateSimulation == NULL) return fmi3Error;
    st = sol2_fmi2CompletedIntegratorStep(INST(instance), noSetFMUStatePriorToCurrentPoint ? fmi2True : fmi2False,
                                          &ev, &term);
    *enterEventMode = ev ? true : false;
    *terminateSimulation = term ? true : false;
    return (fmi3Status)st;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2SetTime(INST(instance), time);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2SetContinuousStates(INST(instance), continuousStates, nContinuousStates);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2GetDerivatives(INST(instance), derivatives, nContinuousStates);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2GetEventIndicators(INST(instance), eventIndicators, nEventIndicators);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2GetContinuousStates(INST(instance), continuousStates, nContinuousStates);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates)
{
    if (instance == NULL) return fmi3Error;
    return (fmi3Status)sol2_fmi2GetNominalsOfContinuousStates(INST(instance), nominals, nContinuousStates);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    if (instance == NULL || nEventIndicators == NULL) return fmi3Error;
    *nEventIndicators = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    if (instance == NULL || nContinuousStates == NULL) return fmi3Error;
    *nContinuousStates = NX;
    return fmi3OK;
}

/* ---- co-simulation --------------------------------------------------------------------------- */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    fmi2Status st;
    if (instance == NULL) return fmi3Error;
    st = sol2_fmi2DoStep(INST(instance), currentCommunicationPoint, communicationStepSize,
                         noSetFMUStatePriorToCurrentPoint ? fmi2True : fmi2False);
    if (eventHandlingNeeded) *eventHandlingNeeded = false;
    if (terminateSimulation) *terminateSimulation = false;
    if (earlyReturn) *earlyReturn = false;
    if (lastSuccessfulTime)
        *lastSuccessfulTime = st == fmi2OK ? currentCommunicationPoint + communicationStepSize : currentCommunicationPoint;
    return (fmi3Status)st;
}
