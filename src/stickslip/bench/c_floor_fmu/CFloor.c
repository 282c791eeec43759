/* CFloor: a compiled FMI 2.0 co-simulation FMU that does nothing, the physical floor of an FMI call.
 * One output x (value reference 0) and one input u (1), both Real and held as set (start 0);
 * fmi2DoStep returns at once. Every other function an importer may look up exists and succeeds
 * where it makes sense; derivatives are not supported (fmi2Error). FMU states are copies of the variables,
 * serialized as STATE_BYTES bytes (the variables, then zeros).
 * Self-contained: the FMI 2 types are declared here, no headers of the standard are needed. */
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

typedef void *fmi2Component;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef int fmi2StatusKind;
typedef struct {
    void (*logger)(void *, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} fmi2CallbackFunctions;

enum { N_REALS = 2 }; /* x, u */

/* The size of a serialized state (bytes): that of a serialized state of SpringBlockFriction.fmu (FMI 2) where the
 * FMU-state benchmark measures it (bench/state_costs.py: msl-pendulum after 0.1 s in steps of 1 ms, slipping, its
 * segment a Runge-Kutta step; measured 614 bytes with FMPy's serializeFMUstate, docs/hosts.md#fmu-states), so that
 * an importer's work with the bytes (a buffer made, filled and copied) is the same as with that FMU. */
#define STATE_BYTES 614

typedef struct {
    fmi2Real reals[N_REALS];
} Instance;

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean logging)
{
    (void)name, (void)guid, (void)resources, (void)functions, (void)visible, (void)logging;
    return type == fmi2CoSimulation ? calloc(1, sizeof(Instance)) : NULL;
}

EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[])
{
    (void)c, (void)on, (void)n, (void)categories;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolerance_defined, fmi2Real tolerance,
                                      fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop)
{
    (void)c, (void)tolerance_defined, (void)tolerance, (void)start, (void)stop_defined, (void)stop;
    return fmi2OK;
}

static fmi2Status no_op(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return no_op(c); }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return no_op(c); }
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { return no_op(c); }

EXPORT fmi2Status fmi2Reset(fmi2Component c)
{
    memset(c, 0, sizeof(Instance));
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    const Instance *instance = c;
    for (size_t i = 0; i < n; ++i) {
        if (vr[i] >= N_REALS) return fmi2Error;
        value[i] = instance->reals[vr[i]];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    Instance *instance = c;
    for (size_t i = 0; i < n; ++i) {
        if (vr[i] >= N_REALS) return fmi2Error;
        instance->reals[vr[i]] = value[i];
    }
    return fmi2OK;
}

/* no Integer, Boolean or String variables: only empty requests succeed */
#define NO_VARIABLES(function, values)                                                              \
    EXPORT fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t n, values)    \
    {                                                                                               \
        (void)c, (void)vr, (void)v;                                                                 \
        return n == 0 ? fmi2OK : fmi2Error;                                                         \
    }
NO_VARIABLES(fmi2GetInteger, fmi2Integer v[])
NO_VARIABLES(fmi2SetInteger, const fmi2Integer v[])
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean v[])
NO_VARIABLES(fmi2SetBoolean, const fmi2Boolean v[])
NO_VARIABLES(fmi2GetString, fmi2String v[])
NO_VARIABLES(fmi2SetString, const fmi2String v[])

/* FMU states that cost next to nothing: a state is a malloc'd copy of the variables, set by copying it back */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    Instance *copy = malloc(sizeof(Instance));
    if (copy == NULL) return fmi2Error;
    *copy = *(const Instance *)c;
    *state = copy;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    if (state == NULL) return fmi2Error;
    *(Instance *)c = *(const Instance *)state;
    return fmi2OK;
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    if (state == NULL) return fmi2Error;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)c, (void)state;
    if (size == NULL) return fmi2Error;
    *size = STATE_BYTES;
    return fmi2OK;
}

/* the variables, then zeros up to STATE_BYTES */
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    (void)c;
    if (state == NULL || size != STATE_BYTES) return fmi2Error;
    memcpy(bytes, state, sizeof(Instance));
    memset(bytes + sizeof(Instance), 0, STATE_BYTES - sizeof(Instance));
    return fmi2OK;
}

/* bytes of any other size than STATE_BYTES are no state of this FMU: fmi2Error */
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                          fmi2FMUstate *state)
{
    (void)c;
    if (size != STATE_BYTES) return fmi2Error;
    Instance *copy = malloc(sizeof(Instance));
    if (copy == NULL) return fmi2Error;
    memcpy(copy, bytes, sizeof(Instance));
    *state = copy;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknowns[], size_t n_u,
                                               const fmi2ValueReference knowns[], size_t n_k,
                                               const fmi2Real dv_known[], fmi2Real dv_unknown[])
{
    (void)c, (void)unknowns, (void)n_u, (void)knowns, (void)n_k, (void)dv_known, (void)dv_unknown;
    return fmi2Error;
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                              const fmi2Integer order[], const fmi2Real value[])
{
    (void)c, (void)vr, (void)n, (void)order, (void)value;
    return fmi2Error;
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                               const fmi2Integer order[], fmi2Real value[])
{
    (void)c, (void)vr, (void)n, (void)order, (void)value;
    return fmi2Error;
}

/* the call this FMU exists for: a step that does nothing */
EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior_state)
{
    (void)c, (void)t, (void)h, (void)no_prior_state;
    return fmi2OK;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { return no_op(c); }

/* no asynchronous steps: there is no status to ask for */
#define NO_STATUS(function, type)                                                                   \
    EXPORT fmi2Status function(fmi2Component c, fmi2StatusKind kind, type *value)                   \
    {                                                                                               \
        (void)c, (void)kind, (void)value;                                                           \
        return fmi2Discard;                                                                         \
    }
NO_STATUS(fmi2GetStatus, fmi2Status)
NO_STATUS(fmi2GetRealStatus, fmi2Real)
NO_STATUS(fmi2GetIntegerStatus, fmi2Integer)
NO_STATUS(fmi2GetBooleanStatus, fmi2Boolean)
NO_STATUS(fmi2GetStringStatus, fmi2String)
