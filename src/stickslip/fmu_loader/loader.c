/* The FMU's linux64 binary: an FMI 2.0 co-simulation front for PythonFMU's binary.
 *
 * PythonFMU's binary (shipped beside this one as SBF_INNER_LIBRARY) leaves every
 * Py* symbol unresolved and so loads only inside a Python process. This library
 * needs nothing but libc. On the first fmi2Instantiate it
 *   1. finds a CPython: the process's own if it has one (never a second one), else
 *      the shared library named by $SBF_LIBPYTHON, else the one the FMU was built
 *      with (SBF_BUILD_LIBPYTHON), else its soname (SBF_LIBPYTHON_SONAME); it is
 *      loaded with RTLD_GLOBAL so that Python's extension modules find its symbols;
 *   2. starts that Python if nobody has, with the standard library of the library's
 *      own installation, through PyConfig, so that a broken installation (a wrong
 *      PYTHONHOME) is an error status and a logged message, not an exit of the host;
 *      the host's handlers of SIGINT, SIGPIPE and SIGXFSZ are kept;
 *   3. loads PythonFMU's binary and forwards every FMI call to it (failures of the
 *      model's calls as fmi2Error where the slave allows it: see FORWARDED).
 * Each host thread gets one Python thread state, kept for the thread's life:
 * PythonFMU's PyGILState_Ensure/Release around every call then only take and
 * give back the GIL instead of creating and destroying a thread state.
 * PythonFMU logs only when its debug logging is on, errors included; it is
 * therefore always instantiated with logging on, and this library filters:
 * warnings, discards, errors and fatals always reach the host's logger, other
 * messages only as the host asked (loggingOn, fmi2SetDebugLogging categories).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef SBF_INNER_LIBRARY
#error "define SBF_INNER_LIBRARY: the file name of PythonFMU's binary beside this library"
#endif
#ifndef SBF_BUILD_LIBPYTHON
#define SBF_BUILD_LIBPYTHON ""
#endif
#ifndef SBF_LIBPYTHON_SONAME
#define SBF_LIBPYTHON_SONAME ""
#endif
#define LIBPYTHON_VARIABLE "SBF_LIBPYTHON"

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
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#define EXPORT __attribute__((visibility("default")))

/* ---- the functions forwarded: X(name, failure, parameters, arguments after the component) ----
 * failure RECOVERABLE: PythonFMU reports an exception of the slave method it calls as fmi2Fatal; with
 * SBF_SLAVE_SURVIVES_RELEASE (a slave whose methods balance PythonFMU's release of it on an exception, as
 * SpringBlockFriction's do) the instance stays valid for fmi2Reset, fmi2SetFMUstate and fmi2FreeInstance,
 * which is what fmi2Error means, so fmi2Fatal is returned and logged as fmi2Error. KEPT: the status as is. */
#define FORWARDED(X)                                                                                               \
    X(fmi2SetupExperiment, RECOVERABLE, (fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real d, fmi2Boolean e, fmi2Real f), \
      (a, b, d, e, f))                                                                                             \
    X(fmi2EnterInitializationMode, RECOVERABLE, (fmi2Component c), ())                                             \
    X(fmi2ExitInitializationMode, RECOVERABLE, (fmi2Component c), ())                                              \
    X(fmi2Terminate, RECOVERABLE, (fmi2Component c), ())                                                           \
    X(fmi2Reset, KEPT, (fmi2Component c), ())                                                                      \
    X(fmi2GetReal, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2Real *x), (v, n, x))  \
    X(fmi2GetInteger, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2Integer *x), (v, n, x)) \
    X(fmi2GetBoolean, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2Boolean *x), (v, n, x)) \
    X(fmi2GetString, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, fmi2String *x), (v, n, x)) \
    X(fmi2SetReal, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Real *x), (v, n, x)) \
    X(fmi2SetInteger, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Integer *x), (v, n, x)) \
    X(fmi2SetBoolean, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Boolean *x), (v, n, x)) \
    X(fmi2SetString, RECOVERABLE, (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2String *x), (v, n, x)) \
    X(fmi2GetFMUstate, RECOVERABLE, (fmi2Component c, fmi2FMUstate *s), (s))                                       \
    X(fmi2SetFMUstate, RECOVERABLE, (fmi2Component c, fmi2FMUstate s), (s))                                        \
    X(fmi2FreeFMUstate, KEPT, (fmi2Component c, fmi2FMUstate *s), (s))                                             \
    X(fmi2SerializedFMUstateSize, KEPT, (fmi2Component c, fmi2FMUstate s, size_t *n), (s, n))                      \
    X(fmi2SerializeFMUstate, KEPT, (fmi2Component c, fmi2FMUstate s, fmi2Byte *b, size_t n), (s, b, n))            \
    X(fmi2DeSerializeFMUstate, KEPT, (fmi2Component c, const fmi2Byte *b, size_t n, fmi2FMUstate *s), (b, n, s))   \
    X(fmi2GetDirectionalDerivative, KEPT,                                                                          \
      (fmi2Component c, const fmi2ValueReference *u, size_t nu, const fmi2ValueReference *k, size_t nk,            \
       const fmi2Real *dk, fmi2Real *du),                                                                          \
      (u, nu, k, nk, dk, du))                                                                                      \
    X(fmi2SetRealInputDerivatives, KEPT,                                                                           \
      (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Integer *o, const fmi2Real *x),           \
      (v, n, o, x))                                                                                                \
    X(fmi2GetRealOutputDerivatives, KEPT,                                                                          \
      (fmi2Component c, const fmi2ValueReference *v, size_t n, const fmi2Integer *o, fmi2Real *x), (v, n, o, x))   \
    X(fmi2DoStep, RECOVERABLE, (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean k), (t, h, k))                \
    X(fmi2CancelStep, KEPT, (fmi2Component c), ())                                                                 \
    X(fmi2GetStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Status *x), (k, x))                       \
    X(fmi2GetRealStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Real *x), (k, x))                     \
    X(fmi2GetIntegerStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Integer *x), (k, x))               \
    X(fmi2GetBooleanStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2Boolean *x), (k, x))               \
    X(fmi2GetStringStatus, KEPT, (fmi2Component c, const fmi2StatusKind k, fmi2String *x), (k, x))

/* PythonFMU's entry points */
static struct {
#define POINTER(name, failure, params, args) fmi2Status(*name) params;
    FORWARDED(POINTER)
#undef POINTER
    fmi2Component (*fmi2Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                     fmi2Boolean, fmi2Boolean);
    void (*fmi2FreeInstance)(fmi2Component);
    fmi2Status (*fmi2SetDebugLogging)(fmi2Component, fmi2Boolean, size_t, const fmi2String *);
} inner;

/* ---- CPython: the few functions used, resolved at run time (stable C API since 3.8) ---- */
typedef struct { int type; const char *func; const char *err_msg; int exitcode; } PyStatus;
static struct {
    int (*Py_IsInitialized)(void);
    int (*PyGILState_Ensure)(void);
    void (*PyGILState_Release)(int);
    void *(*PyEval_SaveThread)(void);
    void (*PyConfig_InitPythonConfig)(void *);
    PyStatus (*PyConfig_SetBytesArgv)(void *, long, char *const *);
    PyStatus (*Py_InitializeFromConfig)(const void *);
    void (*PyConfig_Clear)(void *);
    int (*PyStatus_Exception)(PyStatus);
} py;
enum { PyGILState_LOCKED, PyGILState_UNLOCKED };
#define PYCONFIG_BYTES 16384 /* room for any CPython 3.8-3.13 PyConfig (about 0.5 kB) */

/* ---- one instance ---- */
typedef struct {
    fmi2Component inner;
    fmi2CallbackFunctions host;   /* the importer's callbacks */
    fmi2CallbackFunctions relay;  /* handed to PythonFMU: logs through relay_log */
    char *name;
    fmi2Boolean host_logging;
    size_t n_categories;
    char **categories;  /* none: every category */
    int fatal_is_error; /* during a RECOVERABLE call: PythonFMU's fmi2Fatal is reported as fmi2Error */
} Instance;

static pthread_mutex_t start_lock = PTHREAD_MUTEX_INITIALIZER;
static int started;           /* 0 not tried, 1 ready, -1 failed (start_error says why) */
static char start_error[2048];
static __thread int thread_has_state; /* this host thread owns a Python thread state */

static void host_log(const Instance *inst, fmi2Status status, const char *text)
{
    static const char *const categories[] = {"logStatusOK", "logStatusWarning", "logStatusDiscard",
                                             "logStatusError", "logStatusFatal", "logStatusPending"};
    if (inst->host.logger)
        inst->host.logger(inst->host.componentEnvironment, inst->name, status, categories[status], "%s", text);
    else
        fprintf(stderr, "[%s] %s: %s\n", categories[status], inst->name, text);
}

static int wanted(const Instance *inst, fmi2Status status, fmi2String category)
{
    if (status != fmi2OK && status != fmi2Pending) return 1; /* warning, discard, error, fatal: always */
    if (!inst->host_logging) return 0;
    if (inst->n_categories == 0) return 1;
    for (size_t i = 0; i < inst->n_categories; ++i)
        if (category && strcmp(category, inst->categories[i]) == 0) return 1;
    return 0;
}

/* PythonFMU's text of a slave exception, "Fatal py exception encountered: [call] PyObject_CallMethod\n<exception>",
 * as "[call] <exception>" in out (the exception is no fatal error once reported as fmi2Error); other text as is */
static const char *exception_text(const char *message, char *out, size_t size)
{
    static const char prefix[] = "Fatal py exception encountered: ";
    if (strncmp(message, prefix, sizeof prefix - 1) != 0) return message;
    const char *call = message + sizeof prefix - 1;
    const char *call_end = strstr(call, "] ");
    const char *exception = strchr(call, '\n');
    if (!call_end || !exception || call_end > exception) return call;
    snprintf(out, size, "%.*s %s", (int)(call_end + 1 - call), call, exception + 1);
    return out;
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
        message = exception_text(message, tidy, sizeof tidy);
    }
    if (inst->host.logger && wanted(inst, status, category))
        inst->host.logger(inst->host.componentEnvironment, inst->name, status, category, "%s", message);
}

static void set_host_logging(Instance *inst, fmi2Boolean on, size_t n, const fmi2String *categories)
{
    for (size_t i = 0; i < inst->n_categories; ++i) free(inst->categories[i]);
    free(inst->categories);
    inst->categories = NULL;
    inst->n_categories = 0;
    inst->host_logging = on;
    if (n == 0 || !categories) return;
    inst->categories = calloc(n, sizeof(char *));
    for (size_t i = 0; inst->categories && i < n; ++i)
        if (categories[i]) inst->categories[inst->n_categories++] = strdup(categories[i]);
}

/* ---- starting Python ---- */

static void fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsnprintf(start_error, sizeof start_error, format, args);
    va_end(args);
    started = -1;
}

static int resolve_python(void *lib)
{
#define RESOLVE(symbol) (*(void **)&py.symbol = dlsym(lib, #symbol)) != NULL
    return RESOLVE(Py_IsInitialized) && RESOLVE(PyGILState_Ensure) && RESOLVE(PyGILState_Release) &&
           RESOLVE(PyEval_SaveThread);
}

static int resolve_config_api(void *lib)
{
    return RESOLVE(PyConfig_InitPythonConfig) && RESOLVE(PyConfig_SetBytesArgv) && RESOLVE(Py_InitializeFromConfig) &&
           RESOLVE(PyConfig_Clear) && RESOLVE(PyStatus_Exception);
#undef RESOLVE
}

/* A CPython library: the process's own (RTLD_DEFAULT), or the first that loads (RTLD_GLOBAL). 0 after fail(). */
static int find_libpython(void **lib_out, const char **where)
{
    void *lib = NULL;
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
        *where = "the host process's own CPython";
        *lib_out = RTLD_DEFAULT;
        return 1;
    }
    const char *override = getenv(LIBPYTHON_VARIABLE);
    if (override && *override) {
        lib = dlopen(override, RTLD_NOW | RTLD_GLOBAL);
        if (!lib)
            fail("cannot load the CPython library named by %s=%s: %s. Set %s to the path of a CPython 3 shared "
                 "library (libpython3.X.so.1.0, CPython 3.8 or newer) or unset it.",
                 LIBPYTHON_VARIABLE, override, dlerror(), LIBPYTHON_VARIABLE);
        *where = override;
        *lib_out = lib;
        return lib != NULL;
    }
    const char *candidates[] = {SBF_BUILD_LIBPYTHON, SBF_LIBPYTHON_SONAME};
    char tried[1024] = "";
    for (size_t i = 0; i < sizeof candidates / sizeof *candidates; ++i) {
        if (!*candidates[i]) continue;
        lib = dlopen(candidates[i], RTLD_NOW | RTLD_GLOBAL);
        if (lib) {
            *where = candidates[i];
            *lib_out = lib;
            return 1;
        }
        size_t used = strlen(tried);
        snprintf(tried + used, sizeof tried - used, "%s%s (%s)", used ? ", " : "", candidates[i], dlerror());
    }
    fail("no CPython shared library found; tried %s. This FMU runs its model in Python: install CPython 3 with "
         "its shared library (built with --enable-shared, e.g. the libpython3 package; the FMU was built with %s) "
         "or set %s to the path of a libpython3.X.so.1.0 (CPython 3.8 or newer).",
         *tried ? tried : "nothing", *SBF_BUILD_LIBPYTHON ? SBF_BUILD_LIBPYTHON : SBF_LIBPYTHON_SONAME,
         LIBPYTHON_VARIABLE);
    return 0;
}

/* The program name Python derives its prefix from (unless PYTHONHOME is set): <prefix>/bin/pythonX.Y of the
 * library's installation if it exists, else a name in the library's folder; Python then looks for its
 * standard library upwards from there, so the library and the standard library it finds belong together
 * (the default, "python3" looked up in PATH, may find another installation's). */
static void program_name(char *name, size_t size)
{
    Dl_info library;
    if (!dladdr(*(void **)&py.Py_IsInitialized, &library) || !library.dli_fname) {
        snprintf(name, size, "python3");
        return;
    }
    char version[32] = "3";
    const char *base = strrchr(library.dli_fname, '/');
    base = base ? base + 1 : library.dli_fname;
    if (sscanf(base, "libpython%31[0-9.]", version) == 1 && version[strlen(version) - 1] == '.')
        version[strlen(version) - 1] = '\0';
    int dir_length = base - library.dli_fname; /* with its trailing slash */
    snprintf(name, size, "%.*s../bin/python%s", dir_length, library.dli_fname, version);
    char resolved[4096];
    if (!realpath(name, resolved) || access(resolved, X_OK) != 0)
        snprintf(name, size, "%.*spython%s", dir_length, library.dli_fname, version);
}

/* Py_InitializeFromConfig, keeping the host's signal handlers; leaves the GIL released. */
static void initialize_python(const char *where)
{
    char name[4096];
    char *argv[] = {name, NULL};
    program_name(name, sizeof name);
    static const int kept[] = {SIGINT, SIGPIPE, SIGXFSZ};
    struct sigaction before[sizeof kept / sizeof *kept];
    _Alignas(16) static unsigned char config[PYCONFIG_BYTES];
    for (size_t i = 0; i < sizeof kept / sizeof *kept; ++i) sigaction(kept[i], NULL, &before[i]);
    py.PyConfig_InitPythonConfig(config);
    PyStatus status = py.PyConfig_SetBytesArgv(config, 1, argv);
    if (!py.PyStatus_Exception(status)) status = py.Py_InitializeFromConfig(config);
    py.PyConfig_Clear(config);
    for (size_t i = 0; i < sizeof kept / sizeof *kept; ++i) sigaction(kept[i], &before[i], NULL);
    if (py.PyStatus_Exception(status)) {
        const char *home = getenv("PYTHONHOME");
        fail("Python (%s) failed to start: %s%s%s. Check PYTHONHOME (%s) and PYTHONPATH: unset them, or point "
             "them at this Python's installation, or set %s to another CPython 3 shared library.",
             where, status.func ? status.func : "", status.func ? ": " : "",
             status.err_msg ? status.err_msg : "unknown error", home ? home : "not set", LIBPYTHON_VARIABLE);
        return;
    }
    py.PyEval_SaveThread(); /* this thread keeps its (main) thread state */
    thread_has_state = 1;
}

static void load_inner(void)
{
    Dl_info self;
    char path[4096];
    if (!dladdr((void *)&load_inner, &self) || !self.dli_fname) {
        fail("cannot locate the FMU's binaries folder");
        return;
    }
    const char *slash = strrchr(self.dli_fname, '/');
    int dir_length = slash ? (int)(slash - self.dli_fname + 1) : 0;
    snprintf(path, sizeof path, "%.*s%s", dir_length, self.dli_fname, SBF_INNER_LIBRARY);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fail("cannot load PythonFMU's binary %s: %s", path, dlerror());
        return;
    }
#define LOAD(name, failure, params, args) && (*(void **)&inner.name = dlsym(lib, #name)) != NULL
    if (!(1 FORWARDED(LOAD) LOAD(fmi2Instantiate, , , ) LOAD(fmi2FreeInstance, , , ) LOAD(fmi2SetDebugLogging, , , )))
        fail("%s lacks an FMI 2 function: %s", path, dlerror());
#undef LOAD
}

/* Python and PythonFMU ready (once per process); 0 with start_error set if not. */
static int start(void)
{
    pthread_mutex_lock(&start_lock);
    if (started == 0) {
        const char *where = "";
        void *lib = NULL;
        int found = find_libpython(&lib, &where);
        if (found && !resolve_python(lib))
            fail("%s is not a usable CPython library: %s", where, dlerror());
        else if (found && !py.Py_IsInitialized()) {
            if (!resolve_config_api(lib))
                fail("%s lacks the PyConfig API: CPython 3.8 or newer is needed (set %s)", where,
                     LIBPYTHON_VARIABLE);
            else
                initialize_python(where);
        }
        if (started == 0) load_inner();
        if (started == 0) started = 1;
    }
    pthread_mutex_unlock(&start_lock);
    return started == 1;
}

/* Give this host thread a Python thread state for its life (PythonFMU's per-call Ensure then finds it). */
static inline void keep_thread_state(void)
{
    if (thread_has_state) return;
    if (py.PyGILState_Ensure() == PyGILState_UNLOCKED)
        py.PyEval_SaveThread(); /* release the GIL, keep the state */
    else
        py.PyGILState_Release(PyGILState_LOCKED); /* the thread already held the GIL: it has a state */
    thread_has_state = 1;
}

/* ---- exported FMI 2 functions ---- */

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

static void free_instance(Instance *inst)
{
    set_host_logging(inst, 0, 0, NULL);
    free(inst->name);
    free(inst);
}

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean loggingOn)
{
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    inst->name = strdup(name ? name : "");
    if (functions) inst->host = *functions;
    inst->relay = inst->host;
    inst->relay.logger = relay_log;
    inst->relay.componentEnvironment = inst;
    inst->host_logging = loggingOn;
    if (!start()) {
        host_log(inst, fmi2Fatal, start_error);
        free_instance(inst);
        return NULL;
    }
    keep_thread_state();
    inst->inner = inner.fmi2Instantiate(name, type, guid, resources, &inst->relay, visible, 1);
    if (!inst->inner) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

EXPORT void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = c;
    if (!inst) return;
    keep_thread_state();
    inner.fmi2FreeInstance(inst->inner);
    free_instance(inst);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String *categories)
{
    if (!c) return fmi2Error;
    set_host_logging(c, loggingOn, n, categories);
    return fmi2OK;
}

#ifdef SBF_SLAVE_SURVIVES_RELEASE
#define RECOVERABLE 1
#else
#define RECOVERABLE 0
#endif
#define KEPT 0
#define FORWARD(name, failure, params, args)                                 \
    EXPORT fmi2Status name params                                            \
    {                                                                        \
        Instance *inst = c;                                                  \
        if (!inst) return fmi2Error;                                         \
        keep_thread_state();                                                 \
        inst->fatal_is_error = failure;                                      \
        fmi2Status status = inner.name(inst->inner FORWARD_ARGS args);       \
        inst->fatal_is_error = 0;                                            \
        return failure && status == fmi2Fatal ? fmi2Error : status;          \
    }
#define FORWARD_ARGS(...) __VA_OPT__(, ) __VA_ARGS__
FORWARDED(FORWARD)
#undef FORWARD
