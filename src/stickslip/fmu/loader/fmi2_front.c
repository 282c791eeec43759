/* The FMI 2 FMU's linux64 binary: an FMI 2.0 front (co-simulation, and model exchange where the FMU declares it) for
 * PythonFMU's binary.
 *
 * PythonFMU's binary (shipped beside this one as SBF_INNER_LIBRARY) leaves every Py* symbol unresolved
 * and so loads only inside a Python process. This library needs nothing but libc: on the first
 * fmi2Instantiate it finds and starts CPython and loads PythonFMU's binary (runtime.c), then forwards
 * every FMI call to it (failures of the model's calls as fmi2Error where the slave allows it: see
 * FORWARDED). PythonFMU logs only when its debug logging is on, errors included; it is therefore always
 * instantiated with logging on, and this library filters: warnings, discards, errors and fatals always
 * reach the host's logger, other messages only as the host asked (loggingOn, fmi2SetDebugLogging categories).
 * PythonFMU has no model exchange: built with SBF_MODEL_EXCHANGE (an FMU whose model description has <ModelExchange>),
 * this library makes a model-exchange instance from a PythonFMU co-simulation instance and answers the
 * model-exchange calls through the slave's binding (sbf_slave_exchange), as it answers the input and output
 * derivatives; the model-exchange functions are refused on a co-simulation instance, and the co-simulation ones on a
 * model-exchange instance, with a message naming the call. A freed instance is kept and reset for the next
 * instantiation with the same folder, since PythonFMU's instantiation leaks (see take_kept).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "runtime.h"

/* ---- FMI 2.0 types (as in the standard's fmi2TypesPlatform.h / fmi2FunctionTypes.h) ---- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef char fmi2Byte;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;
typedef struct {
    fmi2Boolean newDiscreteStatesNeeded, terminateSimulation, nominalsOfContinuousStatesChanged,
        valuesOfContinuousStatesChanged, nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#define EXPORT SBF_EXPORT

/* ---- the functions forwarded: X(name, failure, parameters, arguments after the component) ----
 * failure RECOVERABLE: PythonFMU reports an exception of the slave method it calls as fmi2Fatal; with
 * SBF_SLAVE_SURVIVES_RELEASE (a slave whose methods balance PythonFMU's release of it on an exception, as
 * SpringBlockFriction's do) the instance stays valid for fmi2Reset, fmi2SetFMUstate and fmi2FreeInstance,
 * which is what fmi2Error means, so fmi2Fatal is returned and logged as fmi2Error. KEPT: the status as is. */
#define FORWARDED(X)                                                                                               \
    X(fmi2GetBoolean, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2Boolean *x), (v, n, x)) \
    X(fmi2GetString, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2String *x), (v, n, x)) \
    X(fmi2SetInteger, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Integer *x), (v, n, x)) \
    X(fmi2SetBoolean, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Boolean *x), (v, n, x)) \
    X(fmi2SetString, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2String *x), (v, n, x)) \
    X(fmi2GetDirectionalDerivative, KEPT,                                                                          \
      (fmi2Component c, const fmi2ValueReference *u, size_t nu, const fmi2ValueReference *k, size_t nk,            \
       const fmi2Real *dk, fmi2Real *du),                                                                          \
      (u, nu, k, nk, dk, du))                                                                                      \
    X(fmi2CancelStep, KEPT, (fmi2Component c), ())                                                                 \
    X(fmi2GetIntegerStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Integer *x), (k, x))               \
    X(fmi2GetBooleanStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Boolean *x), (k, x))               \
    X(fmi2GetStringStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2String *x), (k, x))

/* The getters of the outputs' types: answered from the fast path's buffer where it holds every value asked for
 * (fast_path.h), else forwarded by forward_<name> as calls that only read; exported below. X(name, failure,
 * parameters, arguments after the component, the fast path's reader) */
#define READERS(X)                                                                                                 \
    X(fmi2GetReal, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2Real *x), (v, n, x),  \
      sbf_fast_reals)                                                                                              \
    X(fmi2GetInteger, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2Integer *x),       \
      (v, n, x), sbf_fast_integers)

/* The setter of the inputs that the loader may keep until the next step (sbf_keep_inputs): kept there, else
 * forwarded by forward_<name>; exported below. */
#define KEPT_SETTERS(X) \
    X(fmi2SetReal, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Real *x), (v, n, x))

/* The functions forwarded that move the instance between FMI 2's states (sbf_mode) or need one, and the
 * deserialization of states: forwarded by forward_<name>, exported below. */
#define TRACKED(X)                                                                                                 \
    X(fmi2SetupExperiment, RECOVERABLE, (fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real d, fmi2Boolean e, fmi2Real f), \
      (a, b, d, e, f))                                                                                             \
    X(fmi2EnterInitializationMode, RECOVERABLE, (fmi2Component c), ())                                             \
    X(fmi2ExitInitializationMode, RECOVERABLE, (fmi2Component c), ())                                              \
    X(fmi2Terminate, RECOVERABLE, (fmi2Component c), ())                                                           \
    X(fmi2Reset, KEPT, (fmi2Component c), ())                                                                      \
    X(fmi2DoStep, RECOVERABLE, (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean k), (t, h, k))                \
    X(fmi2DeSerializeFMUstate, KEPT, (fmi2Component c, const fmi2Byte *b, size_t n, fmi2FMUstate *s), (b, n, s))    \
    X(fmi2GetRealStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Real *x), (k, x))

/* The getter of FMU states: the slave's (SBF_STATE_GOT), else forwarded by forward_<name>, exported below. */
#define STATE_GOT(X) X(fmi2GetFMUstate, RECOVERABLE, (fmi2Component c, fmi2FMUstate *s), (s))

/* The functions forwarded that take an FMU state, refused for a NULL one (SBF_STATE_USED): forwarded by
 * forward_<name>, exported below. */
#define STATE_USED(X)                                                                                              \
    X(fmi2SetFMUstate, RECOVERABLE, (fmi2Component c, fmi2FMUstate s), (s), sbf_state_set)                         \
    X(fmi2SerializedFMUstateSize, KEPT, (fmi2Component c, fmi2FMUstate s, size_t *n), (s, n), sbf_state_size)      \
    X(fmi2SerializeFMUstate, KEPT, (fmi2Component c, fmi2FMUstate s, fmi2Byte *b, size_t n), (s, b, n),             \
      sbf_state_serialize)

/* PythonFMU's entry points */
static struct {
#define POINTER(name, failure, params, args, ...) fmi2Status(*name) params;
    READERS(POINTER)
    FORWARDED(POINTER)
    KEPT_SETTERS(POINTER)
    TRACKED(POINTER)
    STATE_USED(POINTER)
    STATE_GOT(POINTER)
#undef POINTER
    fmi2Component (*fmi2Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                     fmi2Boolean, fmi2Boolean);
    void (*fmi2FreeInstance)(fmi2Component);
    fmi2Status (*fmi2SetDebugLogging)(fmi2Component, fmi2Boolean, size_t, const fmi2String *);
    fmi2Status (*fmi2FreeFMUstate)(fmi2Component, fmi2FMUstate *); /* see below */
} inner;

/* ---- one instance ---- */
typedef struct {
    fmi2Component inner;
    sbf_mode mode; /* where FMI 2.0's state machine of the instance's interface is */
    int exchange;  /* a model-exchange instance */
    fmi2CallbackFunctions host;   /* the importer's callbacks */
    fmi2CallbackFunctions relay;  /* handed to PythonFMU: logs through relay_log */
    char *name;
    sbf_log_filter logging;
    int fatal_is_error; /* during a RECOVERABLE call: PythonFMU's fmi2Fatal is reported as fmi2Error */
    sbf_fast_path fast; /* steps and output reads without PythonFMU (fast_path.h) */
    char folder[4096]; /* the resources folder, as the host named it (fast.folder) */
    char inner_path[4096]; /* the path to it that PythonFMU was given */
    fmi2Boolean visible;
    void *next_kept; /* the next freed instance kept for reuse (see take_kept) */
} Instance;

static void host_log(const Instance *inst, fmi2Status status, const char *text)
{
    const char *category = sbf_category(status, NULL);
    if (inst->host.logger)
        inst->host.logger(inst->host.componentEnvironment, inst->name, status, category, "%s", text);
    else
        fprintf(stderr, "[%s] %s: %s\n", category, inst->name, text);
}

/* PythonFMU's logger: its message is plain text (it passes no format arguments) */
static void relay_log(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                      fmi2String message, ...)
{
    const Instance *inst = env;
    char tidy[4096];
    (void)name;
    if (!message) message = "";
    if (inst->fatal_is_error && status == fmi2Fatal) {
        status = fmi2Error;
        message = sbf_exception_text(message, tidy, sizeof tidy);
    }
    category = sbf_category(status, category); /* PythonFMU passes NULL for none */
    if (inst->host.logger && sbf_log_wanted(&inst->logging, status, category))
        inst->host.logger(inst->host.componentEnvironment, inst->name, status, category, "%s", message);
}

/* sbf_start's resolver: PythonFMU's entry points */
static int resolve_inner(void *lib, const char *path)
{
#define LOAD(name, failure, params, args, ...) && (*(void **)&inner.name = sbf_symbol(lib, #name)) != NULL
    if (1 READERS(LOAD) FORWARDED(LOAD) KEPT_SETTERS(LOAD) TRACKED(LOAD) STATE_USED(LOAD) STATE_GOT(LOAD) LOAD(fmi2Instantiate, , , )
            LOAD(fmi2FreeInstance, , , ) LOAD(fmi2SetDebugLogging, , , )
            LOAD(fmi2FreeFMUstate, , , ))
        return 1;
#undef LOAD
    sbf_fail("%s lacks an FMI 2 function: %s", path, sbf_library_error());
    return 0;
}

/* ---- exported FMI 2 functions ---- */

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

static void free_instance(Instance *inst)
{
    sbf_fast_unbind(&inst->fast);
    sbf_set_log_filter(&inst->logging, 0, 0, NULL);
    free(inst->name);
    free(inst);
}

/* Why the instance asked for cannot be made (0 after a message to the host), else 1 with the resources folder in
 * inst->folder and the path to it for PythonFMU in `path` (as big as inst->folder). */
static int instantiable(Instance *inst, fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                        char *path)
{
    char why[8192];
    if (!sbf_check_instance("fmi2Instantiate", name, "GUID", guid, resources, inst->folder, path, sizeof inst->folder,
                            why, sizeof why)) {
        host_log(inst, fmi2Error, why);
        return 0;
    }
#ifdef SBF_MODEL_EXCHANGE
    if (type == fmi2ModelExchange || type == fmi2CoSimulation) return 1;
    snprintf(why, sizeof why, "fmi2Instantiate: fmuType = %d is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)",
             (int)type);
#else
    snprintf(why, sizeof why, "fmi2Instantiate: this FMU offers co-simulation only (fmuType = fmi2CoSimulation, "
             "1), not fmuType = %d%s", (int)type, type == fmi2ModelExchange ? " (fmi2ModelExchange)" : "");
    if (type == fmi2CoSimulation) return 1;
#endif
    host_log(inst, fmi2Error, why);
    return 0;
}

/* ---- freed instances kept for reuse ----
 * PythonFMU 0.7.0's instantiation leaves about 1.3 kB of Python objects behind each time, for the life of the process
 * (17 objects, measured with tracemalloc: it inserts the resources path into sys.path again, and keeps the method
 * resolution order of the slave class as a list and each of its classes' names as a string and as bytes); its reset
 * makes a new slave without any of that. So fmi2FreeInstance keeps the freed instance, with PythonFMU's instance in
 * it, and the next fmi2Instantiate with the same path for PythonFMU and visibility takes it and resets it to a new
 * slave (PythonFMU's slave is made with the instance name it was first given, which nothing of the slave uses; the
 * messages reach the host under the name the host gave). A host keeps as many as it had at once. */
static Instance *kept;

/* A kept instance made with `path` and `visible`, taken out of the kept ones, or NULL */
static Instance *take_kept(const char *path, fmi2Boolean visible)
{
    sbf_loader_lock();
    Instance **link = &kept;
    while (*link && (strcmp((*link)->inner_path, path) != 0 || (*link)->visible != visible))
        link = (Instance **)&(*link)->next_kept;
    Instance *found = *link;
    if (found) *link = found->next_kept;
    sbf_loader_unlock();
    return found;
}

static void keep(Instance *inst)
{
    sbf_loader_lock();
    inst->next_kept = kept;
    kept = inst;
    sbf_loader_unlock();
}

/* The kept instance `old` made new with the host's settings in `fresh` (freed), PythonFMU's instance reset to a new
 * slave; NULL (both freed) if the reset fails. */
static Instance *renewed(Instance *old, Instance *fresh)
{
    free(old->name);
    old->name = fresh->name;
    fresh->name = NULL;
    old->host = fresh->host;
    old->relay = fresh->host;
    old->relay.logger = relay_log;
    old->relay.componentEnvironment = old;
    sbf_set_log_filter(&old->logging, fresh->logging.on, 0, NULL);
    old->mode = fresh->mode;
    old->exchange = fresh->exchange;
    memcpy(old->folder, fresh->folder, sizeof old->folder);
    free_instance(fresh);
    sbf_call_begin();
    sbf_fast_rebinding(&old->fast);
    fmi2Status status = inner.fmi2Reset(old->inner);
    sbf_fast_binding(NULL);
    sbf_call_end();
    if (status <= fmi2Warning) return old;
    inner.fmi2FreeInstance(old->inner);
    free_instance(old);
    return NULL;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean loggingOn)
{
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    inst->fast.folder = inst->folder;
    inst->name = strdup(name ? name : "");
    if (functions) inst->host = *functions;
    inst->relay = inst->host;
    inst->relay.logger = relay_log;
    inst->relay.componentEnvironment = inst;
    inst->logging.on = loggingOn;
    inst->visible = visible;
    if (!instantiable(inst, name, type, guid, resources, inst->inner_path)) {
        free_instance(inst);
        return NULL;
    }
    if (!sbf_start(resolve_inner)) {
        host_log(inst, fmi2Fatal, sbf_start_error());
        free_instance(inst);
        return NULL;
    }
    sbf_keep_thread_state();
    /* a model-exchange instance is PythonFMU's co-simulation instance, the model-exchange calls answered here */
    inst->exchange = type == fmi2ModelExchange, inst->mode = SBF_INSTANTIATED;
    Instance *old = take_kept(inst->inner_path, visible);
    if (old) return renewed(old, inst);
    sbf_instantiate_begin();
    sbf_fast_binding(&inst->fast);
    inst->inner = inner.fmi2Instantiate(name, fmi2CoSimulation, guid, inst->inner_path, &inst->relay, visible, 1);
    sbf_fast_binding(NULL);
    sbf_instantiate_end();
    if (!inst->inner) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

/* The instance is kept for reuse (see take_kept), its slave dropped by the fast path */
EXPORT void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = c;
    if (!inst) return;
    sbf_keep_thread_state();
    sbf_call_begin();
    sbf_fast_unbind(&inst->fast);
    sbf_call_end();
    keep(inst);
}

/* Categories the model description does not list are refused (fmi2Error, a message), the filter kept. */
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String *categories)
{
    char why[1024];
    if (!c) return fmi2Error;
    if (!sbf_known_categories("fmi2SetDebugLogging", n, categories, why, sizeof why)) {
        host_log(c, fmi2Error, why);
        return fmi2Error;
    }
    sbf_set_log_filter(&((Instance *)c)->logging, loggingOn, n, categories);
    return fmi2OK;
}

/* No fmi2DoStep of this FMU returns fmi2Pending, so there is no step status to give: fmi2Discard, the standard's
 * answer for a status the slave cannot retrieve (PythonFMU answers fmi2Error, which would end the instance). */
EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s, (void)value;
    if (!c) return fmi2Error;
    host_log(c, fmi2Discard, "fmi2GetStatus: no status to give: fmi2DoStep of this FMU never returns fmi2Pending");
    return fmi2Discard;
}

#define FORWARD(name, failure, params, args) \
    SBF_FORWARD(fmi2Status, fmi2Error, fmi2Fatal, name, failure, params, args)
FORWARDED(FORWARD)
#undef FORWARD

#define READER(name, failure, params, args, read) \
    SBF_READER(fmi2Status, fmi2OK, fmi2Error, fmi2Fatal, name, failure, params, args, read)
READERS(READER)
#undef READER

SBF_FREE_STATE(fmi2Status, fmi2Error, fmi2Fatal, fmi2FreeFMUstate, fmi2FMUstate)
#define FORWARD(name, failure, params, args, ...) \
    SBF_FORWARD_AS(static, forward_##name, fmi2Status, fmi2Error, fmi2Fatal, name, failure, params, args)
KEPT_SETTERS(FORWARD)
TRACKED(FORWARD)
STATE_USED(FORWARD)
#undef FORWARD
#define FORWARD(name, failure, params, args, fast) \
    SBF_STATE_USED(fmi2Status, fmi2Error, name, forward_##name, params, args, fast)
STATE_USED(FORWARD)
#undef FORWARD
#define FORWARD(name, failure, params, args, ...) \
    SBF_FORWARD_AS(static, forward_##name, fmi2Status, fmi2Error, fmi2Fatal, name, failure, params, args) \
    SBF_STATE_GOT(fmi2Status, fmi2Error, name, forward_##name, params, args)
STATE_GOT(FORWARD)
#undef FORWARD

/* `status` of a call that moves the instance `c` to `mode` when it succeeds */
static fmi2Status moved(fmi2Component c, fmi2Status status, sbf_mode mode)
{
    Instance *inst = c;
    if (inst && status <= fmi2Warning) inst->mode = mode;
    return status;
}

/* 1 (after a message naming `function` and the state) unless the instance `c` is in one of the states `allowed`
 * (sbf_call_refused) */
static int refused_in_state(fmi2Component c, const char *function, unsigned allowed)
{
    char why[512];
    if (!sbf_call_refused(((Instance *)c)->mode, allowed, function, why, sizeof why)) return 0;
    host_log(c, fmi2Error, why);
    return 1;
}

/* 1 if the loader kept the n values of the real inputs vr[0..n) (their derivatives of the orders order[0..n), or the
 * values themselves where `order` is NULL) until the next step: a co-simulation instance in Step Mode
 * (sbf_keep_inputs) */
static int inputs_kept(fmi2Component c, const fmi2ValueReference *vr, const fmi2Integer *order, size_t n,
                       const fmi2Real *values)
{
    Instance *inst = c;
    if (!inst || inst->exchange || inst->mode != SBF_STEPPING) return 0;
    sbf_keep_thread_state();
    sbf_call_begin();
    int done = sbf_keep_inputs(&inst->fast, vr, order, n, values);
    sbf_call_end();
    return done;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference *vr, size_t n, const fmi2Real *value)
{
    return inputs_kept(c, vr, NULL, n, value) ? fmi2OK : forward_fmi2SetReal(c, vr, n, value);
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    char why[256];
    if (c && sbf_experiment_refused("fmi2SetupExperiment", toleranceDefined, tolerance, startTime, stopTimeDefined,
                                    stopTime, why, sizeof why)) {
        host_log(c, fmi2Error, why);
        return fmi2Error;
    }
    return forward_fmi2SetupExperiment(c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    return moved(c, forward_fmi2EnterInitializationMode(c), SBF_INITIALIZING);
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    /* model exchange goes on in Event Mode (FMI 2.0 section 3.2.3), co-simulation in Step Mode */
    return moved(c, forward_fmi2ExitInitializationMode(c), c && ((Instance *)c)->exchange ? SBF_EVENT : SBF_STEPPING);
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) { return moved(c, forward_fmi2Terminate(c), SBF_TERMINATED); }

/* PythonFMU makes a new slave, which offers itself to the fast path again */
EXPORT fmi2Status fmi2Reset(fmi2Component c)
{
    if (c) sbf_fast_rebinding(&((Instance *)c)->fast);
    fmi2Status status = forward_fmi2Reset(c);
    sbf_fast_binding(NULL);
    return moved(c, status, SBF_INSTANTIATED);
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    char why[4096];
    if (!c) return fmi2Error;
    if (sbf_step_refused(((Instance *)c)->mode, ((Instance *)c)->exchange, "fmi2DoStep", t, why, sizeof why)) {
        host_log(c, fmi2Error, why);
        return fmi2Error;
    }
    sbf_keep_thread_state();
    switch (sbf_model_fast_step(&((Instance *)c)->fast, t, h, why, sizeof why)) {
    case 0: return fmi2OK;
    case 1: host_log(c, fmi2Error, why); return fmi2Error;
    default: return forward_fmi2DoStep(c, t, h, noSetFMUStatePriorToCurrentPoint);
    }
}

/* fmi2LastSuccessfulTime: the time the FMU is at, from the slave (sbf_slave_time), which knows it after every step
 * (PythonFMU does not see the fast path's), a failed step that went part of the way, a restored state or a reset;
 * PythonFMU's answer where no slave is bound (then it takes every step itself). */
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    if (c && s == fmi2LastSuccessfulTime && value) {
        sbf_keep_thread_state();
        if (sbf_slave_time(&((Instance *)c)->fast, value)) return fmi2OK;
    }
    return forward_fmi2GetRealStatus(c, s, value);
}

/* The input and output derivatives (canInterpolateInputs, maxOutputDerivativeOrder), which PythonFMU lacks: answered
 * by the slave's `method` through its binding (fast_path.h); `writes`: the call sets inputs. */
static fmi2Status derivatives(fmi2Component c, const char *function, const char *method, const fmi2ValueReference *vr,
                              size_t n, const fmi2Integer *order, fmi2Real *values, int writes)
{
    char why[4096];
    Instance *inst = c;
    if (!inst) return fmi2Error;
    if (n && (!vr || !order || !values)) {
        snprintf(why, sizeof why, "%s: a NULL array for %zu variables", function, n);
        host_log(c, fmi2Error, why);
        return fmi2Error;
    }
    if (inst->exchange || inst->mode == SBF_TERMINATED) {
        snprintf(why, sizeof why, "%s: not allowed %s", function,
                 inst->exchange ? "for a model-exchange instance: it is a co-simulation function"
                                : "after fmi2Terminate");
        host_log(c, fmi2Error, why);
        return fmi2Error;
    }
    if (writes && inputs_kept(c, vr, order, n, values)) return fmi2OK;
    sbf_keep_thread_state();
    sbf_call_begin();
    sbf_fast_forward(&inst->fast, writes);
    int outcome = sbf_slave_derivatives(&inst->fast, function, method, vr, n, order, values, writes, why, sizeof why);
    sbf_call_end();
    switch (outcome) {
    case 0: return fmi2OK;
    case 2: host_log(c, fmi2Warning, why); return fmi2Warning;
    default: host_log(c, fmi2Error, why); return fmi2Error;
    }
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference *vr, size_t n,
                                              const fmi2Integer *order, const fmi2Real *values)
{
    return derivatives(c, "fmi2SetRealInputDerivatives", "set_real_input_derivatives", vr, n, order,
                       (fmi2Real *)values, 1);
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference *vr, size_t n,
                                               const fmi2Integer *order, fmi2Real *values)
{
    return derivatives(c, "fmi2GetRealOutputDerivatives", "get_real_output_derivatives", vr, n, order, values, 0);
}

SBF_DESERIALIZE(fmi2Status, fmi2Error, fmi2Warning, fmi2Byte, fmi2DeSerializeFMUstate, forward_fmi2DeSerializeFMUstate,
                fmi2SerializedFMUstateSize, fmi2SerializeFMUstate, fmi2FreeFMUstate)

/* ---- model exchange ---- */

/* 1 (and a logged error naming `function`) unless `c` is a model-exchange instance */
static int refused_in_co_simulation(fmi2Component c, const char *function)
{
    char why[512];
    if (c && ((Instance *)c)->exchange) return 0;
    if (!c) return 1;
    snprintf(why, sizeof why, "%s is not allowed for a co-simulation instance: it is a model-exchange function (the "
             "instance was made by fmi2Instantiate with fmuType = fmi2CoSimulation)", function);
    host_log(c, fmi2Error, why);
    return 1;
}

/* The model-exchange call `function` answered by the slave (sbf_slave_exchange): `n_in` numbers given, `count` the
 * length of the call's array, `n_out` numbers answered; refused on a co-simulation instance or for a NULL array. */
static fmi2Status exchanged(fmi2Component c, const char *function, const double *in, size_t n_in, size_t count,
                            double *out, size_t n_out)
{
    char why[4096];
    Instance *inst = c;
    if (refused_in_co_simulation(c, function)) return fmi2Error;
    if ((n_in && !in) || (n_out && !out)) {
        snprintf(why, sizeof why, "%s: a NULL array for %zu values", function, n_in + n_out);
        host_log(c, fmi2Error, why);
        return fmi2Error;
    }
    sbf_keep_thread_state();
    sbf_call_begin();
    sbf_fast_forward(&inst->fast, 1);
    int outcome = sbf_slave_exchange(&inst->fast, function, in, n_in, count, out, n_out, why, sizeof why);
    sbf_call_end();
    if (outcome == 0) return fmi2OK;
    host_log(c, fmi2Error, why);
    return fmi2Error;
}

/* FMI 2.0 section 3.2.3 allows it in Event and Continuous-Time Mode; before, it sets the start time too */
#define SET_TIME_ALLOWED \
    (SBF_IN(SBF_INSTANTIATED) | SBF_IN(SBF_INITIALIZING) | SBF_IN(SBF_EVENT) | SBF_IN(SBF_CONTINUOUS))

EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    if (refused_in_co_simulation(c, "fmi2SetTime") || refused_in_state(c, "fmi2SetTime", SET_TIME_ALLOWED))
        return fmi2Error;
    return exchanged(c, "fmi2SetTime", &time, 1, 0, NULL, 0);
}

EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    return exchanged(c, "fmi2SetContinuousStates", x, nx, nx, NULL, 0);
}

/* The exported model-exchange getter `name` of an array of `n` numbers */
#define ARRAY_GETTER(name, n)                                                    \
    EXPORT fmi2Status name(fmi2Component c, fmi2Real values[], size_t n)         \
    {                                                                            \
        return exchanged(c, #name, NULL, 0, n, values, n);                       \
    }
ARRAY_GETTER(fmi2GetContinuousStates, nx)
ARRAY_GETTER(fmi2GetDerivatives, nx)
ARRAY_GETTER(fmi2GetNominalsOfContinuousStates, nx)
ARRAY_GETTER(fmi2GetEventIndicators, ni)
#undef ARRAY_GETTER

/* The mode changes need nothing of the slave (the event update is fmi2NewDiscreteStates): from Event or
 * Continuous-Time Mode to Event Mode, from Event Mode to Continuous-Time Mode */
EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    if (refused_in_co_simulation(c, "fmi2EnterEventMode") ||
        refused_in_state(c, "fmi2EnterEventMode", SBF_IN(SBF_EVENT) | SBF_IN(SBF_CONTINUOUS)))
        return fmi2Error;
    return moved(c, fmi2OK, SBF_EVENT);
}

EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    if (refused_in_co_simulation(c, "fmi2EnterContinuousTimeMode") ||
        refused_in_state(c, "fmi2EnterContinuousTimeMode", SBF_IN(SBF_EVENT)))
        return fmi2Error;
    return moved(c, fmi2OK, SBF_CONTINUOUS);
}

EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    double answer[6];
    if (refused_in_co_simulation(c, "fmi2NewDiscreteStates") ||
        refused_in_state(c, "fmi2NewDiscreteStates", SBF_IN(SBF_EVENT)))
        return fmi2Error;
    if (!info) return exchanged(c, "fmi2NewDiscreteStates", NULL, 0, 0, NULL, 1); /* refused: a NULL fmi2EventInfo */
    fmi2Status status = exchanged(c, "fmi2NewDiscreteStates", NULL, 0, 0, answer, 6);
    if (status > fmi2Warning) return status;
    *info = (fmi2EventInfo){answer[0] != 0.0, answer[1] != 0.0, answer[2] != 0.0, answer[3] != 0.0, answer[4] != 0.0,
                            answer[5]};
    return status;
}

EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                              fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    double answer[2];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (refused_in_co_simulation(c, "fmi2CompletedIntegratorStep") ||
        refused_in_state(c, "fmi2CompletedIntegratorStep", SBF_IN(SBF_CONTINUOUS)))
        return fmi2Error;
    if (!enterEventMode || !terminateSimulation)
        return exchanged(c, "fmi2CompletedIntegratorStep", NULL, 0, 0, NULL, 2); /* refused: a NULL argument */
    fmi2Status status = exchanged(c, "fmi2CompletedIntegratorStep", NULL, 0, 0, answer, 2);
    if (status <= fmi2Warning) *enterEventMode = answer[0] != 0.0, *terminateSimulation = answer[1] != 0.0;
    return status;
}
