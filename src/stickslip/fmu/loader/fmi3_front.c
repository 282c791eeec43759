/* The FMI 3 FMU's x86_64-linux binary: an FMI 3.0 front (co-simulation and model exchange) for pythonfmu3's binary.
 *
 * pythonfmu3's binary (shipped beside this one as SBF_INNER_LIBRARY) leaves every Py* symbol unresolved, as
 * PythonFMU's does. This library needs nothing but libc: on the first instantiation it finds and starts CPython
 * and loads pythonfmu3's binary (runtime.c), then forwards the FMI calls that pythonfmu3 implements (failures of
 * the model's calls as fmi3Error where the slave allows it: see FORWARDED). The functions pythonfmu3 leaves
 * unimplemented would throw a C++ exception through the host (std::terminate); they are answered here with
 * fmi3Error and a logged message instead (UNSUPPORTED), as is scheduled execution, and so are the model-exchange
 * functions on a co-simulation instance (EXCHANGE_ONLY) and the calls that FMI 3.0's state machines do not allow
 * in the state the instance is in (sbf_call_refused).
 * pythonfmu3 filters its error messages by the host's log categories too; it is therefore instantiated with
 * logging on and no categories, and this library filters: warnings, discards, errors and fatals always reach
 * the host's logMessage, other messages only as the host asked (loggingOn, fmi3SetDebugLogging categories).
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "runtime.h"

/* ---- FMI 3.0 types (as in the standard's fmi3PlatformTypes.h / fmi3FunctionTypes.h) ---- */
typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef void *fmi3FMUState;
typedef uint32_t fmi3ValueReference;
typedef float fmi3Float32;
typedef double fmi3Float64;
typedef int8_t fmi3Int8;
typedef uint8_t fmi3UInt8;
typedef int16_t fmi3Int16;
typedef uint16_t fmi3UInt16;
typedef int32_t fmi3Int32;
typedef uint32_t fmi3UInt32;
typedef int64_t fmi3Int64;
typedef uint64_t fmi3UInt64;
typedef bool fmi3Boolean;
typedef const char *fmi3String;
typedef uint8_t fmi3Byte;
typedef const fmi3Byte *fmi3Binary;
typedef bool fmi3Clock;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef enum { fmi3Independent, fmi3Constant, fmi3Fixed, fmi3Tunable, fmi3Discrete, fmi3Dependent } fmi3DependencyKind;
typedef enum { fmi3IntervalNotYetKnown, fmi3IntervalUnchanged, fmi3IntervalChanged } fmi3IntervalQualifier;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String category, fmi3String message);
typedef void (*fmi3IntermediateUpdateCallback)(fmi3InstanceEnvironment, fmi3Float64, fmi3Boolean, fmi3Boolean,
                                               fmi3Boolean, fmi3Boolean, fmi3Boolean *, fmi3Float64 *);
typedef void (*fmi3ClockUpdateCallback)(fmi3InstanceEnvironment);
typedef void (*fmi3LockPreemptionCallback)(void);
typedef void (*fmi3UnlockPreemptionCallback)(void);

#define EXPORT SBF_EXPORT

/* parameters of fmi3Get<T> and fmi3Set<T> */
#define GETTER(T) (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, T *values, size_t n)
#define SETTER(T) (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, const T *values, size_t n)
#define ARRAY_ARGS (vr, nvr, values, n)
#define GET_AND_SET(X, suffix, T)                                                                                 \
    X(fmi3Get##suffix, RECOVERABLE, GETTER(T), ARRAY_ARGS) X(fmi3Set##suffix, RECOVERABLE, SETTER(T), ARRAY_ARGS)

/* ---- the functions forwarded: X(name, failure, parameters, arguments after the instance) ----
 * failure RECOVERABLE: pythonfmu3 reports an exception of the slave method it calls as fmi3Fatal; with
 * SBF_SLAVE_SURVIVES_RELEASE (a slave whose methods balance pythonfmu3's release of it on an exception, as
 * SpringBlockFriction_fmi3's do) the instance stays valid for fmi3Reset, fmi3SetFMUState and fmi3FreeInstance,
 * which is what fmi3Error means, so fmi3Fatal is returned and logged as fmi3Error. KEPT: the status as is. */
#define FORWARDED(X)                                                                                               \
    X(fmi3SetInt32, RECOVERABLE, SETTER(fmi3Int32), ARRAY_ARGS)                                                   \
    GET_AND_SET(X, Int64, fmi3Int64)                                                                              \
    GET_AND_SET(X, UInt64, fmi3UInt64)                                                                            \
    GET_AND_SET(X, Boolean, fmi3Boolean)                                                                          \
    GET_AND_SET(X, String, fmi3String)                                                                            \
    X(fmi3GetDirectionalDerivative, KEPT,                                                                         \
      (fmi3Instance c, const fmi3ValueReference *unknowns, size_t nUnknowns, const fmi3ValueReference *knowns,    \
       size_t nKnowns, const fmi3Float64 *seed, size_t nSeed, fmi3Float64 *sensitivity, size_t nSensitivity),    \
      (unknowns, nUnknowns, knowns, nKnowns, seed, nSeed, sensitivity, nSensitivity))

/* The setter of the inputs that the loader may keep until the next step (sbf_keep_inputs): kept there, else
 * forwarded by forward_<name>; exported below. */
#define KEPT_SETTERS(X) X(fmi3SetFloat64, RECOVERABLE, SETTER(fmi3Float64), ARRAY_ARGS)

/* The model-exchange functions forwarded as they are, refused for a co-simulation instance (FMI 3.0 section
 * 2.3: "Not allowed in Co-Simulation") and outside the states they are allowed in (the last argument,
 * sbf_call_refused; fmi3SetTime also before Event Mode, where it sets the start time): forwarded by
 * forward_<name>, exported below (the model-exchange arrays are refused by refused_array). */
#define ANY_STATE (~0u)
#define EXCHANGE_ONLY(X)                                                                                           \
    X(fmi3CompletedIntegratorStep, KEPT,                                                                          \
      (fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *enterEventMode,                 \
       fmi3Boolean *terminateSimulation),                                                                         \
      (noSetFMUStatePriorToCurrentPoint, enterEventMode, terminateSimulation), SBF_IN(SBF_CONTINUOUS))            \
    X(fmi3SetTime, RECOVERABLE, (fmi3Instance c, fmi3Float64 time), (time),                                       \
      SBF_IN(SBF_INSTANTIATED) | SBF_IN(SBF_INITIALIZING) | SBF_IN(SBF_EVENT) | SBF_IN(SBF_CONTINUOUS))           \
    X(fmi3GetNumberOfEventIndicators, RECOVERABLE, (fmi3Instance c, size_t *n), (n), ANY_STATE)                   \
    X(fmi3GetNumberOfContinuousStates, RECOVERABLE, (fmi3Instance c, size_t *n), (n), ANY_STATE)

/* The getters of the outputs' types: answered from the fast path's buffer where it holds every value asked for
 * (fast_path.h), else forwarded by forward_<name> as calls that only read; exported below. X(name, failure,
 * parameters, arguments after the instance, the fast path's reader) */
#define READERS(X)                                                                                                 \
    X(fmi3GetFloat64, RECOVERABLE, GETTER(fmi3Float64), ARRAY_ARGS, fast_float64)                                 \
    X(fmi3GetInt32, RECOVERABLE, GETTER(fmi3Int32), ARRAY_ARGS, fast_int32)

/* The functions forwarded that move the instance between FMI 3's states (sbf_mode) or need one (event mode and
 * the discrete-state update: model exchange only), the deserialization of states, and the model-exchange arrays
 * whose size is checked (COUNTED): forwarded by forward_<name>, exported below. */
#define TRACKED(X)                                                                                                 \
    X(fmi3EnterContinuousTimeMode, KEPT, (fmi3Instance c), ())                                                    \
    X(fmi3SetContinuousStates, RECOVERABLE, (fmi3Instance c, const fmi3Float64 *x, size_t n), (x, n))             \
    X(fmi3GetEventIndicators, RECOVERABLE, (fmi3Instance c, fmi3Float64 *z, size_t n), (z, n))                    \
    X(fmi3GetContinuousStates, RECOVERABLE, (fmi3Instance c, fmi3Float64 *x, size_t n), (x, n))                   \
    X(fmi3GetNominalsOfContinuousStates, RECOVERABLE, (fmi3Instance c, fmi3Float64 *x, size_t n), (x, n))         \
    X(fmi3EnterEventMode, KEPT, (fmi3Instance c), ())                                                             \
    X(fmi3UpdateDiscreteStates, RECOVERABLE,                                                                      \
      (fmi3Instance c, fmi3Boolean *discreteStatesNeedUpdate, fmi3Boolean *terminateSimulation,                   \
       fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged, fmi3Boolean *nextEventTimeDefined,               \
       fmi3Float64 *nextEventTime),                                                                               \
      (discreteStatesNeedUpdate, terminateSimulation, nominalsChanged, valuesChanged, nextEventTimeDefined,       \
       nextEventTime))                                                                                            \
    X(fmi3EnterInitializationMode, RECOVERABLE,                                                                   \
      (fmi3Instance c, fmi3Boolean toleranceDefined, fmi3Float64 tolerance, fmi3Float64 startTime,                \
       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime),                                                        \
      (toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime))                                        \
    X(fmi3ExitInitializationMode, RECOVERABLE, (fmi3Instance c), ())                                              \
    X(fmi3Terminate, RECOVERABLE, (fmi3Instance c), ())                                                           \
    X(fmi3Reset, KEPT, (fmi3Instance c), ())                                                                      \
    X(fmi3DoStep, RECOVERABLE,                                                                                    \
      (fmi3Instance c, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,                  \
       fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,                            \
       fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime),             \
      (currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint, eventHandlingNeeded,  \
       terminateSimulation, earlyReturn, lastSuccessfulTime))                                                     \
    X(fmi3DeserializeFMUState, KEPT, (fmi3Instance c, const fmi3Byte *bytes, size_t size, fmi3FMUState *s),       \
      (bytes, size, s))

/* The getter of FMU states: the slave's (SBF_STATE_GOT), else forwarded by forward_<name>, exported below. */
#define STATE_GOT(X) X(fmi3GetFMUState, RECOVERABLE, (fmi3Instance c, fmi3FMUState *s), (s))

/* The functions forwarded that take an FMU state, refused for a NULL one (SBF_STATE_USED): forwarded by
 * forward_<name>, exported below. */
#define STATE_USED(X)                                                                                              \
    X(fmi3SetFMUState, RECOVERABLE, (fmi3Instance c, fmi3FMUState s), (s), sbf_state_set)                          \
    X(fmi3SerializedFMUStateSize, KEPT, (fmi3Instance c, fmi3FMUState s, size_t *size), (s, size), sbf_state_size) \
    X(fmi3SerializeFMUState, KEPT, (fmi3Instance c, fmi3FMUState s, fmi3Byte *bytes, size_t size), (s, bytes, size), \
      sbf_state_serialize)

/* ---- the functions pythonfmu3 does not implement, and the mode changes this FMU never allows (pythonfmu3
 * answers them with fmi3OK): configuration mode (the model has no structural parameter). X(name, parameters) */
#define UNSUPPORTED(X)                                                                                             \
    X(fmi3EnterConfigurationMode, (fmi3Instance c)) X(fmi3ExitConfigurationMode, (fmi3Instance c))               \
    X(fmi3GetFloat32, GETTER(fmi3Float32)) X(fmi3SetFloat32, SETTER(fmi3Float32))                                 \
    X(fmi3GetInt8, GETTER(fmi3Int8)) X(fmi3SetInt8, SETTER(fmi3Int8))                                             \
    X(fmi3GetUInt8, GETTER(fmi3UInt8)) X(fmi3SetUInt8, SETTER(fmi3UInt8))                                         \
    X(fmi3GetInt16, GETTER(fmi3Int16)) X(fmi3SetInt16, SETTER(fmi3Int16))                                         \
    X(fmi3GetUInt16, GETTER(fmi3UInt16)) X(fmi3SetUInt16, SETTER(fmi3UInt16))                                     \
    X(fmi3GetUInt32, GETTER(fmi3UInt32)) X(fmi3SetUInt32, SETTER(fmi3UInt32))                                     \
    X(fmi3GetBinary,                                                                                              \
      (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, size_t *sizes, fmi3Binary *values, size_t n))   \
    X(fmi3SetBinary, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, const size_t *sizes,              \
                      const fmi3Binary *values, size_t n))                                                        \
    X(fmi3GetClock, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, fmi3Clock *values))                \
    X(fmi3SetClock, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, const fmi3Clock *values))          \
    X(fmi3GetNumberOfVariableDependencies, (fmi3Instance c, fmi3ValueReference vr, size_t *n))                    \
    X(fmi3GetVariableDependencies,                                                                                \
      (fmi3Instance c, fmi3ValueReference dependent, size_t *elementIndicesOfDependent,                           \
       fmi3ValueReference *independents, size_t *elementIndicesOfIndependents, fmi3DependencyKind *kinds, size_t n)) \
    X(fmi3GetAdjointDerivative,                                                                                   \
      (fmi3Instance c, const fmi3ValueReference *unknowns, size_t nUnknowns, const fmi3ValueReference *knowns,    \
       size_t nKnowns, const fmi3Float64 *seed, size_t nSeed, fmi3Float64 *sensitivity, size_t nSensitivity))    \
    X(fmi3GetIntervalDecimal, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, fmi3Float64 *intervals, \
                               fmi3IntervalQualifier *qualifiers))                                                \
    X(fmi3GetIntervalFraction, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, fmi3UInt64 *counters,  \
                                fmi3UInt64 *resolutions, fmi3IntervalQualifier *qualifiers))                      \
    X(fmi3GetShiftDecimal, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, fmi3Float64 *shifts))      \
    X(fmi3GetShiftFraction, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, fmi3UInt64 *counters,     \
                             fmi3UInt64 *resolutions))                                                            \
    X(fmi3SetIntervalDecimal, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr,                          \
                               const fmi3Float64 *intervals))                                                     \
    X(fmi3SetIntervalFraction, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr,                         \
                                const fmi3UInt64 *counters, const fmi3UInt64 *resolutions))                       \
    X(fmi3SetShiftDecimal, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, const fmi3Float64 *shifts)) \
    X(fmi3SetShiftFraction, (fmi3Instance c, const fmi3ValueReference *vr, size_t nvr,                            \
                             const fmi3UInt64 *counters, const fmi3UInt64 *resolutions))                          \
    X(fmi3EvaluateDiscreteStates, (fmi3Instance c))                                                               \
    X(fmi3ActivateModelPartition, (fmi3Instance c, fmi3ValueReference clockReference, fmi3Float64 activationTime))

/* pythonfmu3's entry points */
static struct {
#define POINTER(name, failure, params, args, ...) fmi3Status(*name) params;
    READERS(POINTER)
    FORWARDED(POINTER)
    KEPT_SETTERS(POINTER)
    EXCHANGE_ONLY(POINTER)
    TRACKED(POINTER)
    STATE_USED(POINTER)
    STATE_GOT(POINTER)
#undef POINTER
    fmi3Instance (*fmi3InstantiateCoSimulation)(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean,
                                                fmi3Boolean, fmi3Boolean, const fmi3ValueReference *, size_t,
                                                fmi3InstanceEnvironment, fmi3LogMessageCallback,
                                                fmi3IntermediateUpdateCallback);
    fmi3Instance (*fmi3InstantiateModelExchange)(fmi3String, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean,
                                                 fmi3InstanceEnvironment, fmi3LogMessageCallback);
    void (*fmi3FreeInstance)(fmi3Instance);
    fmi3Status (*fmi3GetContinuousStateDerivatives)(fmi3Instance, fmi3Float64 *, size_t); /* see below */
    fmi3Status (*fmi3FreeFMUState)(fmi3Instance, fmi3FMUState *);                         /* see below */
} inner;

/* ---- one instance ---- */
typedef struct {
    fmi3Instance inner;
    sbf_mode mode; /* where FMI 3.0's state machine of the instance's interface is */
    int exchange;  /* a model-exchange instance */
    fmi3InstanceEnvironment environment; /* the host's */
    fmi3LogMessageCallback log_message;   /* the host's */
    sbf_log_filter logging;
    int fatal_is_error; /* during a RECOVERABLE call: pythonfmu3's fmi3Fatal is reported as fmi3Error */
    sbf_fast_path fast; /* steps and output reads without pythonfmu3 (fast_path.h) */
    char folder[4096]; /* the resources folder, as the host named it (fast.folder) */
    int early_return;  /* co-simulation, earlyReturnAllowed: fmi3DoStep stops at the first event inside a step */
    int event_mode;    /* co-simulation, eventModeUsed: that event is handled in Event Mode */
    size_t counts[2];  /* the numbers of continuous states [0] and event indicators [1], once asked (counted) */
    int counted[2];
} Instance;

static void host_log(const Instance *inst, fmi3Status status, const char *text)
{
    if (inst->log_message)
        inst->log_message(inst->environment, status, sbf_category(status, NULL), text);
    else
        fprintf(stderr, "[FMI 3 status %d] %s\n", (int)status, text);
}

/* pythonfmu3's logMessage (its instance environment is ours) */
static void relay_log(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    const Instance *inst = env;
    char tidy[4096];
    if (!message) message = "";
    if (inst->fatal_is_error && status == fmi3Fatal) {
        status = fmi3Error;
        message = sbf_exception_text(message, tidy, sizeof tidy);
    }
    category = sbf_category(status, category); /* pythonfmu3 passes "" for none */
    if (inst->log_message && sbf_log_wanted(&inst->logging, status, category))
        inst->log_message(inst->environment, status, category, message);
}

/* sbf_start's resolver: pythonfmu3's entry points */
static int resolve_inner(void *lib, const char *path)
{
#define LOAD(name, failure, params, args, ...) && (*(void **)&inner.name = sbf_symbol(lib, #name)) != NULL
    if (1 READERS(LOAD) FORWARDED(LOAD) KEPT_SETTERS(LOAD) EXCHANGE_ONLY(LOAD) TRACKED(LOAD) STATE_USED(LOAD) STATE_GOT(LOAD)
            LOAD(fmi3InstantiateCoSimulation, , , ) LOAD(fmi3InstantiateModelExchange, , , )
            LOAD(fmi3FreeInstance, , , ) LOAD(fmi3GetContinuousStateDerivatives, , , )
            LOAD(fmi3FreeFMUState, , , ))
        return 1;
#undef LOAD
    sbf_fail("%s lacks an FMI 3 function: %s", path, sbf_library_error());
    return 0;
}

/* ---- exported FMI 3 functions ---- */

EXPORT const char *fmi3GetVersion(void) { return "3.0"; }

static void free_instance(Instance *inst)
{
    sbf_fast_unbind(&inst->fast);
    sbf_set_log_filter(&inst->logging, 0, 0, NULL);
    free(inst);
}

/* A new Instance with Python and pythonfmu3 ready and the resources folder's path for it in `path`, or NULL after
 * a message to the host's logger (`function` cannot instantiate). */
static Instance *new_instance(const char *function, fmi3String name, fmi3String token, fmi3String resourcePath,
                              char *path, size_t size, fmi3Boolean loggingOn, fmi3InstanceEnvironment environment,
                              fmi3LogMessageCallback logMessage)
{
    char why[8192];
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    inst->environment = environment;
    inst->log_message = logMessage;
    inst->logging.on = loggingOn;
    inst->fast.folder = inst->folder;
    if (!sbf_check_instance(function, name, "instantiation token", token, resourcePath, inst->folder, path,
                            size < sizeof inst->folder ? size : sizeof inst->folder, why, sizeof why)) {
        host_log(inst, fmi3Error, why);
        free_instance(inst);
        return NULL;
    }
    if (!sbf_start(resolve_inner)) {
        host_log(inst, fmi3Fatal, sbf_start_error());
        free_instance(inst);
        return NULL;
    }
    sbf_keep_thread_state();
    return inst;
}

static Instance *instantiated(Instance *inst)
{
    if (inst && !inst->inner) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

/* pythonfmu3 has no intermediate update, event mode or early return in co-simulation: this library answers event
 * mode and early return itself (fmi3DoStep, fmi3EnterEventMode, fmi3UpdateDiscreteStates, fmi3EnterStepMode); the
 * host's intermediateUpdate callback is not passed on (the model description offers no intermediate update). */
EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                                fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                                fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                                const fmi3ValueReference *requiredIntermediateVariables,
                                                size_t nRequiredIntermediateVariables,
                                                fmi3InstanceEnvironment instanceEnvironment,
                                                fmi3LogMessageCallback logMessage,
                                                fmi3IntermediateUpdateCallback intermediateUpdate)
{
    char path[4096];
    (void)intermediateUpdate;
    Instance *inst = new_instance("fmi3InstantiateCoSimulation", instanceName, instantiationToken, resourcePath, path,
                                  sizeof path, loggingOn, instanceEnvironment, logMessage);
    if (inst) {
        inst->early_return = earlyReturnAllowed, inst->event_mode = eventModeUsed;
        sbf_instantiate_begin();
        sbf_fast_binding(&inst->fast);
        inst->inner = inner.fmi3InstantiateCoSimulation(instanceName, instantiationToken, path, visible, true,
                                                        eventModeUsed, earlyReturnAllowed,
                                                        requiredIntermediateVariables, nRequiredIntermediateVariables,
                                                        inst, relay_log, NULL);
        sbf_fast_binding(NULL);
        sbf_instantiate_end();
    }
    return instantiated(inst);
}

EXPORT fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                 fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                                 fmi3InstanceEnvironment instanceEnvironment,
                                                 fmi3LogMessageCallback logMessage)
{
    char path[4096];
    Instance *inst = new_instance("fmi3InstantiateModelExchange", instanceName, instantiationToken, resourcePath,
                                  path, sizeof path, loggingOn, instanceEnvironment, logMessage);
    if (inst) {
        inst->exchange = 1;
        sbf_instantiate_begin();
        inst->inner = inner.fmi3InstantiateModelExchange(instanceName, instantiationToken, path, visible, true,
                                                         inst, relay_log);
        sbf_instantiate_end();
    }
    return instantiated(inst);
}

EXPORT fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    Instance host = {.environment = instanceEnvironment, .log_message = logMessage};
    host_log(&host, fmi3Error,
             "fmi3InstantiateScheduledExecution: scheduled execution is not supported: this FMU offers co-simulation "
             "and model exchange");
    return NULL;
}

EXPORT void fmi3FreeInstance(fmi3Instance c)
{
    Instance *inst = c;
    if (!inst) return;
    sbf_keep_thread_state();
    sbf_call_begin();
    sbf_fast_unbind(&inst->fast);
    inner.fmi3FreeInstance(inst->inner);
    sbf_call_end();
    free_instance(inst);
}

/* FMI 3.0 section 2.3.1's rule: each of the n `categories` (every listed one if n = 0) is switched to `on`, the
 * others keep their state (FMI 2's rule, sbf_set_log_filter's, replaces them all). */
static void switch_categories(sbf_log_filter *filter, fmi3Boolean on, size_t n, const fmi3String *categories)
{
    const char *const *listed;
    size_t count = sbf_listed_categories(&listed), m = 0;
    const char *enabled[count];
    for (size_t k = 0; k < count; ++k) {
        int named = n == 0;
        for (size_t i = 0; i < n && !named; ++i) named = strcmp(categories[i], listed[k]) == 0;
        if (named ? on : sbf_log_wanted(filter, fmi3OK, listed[k])) enabled[m++] = listed[k];
    }
    sbf_set_log_filter(filter, m > 0, m, enabled);
}

/* Categories the model description does not list are refused (fmi3Error, a message), the filter kept. */
EXPORT fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t n, const fmi3String *categories)
{
    char why[1024];
    if (!c) return fmi3Error;
    if (!sbf_known_categories("fmi3SetDebugLogging", n, categories, why, sizeof why)) {
        host_log(c, fmi3Error, why);
        return fmi3Error;
    }
    switch_categories(&((Instance *)c)->logging, loggingOn, n, categories);
    return fmi3OK;
}

#define FORWARD(name, failure, params, args) \
    SBF_FORWARD(fmi3Status, fmi3Error, fmi3Fatal, name, failure, params, args)
FORWARDED(FORWARD)
#undef FORWARD

/* the fast path's readers with FMI 3's count of values: scalars only (n = nvr) */
static int fast_float64(sbf_fast_path *fast, const fmi3ValueReference *vr, size_t nvr, fmi3Float64 *values,
                        size_t n)
{
    return n == nvr && sbf_fast_reals(fast, vr, nvr, values);
}

static int fast_int32(sbf_fast_path *fast, const fmi3ValueReference *vr, size_t nvr, fmi3Int32 *values, size_t n)
{
    return n == nvr && sbf_fast_integers(fast, vr, nvr, values);
}

#define READER(name, failure, params, args, read) \
    SBF_READER(fmi3Status, fmi3OK, fmi3Error, fmi3Fatal, name, failure, params, args, read)
READERS(READER)
#undef READER
#define FORWARD(name, failure, params, args, ...) \
    SBF_FORWARD_AS(static, forward_##name, fmi3Status, fmi3Error, fmi3Fatal, name, failure, params, args)
KEPT_SETTERS(FORWARD)
EXCHANGE_ONLY(FORWARD)
TRACKED(FORWARD)
STATE_USED(FORWARD)
#undef FORWARD
#define FORWARD(name, failure, params, args, fast) \
    SBF_STATE_USED(fmi3Status, fmi3Error, name, forward_##name, params, args, fast)
STATE_USED(FORWARD)
#undef FORWARD
#define FORWARD(name, failure, params, args) \
    SBF_FORWARD_AS(static, forward_##name, fmi3Status, fmi3Error, fmi3Fatal, name, failure, params, args) \
    SBF_STATE_GOT(fmi3Status, fmi3Error, name, forward_##name, params, args)
STATE_GOT(FORWARD)
#undef FORWARD

/* `status` of a call that moves the instance `c` to `mode` when it succeeds */
static fmi3Status moved(fmi3Instance c, fmi3Status status, sbf_mode mode)
{
    Instance *inst = c;
    if (inst && status <= fmi3Warning) inst->mode = mode;
    return status;
}

/* 1 (after a message naming `function` and the state) unless the instance `c` is in one of the states `allowed`
 * (sbf_call_refused); 0 for no instance (the call refuses it) */
static int refused_in_state(fmi3Instance c, const char *function, unsigned allowed)
{
    char why[512];
    if (!c || !sbf_call_refused(((Instance *)c)->mode, allowed, function, why, sizeof why)) return 0;
    host_log(c, fmi3Error, why);
    return 1;
}

/* Values of inputs set in Step Mode of a co-simulation instance that the loader keeps until the next step
 * (sbf_keep_inputs: scalars, nValues = nValueReferences), else forwarded */
EXPORT fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference *vr, size_t nvr, const fmi3Float64 *values,
                                 size_t n)
{
    Instance *inst = c;
    if (inst && !inst->exchange && inst->mode == SBF_STEPPING && n == nvr) {
        sbf_keep_thread_state();
        sbf_call_begin();
        int done = sbf_keep_inputs(&inst->fast, vr, NULL, nvr, values);
        sbf_call_end();
        if (done) return fmi3OK;
    }
    return forward_fmi3SetFloat64(c, vr, nvr, values, n);
}

EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                              fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    char why[256];
    if (c && sbf_experiment_refused("fmi3EnterInitializationMode", toleranceDefined, tolerance, startTime,
                                    stopTimeDefined, stopTime, why, sizeof why)) {
        host_log(c, fmi3Error, why);
        return fmi3Error;
    }
    fmi3Status status = forward_fmi3EnterInitializationMode(c, toleranceDefined, tolerance, startTime,
                                                            stopTimeDefined, stopTime);
    if (status <= fmi3Warning) { /* pythonfmu3 keeps startTime to itself: the slave takes it as its time */
        fmi3Status timed = forward_fmi3SetTime(c, startTime);
        if (timed > status) status = timed;
    }
    return moved(c, status, SBF_INITIALIZING);
}

/* FMI 3.0 sections 3.2 and 4.2: model exchange, and a co-simulation instance that uses event mode, go on in Event
 * Mode, any other in Step Mode */
EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance c)
{
    fmi3Status status = forward_fmi3ExitInitializationMode(c);
    const Instance *inst = c;
    return moved(c, status, inst && (inst->exchange || inst->event_mode) ? SBF_EVENT : SBF_STEPPING);
}

/* True (and a logged error naming `function` and `reason`) if `c` is a co-simulation instance */
static int refused_in_co_simulation(fmi3Instance c, const char *function, const char *reason)
{
    char why[512];
    if (!c || ((Instance *)c)->exchange) return 0;
    snprintf(why, sizeof why, "%s is not allowed for a co-simulation instance: %s", function, reason);
    host_log(c, fmi3Error, why);
    return 1;
}
#define EXCHANGE_FUNCTION \
    "it is a model-exchange function (FMI 3.0: not allowed in co-simulation; the instance was made by " \
    "fmi3InstantiateCoSimulation)"

#define EXPORT_EXCHANGE_ONLY(name, failure, params, args, allowed)                                          \
    EXPORT fmi3Status name params                                                                          \
    {                                                                                                      \
        if (refused_in_co_simulation(c, #name, EXCHANGE_FUNCTION) || refused_in_state(c, #name, allowed))  \
            return fmi3Error;                                                                              \
        return forward_##name(c SBF_FORWARD_ARGS args);                                                    \
    }
EXCHANGE_ONLY(EXPORT_EXCHANGE_ONLY)
#undef EXPORT_EXCHANGE_ONLY

/* 1 (after a message naming `function`) unless the co-simulation instance `c` uses event mode and is in `mode`
 * (SBF_STEPPING or SBF_EVENT; the message as sbf_call_refused's) */
static int refused_event_call(fmi3Instance c, const char *function, sbf_mode mode)
{
    char why[512];
    Instance *inst = c;
    if (!inst->event_mode)
        snprintf(why, sizeof why, "%s is not allowed: this co-simulation instance was made with eventModeUsed = false",
                 function);
    else if (!sbf_call_refused(inst->mode, SBF_IN(mode), function, why, sizeof why))
        return 0;
    host_log(c, fmi3Error, why);
    return 1;
}

/* Co-simulation (eventModeUsed): from Step Mode to Event Mode, at the time the last fmi3DoStep reached */
EXPORT fmi3Status fmi3EnterEventMode(fmi3Instance c)
{
    if (!c) return fmi3Error;
    if (((Instance *)c)->exchange) {
        if (refused_in_state(c, "fmi3EnterEventMode", SBF_IN(SBF_EVENT) | SBF_IN(SBF_CONTINUOUS))) return fmi3Error;
        return moved(c, forward_fmi3EnterEventMode(c), SBF_EVENT);
    }
    if (refused_event_call(c, "fmi3EnterEventMode", SBF_STEPPING)) return fmi3Error;
    ((Instance *)c)->mode = SBF_EVENT;
    return fmi3OK;
}

/* Co-simulation in Event Mode: the event an early return stopped at, and the inputs set in Event Mode, applied by
 * the slave; nothing more to update, no state jumps, no time event. */
EXPORT fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *discreteStatesNeedUpdate,
                                           fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsChanged,
                                           fmi3Boolean *valuesChanged, fmi3Boolean *nextEventTimeDefined,
                                           fmi3Float64 *nextEventTime)
{
    char why[4096];
    Instance *inst = c;
    if (!inst) return fmi3Error;
    if (inst->exchange) {
        if (refused_in_state(c, "fmi3UpdateDiscreteStates", SBF_IN(SBF_EVENT))) return fmi3Error;
        return forward_fmi3UpdateDiscreteStates(c, discreteStatesNeedUpdate, terminateSimulation, nominalsChanged,
                                                valuesChanged, nextEventTimeDefined, nextEventTime);
    }
    if (refused_event_call(c, "fmi3UpdateDiscreteStates", SBF_EVENT)) return fmi3Error;
    sbf_keep_thread_state();
    sbf_call_begin();
    sbf_fast_forward(&inst->fast, 1);
    int failed = sbf_slave_apply_events(&inst->fast, why, sizeof why);
    sbf_call_end();
    if (failed) {
        host_log(c, fmi3Error, why);
        return fmi3Error;
    }
    *discreteStatesNeedUpdate = *terminateSimulation = *nominalsChanged = *valuesChanged = false;
    *nextEventTimeDefined = false;
    *nextEventTime = 0.0;
    return fmi3OK;
}

/* Model exchange: from Event Mode to Continuous-Time Mode */
EXPORT fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c)
{
    if (refused_in_co_simulation(c, "fmi3EnterContinuousTimeMode", EXCHANGE_FUNCTION) ||
        refused_in_state(c, "fmi3EnterContinuousTimeMode", SBF_IN(SBF_EVENT)))
        return fmi3Error;
    return moved(c, forward_fmi3EnterContinuousTimeMode(c), SBF_CONTINUOUS);
}

/* Co-simulation: from Event Mode back to Step Mode (FMI 3.0: not allowed in model exchange) */
EXPORT fmi3Status fmi3EnterStepMode(fmi3Instance c)
{
    if (!c) return fmi3Error;
    if (((Instance *)c)->exchange) {
        host_log(c, fmi3Error, "fmi3EnterStepMode is not allowed for a model-exchange instance: it is a "
                               "co-simulation function (FMI 3.0)");
        return fmi3Error;
    }
    if (refused_event_call(c, "fmi3EnterStepMode", SBF_EVENT)) return fmi3Error;
    ((Instance *)c)->mode = SBF_STEPPING;
    return fmi3OK;
}

EXPORT fmi3Status fmi3Terminate(fmi3Instance c) { return moved(c, forward_fmi3Terminate(c), SBF_TERMINATED); }

/* pythonfmu3 makes a new slave, which offers itself to the fast path again */
EXPORT fmi3Status fmi3Reset(fmi3Instance c)
{
    if (c) {
        sbf_fast_rebinding(&((Instance *)c)->fast);
        ((Instance *)c)->counted[0] = ((Instance *)c)->counted[1] = 0; /* asked of the new slave */
    }
    fmi3Status status = forward_fmi3Reset(c);
    sbf_fast_binding(NULL);
    return moved(c, status, SBF_INSTANTIATED);
}

/* fmi3DoStep of an instance made with earlyReturnAllowed, by the slave's step_to_event (sbf_slave_event_step):
 * fmi3OK with the time reached in *reached, *early if that is short of t + h, and *handling if the instance uses
 * event mode and the step stopped at an event (inside it or at its end, left for Event Mode), fmi3Error after a
 * message (and the time where the failed step left the FMU), or fmi3Discard, nothing done, if no slave is bound
 * (the step goes the usual way). */
static fmi3Status event_step(Instance *inst, double t, double h, char *why, size_t size, fmi3Boolean *early,
                             fmi3Boolean *handling, fmi3Float64 *reached)
{
    int stopped = 0;
    sbf_call_begin(); /* the slave hears of the last step, and takes the inputs kept, in the step */
    int outcome = sbf_slave_event_step(&inst->fast, t, h, inst->event_mode, reached, &stopped, why, size);
    sbf_call_end();
    if (outcome < 0) return fmi3Discard;
    *early = outcome == 0 && stopped && *reached < t + h;
    *handling = outcome == 0 && stopped && inst->event_mode;
    if (outcome == 0) return fmi3OK;
    host_log(inst, fmi3Error, why);
    sbf_slave_time(&inst->fast, reached);
    return fmi3Error;
}

EXPORT fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                             fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                             fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    char why[4096];
    /* pythonfmu3 writes only terminateSimulation, and only if the slave's do_step returns one; this FMU never
     * terminates, and returns early (at an event, handled in Event Mode if the instance uses it) only if allowed */
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = false;
    if (!c) return fmi3Error;
    if (sbf_step_refused(((Instance *)c)->mode, ((Instance *)c)->exchange, "fmi3DoStep", t, why, sizeof why)) {
        host_log(c, fmi3Error, why);
        return fmi3Error;
    }
    sbf_keep_thread_state();
    if (((Instance *)c)->early_return) {
        fmi3Status status = event_step(c, t, h, why, sizeof why, earlyReturn, eventHandlingNeeded, lastSuccessfulTime);
        if (status != fmi3Discard) return status;
    }
    fmi3Status status;
    switch (sbf_model_fast_step(&((Instance *)c)->fast, t, h, why, sizeof why)) {
    case 0: status = fmi3OK; break;
    case 1: host_log(c, fmi3Error, why); status = fmi3Error; break;
    default:
        status = forward_fmi3DoStep(c, t, h, noSetFMUStatePriorToCurrentPoint, eventHandlingNeeded,
                                    terminateSimulation, earlyReturn, lastSuccessfulTime);
    }
    if (status <= fmi3Warning)
        *lastSuccessfulTime = t + h;
    else
        sbf_slave_time(&((Instance *)c)->fast, lastSuccessfulTime); /* where a failed step left the FMU */
    return status;
}

SBF_DESERIALIZE(fmi3Status, fmi3Error, fmi3Warning, fmi3Byte, fmi3DeserializeFMUState, forward_fmi3DeserializeFMUState,
                fmi3SerializedFMUStateSize, fmi3SerializeFMUState, fmi3FreeFMUState)

/* Forwarded as RECOVERABLE, and more: pythonfmu3 0.3.4 crashes the process when the slave raises in
 * get_continuous_state_derivatives (in every other call it reports the exception). The slave therefore logs
 * such a failure as an error and answers NaN, returned here as fmi3Error: no non-finite derivative reaches
 * the host with a success status. */
SBF_FORWARD_AS(static, forward_derivatives, fmi3Status, fmi3Error, fmi3Fatal, fmi3GetContinuousStateDerivatives,
               RECOVERABLE, (fmi3Instance c, fmi3Float64 *dx, size_t n), (dx, n))

/* 1 (after a message naming `function`) if `c` is a co-simulation instance, or if `n` is not the number of the
 * instance's event indicators (`indicators`) or continuous states: pythonfmu3 reads or writes `n` values of its
 * lists, past their end (a Python exception left set in the host) or short of it. */
static int refused_array(fmi3Instance c, const char *function, size_t n, int indicators)
{
    char why[256];
    size_t count = 0;
    if (refused_in_co_simulation(c, function, EXCHANGE_FUNCTION)) return 1;
    if (!c) return 0;
    Instance *inst = c;
    /* asked of the slave once: only structural parameters change these numbers, and the FMU has none; the slave's
     * answer, a call into Python, cost about as much as the call it guards */
    fmi3Status status = fmi3OK;
    if (!inst->counted[indicators]) {
        status = indicators ? forward_fmi3GetNumberOfEventIndicators(c, &count)
                            : forward_fmi3GetNumberOfContinuousStates(c, &count);
        if (status <= fmi3Warning) {
            inst->counts[indicators] = count;
            inst->counted[indicators] = 1;
        }
    }
    count = inst->counts[indicators];
    if (status > fmi3Warning || n == count) return 0;
    snprintf(why, sizeof why, "%s: %s = %zu, but this FMU has %zu %s", function,
             indicators ? "nEventIndicators" : "nContinuousStates", n, count,
             indicators ? "event indicators" : "continuous states");
    host_log(c, fmi3Error, why);
    return 1;
}

/* The exported model-exchange function `name` with the array `values` of `n` doubles, refused (fmi3Error) for a
 * co-simulation instance or when `n` is not the FMU's count (refused_array) */
#define COUNTED(name, indicators, Values)                                                   \
    EXPORT fmi3Status name(fmi3Instance c, Values *values, size_t n)                        \
    {                                                                                       \
        return refused_array(c, #name, n, indicators) ? fmi3Error : forward_##name(c, values, n); \
    }
COUNTED(fmi3SetContinuousStates, 0, const fmi3Float64)
COUNTED(fmi3GetContinuousStates, 0, fmi3Float64)
COUNTED(fmi3GetNominalsOfContinuousStates, 0, fmi3Float64)
COUNTED(fmi3GetEventIndicators, 1, fmi3Float64)
#undef COUNTED

EXPORT fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 *dx, size_t n)
{
    if (refused_array(c, "fmi3GetContinuousStateDerivatives", n, 0)) return fmi3Error;
    fmi3Status status = forward_derivatives(c, dx, n);
    for (size_t i = 0; i < n && status <= fmi3Warning; i++)
        if (!isfinite(dx[i])) status = fmi3Error;
    return status;
}

/* The output derivatives (maxOutputDerivativeOrder), which pythonfmu3 lacks: answered by the slave's
 * get_output_derivatives through its binding (fast_path.h), for scalar outputs (n = nvr), in co-simulation only
 * (FMI 3.0), not after fmi3Terminate (as the FMI 2 FMU answers fmi2GetRealOutputDerivatives). */
EXPORT fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference *vr, size_t nvr,
                                           const fmi3Int32 *orders, fmi3Float64 *values, size_t n)
{
    char why[4096];
    Instance *inst = c;
    if (!inst) return fmi3Error;
    if (inst->exchange)
        snprintf(why, sizeof why, "fmi3GetOutputDerivatives is not allowed for a model-exchange instance: it is a "
                 "co-simulation function (FMI 3.0)");
    else if (n != nvr)
        snprintf(why, sizeof why, "fmi3GetOutputDerivatives: nValues = %zu, but the %zu outputs asked for are scalars "
                 "(nValues = nValueReferences)", n, nvr);
    else if (nvr && (!vr || !orders || !values))
        snprintf(why, sizeof why, "fmi3GetOutputDerivatives: a NULL array for %zu variables", nvr);
    else if (inst->mode == SBF_TERMINATED)
        snprintf(why, sizeof why, "fmi3GetOutputDerivatives: not allowed after fmi3Terminate");
    else {
        sbf_keep_thread_state();
        sbf_call_begin();
        sbf_fast_forward(&inst->fast, 0);
        int outcome = sbf_slave_derivatives(&inst->fast, "fmi3GetOutputDerivatives", "get_output_derivatives", vr, nvr,
                                            orders, values, 0, why, sizeof why);
        sbf_call_end();
        if (outcome == 0) return fmi3OK;
    }
    host_log(c, fmi3Error, why);
    return fmi3Error;
}

SBF_FREE_STATE(fmi3Status, fmi3Error, fmi3Fatal, fmi3FreeFMUState, fmi3FMUState)

#define REFUSE(name, params)                                                 \
    EXPORT fmi3Status name params                                            \
    {                                                                        \
        if (c) host_log(c, fmi3Error, #name " is not supported by this FMU"); \
        return fmi3Error;                                                    \
    }
UNSUPPORTED(REFUSE)
#undef REFUSE
