/* What both FMI fronts of the loader share: finding and starting CPython, loading the library they
 * forward to, Python thread states of host threads, the checks of an instantiation's arguments (resource
 * location, token, name), the co-simulation states that allow a step, the filter and the names of the host's
 * log categories, and the refusal of bad serialized FMU states.
 * See runtime.c; the fronts are fmi2_front.c (PythonFMU) and fmi3_front.c (pythonfmu3). */
#ifndef SBF_RUNTIME_H
#define SBF_RUNTIME_H
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "fast_path.h"
#include "platform.h"

/* Called once, under the start lock, with the inner library (loaded from beside this one) and its path:
 * resolves the front's entry points; returns 0 after sbf_fail() if one is missing. */
typedef int (*sbf_resolve_inner)(void *library, const char *path);

/* Python and the inner library ready (once per process); 0 with sbf_start_error() saying why if not. */
int sbf_start(sbf_resolve_inner resolve);
const char *sbf_start_error(void);
void sbf_fail(const char *format, ...) __attribute__((format(gnu_printf, 1, 2)));

/* Give this host thread a Python thread state for its life (the inner library's per-call
 * PyGILState_Ensure/Release then only take and give back the GIL); a state made here is deleted when the
 * thread ends. */
void sbf_keep_thread_state(void);

/* Whether `function` (fmi2Instantiate, fmi3Instantiate...) can make an instance named `name` with the token
 * `token` (the FMI version's `token_name`: "GUID", "instantiation token") and the resource location `location`:
 * 1 with the resources folder (a plain absolute path) in `folder` and the path to it that the inner library is to be
 * given in `path` (each `size` bytes; the same unless the library would rewrite the folder's path, see
 * inner_library_path in runtime.c); else 0 with a message naming the function, the value and the cause in `why`.
 * The location is an RFC 8089 file URI (file:///abs, file:/abs, file://localhost/abs; every percent-escape decoded
 * to its byte) or a plain absolute path (FMI 3's form, taken as is); it must name a folder with the FMU's slave
 * module. */
int sbf_check_instance(const char *function, const char *name, const char *token_name, const char *token,
                       const char *location, char *folder, char *path, size_t size, char *why, size_t why_size);

/* Around every call into the model (the inner library, or the slave through the fast path): a SIGINT that arrives
 * meanwhile while this is the process's main thread reaches the host's handler when sbf_call_end is called, not
 * inside the model's Python code (see runtime.c). Calls nest. */
void sbf_call_begin(void);
void sbf_call_end(void);
/* Around the inner library's instantiation, as sbf_call_begin/sbf_call_end: the first one of this library, which
 * imports the FMU's Python modules, runs under the process-wide start lock, so that two FMUs never import at once on
 * two threads (CPython then may hand one of them a module the other is still importing: "partially initialized
 * module"). */
void sbf_instantiate_begin(void);
void sbf_instantiate_end(void);
/* sbf_fast_step (fast_path.h) as such a call */
int sbf_model_fast_step(sbf_fast_path *fast, double t, double h, char *why, size_t why_size);

/* The states of FMI's state machines that the fronts tell apart (co-simulation: FMI 2.0 section 4.2.4, FMI 3.0
 * section 4.2, SBF_EVENT there FMI 3's Event Mode of an instance made with eventModeUsed; model exchange: FMI 2.0
 * section 3.2.3, FMI 3.0 section 3.2, from Initialization Mode to Event Mode and Continuous-Time Mode). */
typedef enum {
    SBF_INSTANTIATED, SBF_INITIALIZING, SBF_STEPPING, SBF_TERMINATED, SBF_EVENT, SBF_CONTINUOUS
} sbf_mode;
/* The set of the states `mode`, ... in sbf_call_refused's `allowed`: SBF_IN(SBF_EVENT) | SBF_IN(SBF_CONTINUOUS) */
#define SBF_IN(mode) (1u << (mode))
/* 0 if `function` is allowed in `mode`, one of the states in `allowed`, else 1 with the message saying why not in
 * `why`: the call, the state the instance is in and those where the call is allowed. */
int sbf_call_refused(sbf_mode mode, unsigned allowed, const char *function, char *why, size_t why_size);
/* 0 if a communication step (`function` at `t` s) is allowed in `mode` (only in SBF_STEPPING of a co-simulation
 * instance; `exchange`: a model-exchange instance, which takes none), else 1 with the message saying why not in
 * `why`. */
int sbf_step_refused(sbf_mode mode, int exchange, const char *function, double t, char *why, size_t why_size);

/* 0 if the experiment's times `function` (fmi2SetupExperiment, fmi3EnterInitializationMode) was given are finite
 * (the start time; the stop time and the tolerance where defined), else 1 with the message naming the first that
 * is not in `why`. */
int sbf_experiment_refused(const char *function, int tolerance_defined, double tolerance, double start,
                           int stop_defined, double stop, char *why, size_t why_size);

/* The log category of a message: `category` unless it is NULL or empty, else its status's ("logStatusError"). */
const char *sbf_category(int status, const char *category);

/* The inner library's text of a slave exception, "Fatal py exception encountered: [call] PyObject_CallMethod\n
 * <exception>", as "[call] <exception>" in out; other text as is. */
const char *sbf_exception_text(const char *message, char *out, size_t size);

/* Which messages the host asked for. Status numbers as in FMI 2 and 3: 0 OK, 1 warning, 2 discard, 3 error,
 * 4 fatal (5 pending in FMI 2). */
typedef struct {
    int on;             /* loggingOn / fmi*SetDebugLogging */
    size_t n_categories;
    char **categories;  /* none: every category */
} sbf_log_filter;

void sbf_set_log_filter(sbf_log_filter *filter, int on, size_t n, const char *const *categories);
/* 1 if each of categories[0..n) is a log category of the model description; else 0, with the message for the
 * host in `why` (naming `function` and the category). */
int sbf_known_categories(const char *function, size_t n, const char *const *categories, char *why, size_t size);
/* The <LogCategories> of the model description: their count, the names in *names. */
size_t sbf_listed_categories(const char *const **names);
/* Warnings, discards, errors and fatals always; other messages only as the host asked. */
int sbf_log_wanted(const sbf_log_filter *filter, int status, const char *category);

/* ---- for the fronts: an exported FMI function forwarded to the inner library ----
 * The front defines `Instance` (with the fields `inner`, the inner library's instance, and `fatal_is_error`),
 * the struct `inner` of the inner library's entry points, and its list of forwarded functions as
 * X(name, failure, parameters, arguments after the instance), the instance parameter named `c`.
 * failure RECOVERABLE: the inner library reports an exception of the slave method it calls as fatal; with
 * SBF_SLAVE_SURVIVES_RELEASE (a slave whose methods balance the library's release of it on an exception, as
 * SpringBlockFriction's do) the instance stays valid for reset, state restore and free, which is what an error
 * status means, so the fatal status is returned and logged as an error. KEPT: the status as is. */
#ifdef SBF_SLAVE_SURVIVES_RELEASE
#define RECOVERABLE 1
#else
#define RECOVERABLE 0
#endif
#define KEPT 0
#define SBF_FORWARD_ARGS(...) __VA_OPT__(, ) __VA_ARGS__
/* The function `function` (with linkage `Linkage`) that forwards to the inner library's `name`, after the fast
 * path's bookkeeping (sbf_fast_forward; the front's Instance has the field `fast`): `changes` is 0 for a call that
 * only reads values, 1 for any other. */
#define SBF_FORWARD_WITH(Linkage, function, Status, error, fatal, name, failure, changes, params, args) \
    Linkage Status function params                                                                   \
    {                                                                                                \
        Instance *inst = c;                                                                          \
        if (!inst) return error;                                                                     \
        sbf_keep_thread_state();                                                                     \
        sbf_call_begin();                                                                            \
        sbf_fast_forward(&inst->fast, changes);                                                      \
        inst->fatal_is_error = failure;                                                              \
        Status status = inner.name(inst->inner SBF_FORWARD_ARGS args);                               \
        inst->fatal_is_error = 0;                                                                    \
        sbf_call_end();                                                                              \
        return failure && status == fatal ? error : status;                                          \
    }
/* The same, for a call that may change the instance */
#define SBF_FORWARD_AS(Linkage, function, Status, error, fatal, name, failure, params, args) \
    SBF_FORWARD_WITH(Linkage, function, Status, error, fatal, name, failure, 1, params, args)
/* The exported fmi2FreeFMUstate / fmi3FreeFMUState `name`, forwarded to the inner library's, and as the standard
 * asks: a null pointer is ignored and the freed state comes back as NULL (PythonFMU and pythonfmu3 dereference
 * the one and leave the other). Status 0 is OK and 1 warning in both. */
#define SBF_FREE_STATE(Status, error, fatal, name, State)                                                      \
    SBF_FORWARD_AS(static, forward_free_state, Status, error, fatal, name, KEPT, (void *c, State *s), (s))    \
    SBF_EXPORT Status name(void *c, State *s)                                     \
    {                                                                                                          \
        if (!s || !*s) return c ? 0 : error;                                                                   \
        if (c && sbf_state_free(&((Instance *)c)->fast, s) == 0) return 0;                                     \
        Status status = forward_free_state(c, s);                                                              \
        if (status <= 1) *s = NULL;                                                                            \
        return status;                                                                                         \
    }
/* The exported getter `name` (its component parameter named `c`): answered by the fast path's reader `read` (the
 * instance's `fast`, then the getter's arguments after the component) where that holds every value asked for,
 * else forwarded by forward_<name> as a call that only reads. */
#define SBF_READER(Status, ok, error, fatal, name, failure, params, args, read)                                  \
    SBF_FORWARD_WITH(static, forward_##name, Status, error, fatal, name, failure, 0, params, args)              \
    SBF_EXPORT Status name params                                                  \
    {                                                                                                           \
        sbf_call_begin();                                                                                       \
        int answered = c && read(&((Instance *)c)->fast SBF_FORWARD_ARGS args);                                 \
        sbf_call_end();                                                                                         \
        if (answered) return ok;                                                                                \
        return forward_##name(c SBF_FORWARD_ARGS args);                                                         \
    }
/* The exported FMI function `name`, forwarded as is. */
#define SBF_FORWARD(Status, error, fatal, name, failure, params, args) \
    SBF_FORWARD_AS(SBF_EXPORT, name, Status, error, fatal, name, failure, params, args)

/* The exported FMU-state function `name` (its FMU state parameter named `s`), forwarded by `forward` (an
 * SBF_FORWARD_AS function) unless the state is NULL (none was got into it, or it was freed): that is refused with
 * `error` and a message naming `name` (PythonFMU crashed the host, pythonfmu3 failed fatally). */
#define SBF_STATE_USED(Status, error, name, forward, params, args, answer)                                         \
    SBF_EXPORT Status name params                                                    \
    {                                                                                                             \
        if (c && !s) {                                                                                            \
            host_log(c, error, #name ": the FMU state is NULL (no state was got into it, or it was freed)");     \
            return error;                                                                                         \
        }                                                                                                         \
        SBF_STATE_FAST(error, answer, args)                                                                       \
        return forward(c SBF_FORWARD_ARGS args);                                                                  \
    }
/* The exported fmi2GetFMUstate / fmi3GetFMUState `name`: the slave's state with the inputs the loader kept
 * (sbf_state_get), else forwarded by `forward`. */
#define SBF_STATE_GOT(Status, error, name, forward, params, args)                                                 \
    SBF_EXPORT Status name params                                                    \
    {                                                                                                             \
        SBF_STATE_FAST(error, sbf_state_get, args)                                                                \
        return forward(c SBF_FORWARD_ARGS args);                                                                  \
    }
/* In an FMU-state function: return what the bound slave answers (`answer`, a sbf_state_* function of fast_path.h,
 * with the call's arguments `args` after the instance), a refusal logged as `error`; go on if it does not answer. */
#define SBF_STATE_FAST(error, answer, args)                                                                         \
    if (c) {                                                                                                      \
        char why_[2048];                                                                                          \
        sbf_keep_thread_state();                                                                                  \
        sbf_call_begin();                                                                                         \
        int outcome_ = answer(&((Instance *)c)->fast SBF_FORWARD_ARGS args, why_, sizeof why_);                  \
        sbf_call_end();                                                                                           \
        if (outcome_ == 1) host_log(c, error, why_);                                                              \
        if (outcome_ >= 0) return outcome_ ? error : 0;                                                           \
    }

/* ---- for the fronts: the exported deserialization of FMU states ----
 * The slaves answer bytes that are no FMU state of theirs with a state that serializes as SBF_REFUSED_STATE and
 * the reason (fmu_src/loader_binding.py, state_from_bytes): an exception there would make the inner library
 * release the slave unbalanced, and the host crashed at its next call. The exported function `name` forwards to
 * the inner library (by `forward`, an SBF_FORWARD_AS function) and serializes the state it got (through the inner
 * library's `size_of` and `serialize`); a refused one is freed (`free_state`) and refused with `error` and the
 * reason, the instance unharmed. */
#define SBF_REFUSED_STATE "refused FMU state: "
#define SBF_DESERIALIZE(Status, error, warning, Byte, name, forward, size_of, serialize, free_state)              \
    SBF_EXPORT Status name(void *c, const Byte *bytes, size_t size, void **state)    \
    {                                                                                                             \
        SBF_STATE_FAST(error, sbf_state_deserialize, (bytes, size, state))                                        \
        sbf_call_begin();                                                                                         \
        Status status = forward(c, bytes, size, state);                                                           \
        Instance *inst = c;                                                                                       \
        size_t n = 0;                                                                                             \
        char *text = NULL;                                                                                        \
        if (status <= warning && inner.size_of(inst->inner, *state, &n) <= warning && (text = calloc(n + 1, 1)) && \
            inner.serialize(inst->inner, *state, (void *)text, n) <= warning &&                                   \
            strncmp(text, SBF_REFUSED_STATE, sizeof SBF_REFUSED_STATE - 1) == 0) {                                \
            host_log(inst, error, text + sizeof SBF_REFUSED_STATE - 1);                                           \
            inner.free_state(inst->inner, state);                                                                 \
            *state = NULL;                                                                                        \
            status = error;                                                                                       \
        }                                                                                                         \
        free(text);                                                                                               \
        sbf_call_end();                                                                                           \
        return status;                                                                                            \
    }

#endif
