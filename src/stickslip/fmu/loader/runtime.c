/* The loader's shared part (runtime.h): CPython found and started, the inner library loaded.
 *
 * On the first instantiation a front calls sbf_start, which
 *   1. finds a CPython: the process's own if it has one (never a second one), else the shared library
 *      named by $SBF_LIBPYTHON, else the one the FMU carries (SBF_BUNDLED_LIBPYTHON, a path below its "python/"
 *      folder, unpacked where it is needed: carried.c; where it cannot be, the start fails saying why; the libraries
 *      its extension modules need are loaded first from it where the system has none by their names), else, in an
 *      FMU that carries none, the one the FMU was built with
 *      (SBF_BUILD_LIBPYTHON), else its soname (SBF_LIBPYTHON_SONAME); it is loaded with RTLD_GLOBAL so that
 *      Python's extension modules find its symbols; one older than SBF_PYTHON_FLOOR_MINOR is refused before
 *      anything is imported (python_new_enough);
 *   2. starts that Python if nobody has, with the standard library of the library's own installation,
 *      through PyConfig, so that a broken installation is an error status and a logged message, not an exit of
 *      the host; it reads no environment variable (initialize_python); the host's handlers of SIGINT, SIGPIPE and
 *      SIGXFSZ are kept; then Python must import ctypes (imports_ctypes);
 *   3. loads the inner library (PythonFMU's or pythonfmu3's binary, SBF_INNER_LIBRARY beside this one; where it
 *      does not load, again after the C++ runtime the FMU carries, SBF_BUNDLED_INNER_NEEDS, or the carried build
 *      of it with that runtime linked in, SBF_BUNDLED_INNER, so that a host with a C++ runtime of its own keeps
 *      it; a loader with no SBF_INNER_LIBRARY, "", loads SBF_BUNDLED_INNER only, unpacking the carried CPython for
 *      it even where the host process has a Python of its own) and lets the front resolve its entry points.
 * Steps 1 and 2 run under a process-wide lock that every copy of the loader in the process shares (see
 * process_start_lock), and sbf_start first pins this library in memory (see pin_library).
 * Each host thread gets one Python thread state, kept for the thread's life (sbf_keep_thread_state).
 * The resource location a host passes is decoded and checked here for both fronts (sbf_check_instance), and the
 * inner library is handed a path to that folder that it does not rewrite (inner_library_path).
 * A Ctrl-C (SIGINT) that arrives while the process's main thread is inside a call into the model reaches the host's
 * handler when that call returns (sbf_call_begin).
 * What depends on the operating system is in platform.h (platform_posix.c, platform_windows.c).
 * At process exit the inner library's Python start-up object is destroyed once (see "the inner library's exit
 * fault").
 */
#include "runtime.h"

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "carried.h"
#include "platform.h"

/* the file name of the inner library beside this one; "": none there, SBF_BUNDLED_INNER only */
#ifndef SBF_INNER_LIBRARY
#error "define SBF_INNER_LIBRARY: the file name of the inner FMU binary beside this library"
#endif
#ifndef SBF_TOKEN
#error "define SBF_TOKEN: the FMU's GUID (FMI 2) or instantiation token (FMI 3)"
#endif
#ifndef SBF_BUILD_LIBPYTHON
#define SBF_BUILD_LIBPYTHON ""
#endif
#ifndef SBF_LIBPYTHON_SONAME
#define SBF_LIBPYTHON_SONAME ""
#endif
#ifndef SBF_BUNDLED_LIBPYTHON
#define SBF_BUNDLED_LIBPYTHON ""
#endif
/* Libraries the FMU carries beside the bundled CPython, as comma-separated string literals (paths relative to this
 * library's folder, each ending in the file name the system knows it by, in the order to load them): those its
 * extension modules need, and those the inner library needs (its C++ runtime) */
#ifndef SBF_BUNDLED_PYTHON_NEEDS
#define SBF_BUNDLED_PYTHON_NEEDS
#endif
#ifndef SBF_BUNDLED_INNER_NEEDS
#define SBF_BUNDLED_INNER_NEEDS
#endif
static const char *const bundled_python_needs[] = {SBF_BUNDLED_PYTHON_NEEDS NULL};
static const char *const bundled_inner_needs[] = {SBF_BUNDLED_INNER_NEEDS NULL};
#define LIBPYTHON_VARIABLE "SBF_LIBPYTHON"
/* The oldest CPython the FMU's Python code runs in (FMI 2: the runtime's typing.Final, 3.8; FMI 3: pythonfmu3, 3.9) */
#ifndef SBF_PYTHON_FLOOR_MINOR
#error "define SBF_PYTHON_FLOOR_MINOR: the oldest CPython 3 minor version the FMU's Python code runs in"
#endif

/* ---- CPython: the few functions used, resolved at run time (stable C API since 3.8) ---- */
typedef struct { int type; const char *func; const char *err_msg; int exitcode; } PyStatus;
static struct {
    int (*Py_IsInitialized)(void);
    int (*PyGILState_Ensure)(void);
    void (*PyGILState_Release)(int);
    void *(*PyGILState_GetThisThreadState)(void);
    void *(*PyEval_SaveThread)(void);
    void (*PyEval_RestoreThread)(void *);
    void (*PyThreadState_Clear)(void *);
    void (*PyThreadState_DeleteCurrent)(void);
    int (*Py_IsFinalizing)(void); /* _Py_IsFinalizing before CPython 3.13; NULL before 3.7 */
    int (*PyOS_InterruptOccurred)(void); /* takes back a SIGINT Python has noted and not handled yet */
    void (*PyPreConfig_InitPythonConfig)(void *);
    PyStatus (*Py_PreInitialize)(const void *);
    void (*PyConfig_InitPythonConfig)(void *);
    PyStatus (*PyConfig_SetBytesArgv)(void *, long, char *const *);
    PyStatus (*Py_InitializeFromConfig)(const void *);
    void (*PyConfig_Clear)(void *);
    int (*PyStatus_Exception)(PyStatus);
    void *(*PyImport_ImportModule)(const char *);
    void (*Py_DecRef)(void *);
    void (*PyErr_Fetch)(void **, void **, void **);
    void *(*PyObject_Str)(void *);
    const char *(*PyUnicode_AsUTF8)(void *);
} py;
/* The leading fields of CPython's PyPreConfig and PyConfig, the same from 3.8 to 3.13 */
typedef struct { int config_init, parse_argv, isolated, use_environment; } PreConfigHead;
typedef struct { int config_init, isolated, use_environment; } ConfigHead;
enum { PyGILState_LOCKED, PyGILState_UNLOCKED };
#define PYCONFIG_BYTES 16384 /* room for any CPython 3.8-3.13 PyConfig (about 0.5 kB) */

static int started;           /* 0 not tried, 1 ready, -1 failed (start_error says why) */
static char start_error[2048];
static SBF_THREAD_LOCAL int thread_has_state; /* this host thread owns a Python thread state */

const char *sbf_start_error(void) { return start_error; }

/* ---- starting Python ---- */

void sbf_fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsnprintf(start_error, sizeof start_error, format, args);
    va_end(args);
    started = -1;
}

static int resolve_python(void *lib)
{
#define RESOLVE(symbol) (*(void **)&py.symbol = sbf_symbol(lib, #symbol)) != NULL
    *(void **)&py.Py_IsFinalizing = sbf_symbol(lib, "Py_IsFinalizing");
    if (!py.Py_IsFinalizing) *(void **)&py.Py_IsFinalizing = sbf_symbol(lib, "_Py_IsFinalizing");
    *(void **)&py.PyOS_InterruptOccurred = sbf_symbol(lib, "PyOS_InterruptOccurred");
    return RESOLVE(Py_IsInitialized) && RESOLVE(PyImport_ImportModule) && RESOLVE(Py_DecRef) && RESOLVE(PyErr_Fetch) &&
           RESOLVE(PyObject_Str) && RESOLVE(PyUnicode_AsUTF8) && RESOLVE(PyGILState_Ensure) &&
           RESOLVE(PyGILState_Release) &&
           RESOLVE(PyGILState_GetThisThreadState) && RESOLVE(PyEval_SaveThread) && RESOLVE(PyEval_RestoreThread) &&
           RESOLVE(PyThreadState_Clear) && RESOLVE(PyThreadState_DeleteCurrent);
}

static int resolve_config_api(void *lib)
{
    return RESOLVE(PyPreConfig_InitPythonConfig) && RESOLVE(Py_PreInitialize) && RESOLVE(PyConfig_InitPythonConfig) &&
           RESOLVE(PyConfig_SetBytesArgv) && RESOLVE(Py_InitializeFromConfig) &&
           RESOLVE(PyConfig_Clear) && RESOLVE(PyStatus_Exception);
#undef RESOLVE
}

/* The path of the file `name` beside this library into `path`; 0 after sbf_fail() if this library cannot be found. */
static int beside_this_library(const char *name, char *path, size_t size)
{
    char self[4096];
    if (!sbf_loader_path(self, sizeof self)) {
        sbf_fail("cannot locate the FMU's binaries folder");
        return 0;
    }
    const char *slash = strrchr(self, '/'), *backslash = strrchr(self, '\\');
    if (backslash > slash) slash = backslash;
    int dir_length = slash ? (int)(slash - self + 1) : 0;
    snprintf(path, size, "%.*s%s", dir_length, self, name);
    return 1;
}

/* Load the libraries `needs` (see SBF_BUNDLED_PYTHON_NEEDS) from the FMU, with their symbols global; where
 * `system_first`, only those the system does not find by their file names, so that the system's are used where it
 * has them. A library that does not load is left out: what needs it then fails, saying so. */
static void load_bundled(const char *const *needs, int system_first)
{
    char path[4096], why[4096];
    for (; *needs; ++needs) {
        const char *slash = strrchr(*needs, '/');
        if (system_first && sbf_open_library(slash ? slash + 1 : *needs, 0)) continue;
        if (sbf_carried_path(*needs, path, sizeof path, why, sizeof why)) sbf_open_library(path, 1);
    }
}

#define HOST_PYTHON "the host process's own CPython"

/* A CPython library: the process's own (RTLD_DEFAULT), or the first that loads (RTLD_GLOBAL). 0 after sbf_fail(). */
static int find_libpython(void **lib_out, const char **where)
{
    void *lib = NULL;
    if (sbf_process_python(lib_out)) {
        *where = HOST_PYTHON;
        return 1;
    }
    const char *override = getenv(LIBPYTHON_VARIABLE);
    if (override && *override) {
        lib = sbf_open_library(override, 1);
        if (!lib)
            sbf_fail("cannot load the CPython library named by %s=%s: %s. Set %s to the path of a CPython 3 shared "
                 "library (libpython3.X.so.1.0, CPython 3.8 or newer) or unset it.",
                 LIBPYTHON_VARIABLE, override, sbf_library_error(), LIBPYTHON_VARIABLE);
        *where = override;
        *lib_out = lib;
        return lib != NULL;
    }
    static char bundled[4096];
    char why[4096];
    if (sbf_carries_python() && !sbf_carried_path(SBF_BUNDLED_LIBPYTHON, bundled, sizeof bundled, why, sizeof why)) {
        sbf_fail("%s", why);
        return 0;
    }
    const char *candidates[] = {bundled, SBF_BUILD_LIBPYTHON, SBF_LIBPYTHON_SONAME};
    char tried[1024] = "";
    for (size_t i = 0; i < sizeof candidates / sizeof *candidates; ++i) {
        if (!*candidates[i]) continue;
        if (candidates[i] == bundled) load_bundled(bundled_python_needs, SBF_SYSTEM_LIBRARIES_FIRST);
        lib = sbf_open_library(candidates[i], 1);
        if (lib) {
            *where = candidates[i];
            *lib_out = lib;
            return 1;
        }
        size_t used = strlen(tried);
        snprintf(tried + used, sizeof tried - used, "%s%s (%s)", used ? ", " : "", candidates[i], sbf_library_error());
    }
    sbf_fail("no CPython shared library found; tried %s. This FMU runs its model in Python: install CPython 3 with "
         "its shared library (built with --enable-shared, e.g. the libpython3 package; the FMU was built with %s) "
         "or set %s to the path of a libpython3.X.so.1.0 (CPython 3.8 or newer).",
         *tried ? tried : "nothing", *SBF_BUILD_LIBPYTHON ? SBF_BUILD_LIBPYTHON : SBF_LIBPYTHON_SONAME,
         LIBPYTHON_VARIABLE);
    return 0;
}

/* Whether the CPython library `lib` (found as `where`) is as new as the FMU's Python code needs, read from its
 * Py_GetVersion before anything is imported (an older one crashed the host in pythonfmu3's import); else 0 after
 * sbf_fail() naming the version found, the one needed and what to do. */
static int python_new_enough(void *lib, const char *where)
{
    const char *(*version)(void);
    int major = 0, minor = 0;
    *(void **)&version = sbf_symbol(lib, "Py_GetVersion");
    if (!version || sscanf(version(), "%d.%d", &major, &minor) != 2) {
        sbf_fail("%s is not a CPython library (it has no Py_GetVersion)", where);
        return 0;
    }
    if (major > 3 || (major == 3 && minor >= SBF_PYTHON_FLOOR_MINOR)) return 1;
    const char *override = getenv(LIBPYTHON_VARIABLE);
    sbf_fail("%s is version %.*s; this FMU needs CPython 3.%d or newer: %s", where, (int)strcspn(version(), " "),
             version(), SBF_PYTHON_FLOOR_MINOR,
             strcmp(where, HOST_PYTHON) == 0 ? "run it in a host process with a newer CPython, or in one without "
                                               "Python (the FMU then starts its own)"
             : override && *override ? "point " LIBPYTHON_VARIABLE " at a newer CPython's shared library, or unset it"
                                     : "set " LIBPYTHON_VARIABLE " to a newer CPython's shared library");
    return 0;
}

/* Py_InitializeFromConfig, keeping the host's signal handlers; leaves the GIL released. Python reads none of the
 * process's environment variables (use_environment = 0 in its pre-configuration and configuration, as -E does):
 * a PYTHONHOME, PYTHONPATH, PYTHONHASHSEED, PYTHONMALLOC... set for another Python neither stops nor changes it.
 * SBF_PYTHON_VERBOSE set to anything but empty passes Python's -v: it reports on stderr where it imports each
 * module from (PYTHONVERBOSE is ignored with the rest). */
static void initialize_python(void *lib, const char *where)
{
    char name[4096], verbose[] = "-v";
    const char *wanted = getenv("SBF_PYTHON_VERBOSE");
    char *argv[] = {name, wanted && *wanted ? verbose : NULL, NULL};
    sbf_python_program_name(*(void **)&py.Py_IsInitialized, name, sizeof name);
    _Alignas(16) static unsigned char preconfig[PYCONFIG_BYTES], config[PYCONFIG_BYTES];
    sbf_save_host_signals(lib);
    py.PyPreConfig_InitPythonConfig(preconfig);
    ((PreConfigHead *)preconfig)->use_environment = 0;
    PyStatus status = py.Py_PreInitialize(preconfig);
    if (!py.PyStatus_Exception(status)) {
        py.PyConfig_InitPythonConfig(config);
        ((ConfigHead *)config)->use_environment = 0;
        status = py.PyConfig_SetBytesArgv(config, argv[1] ? 2 : 1, argv);
        if (!py.PyStatus_Exception(status)) status = py.Py_InitializeFromConfig(config);
        py.PyConfig_Clear(config);
    }
    sbf_restore_host_signals();
    if (py.PyStatus_Exception(status)) {
        char cause[1024];
        if (!sbf_unusable_stdio(cause, sizeof cause))
            snprintf(cause, sizeof cause, "Set %s to another CPython 3 shared library (3.%d or newer) with its "
                     "standard library, or unset it", LIBPYTHON_VARIABLE, SBF_PYTHON_FLOOR_MINOR);
        sbf_fail("Python (%s) failed to start: %s%s%s. %s", where, status.func ? status.func : "",
                 status.func ? ": " : "", status.err_msg ? status.err_msg : "unknown error", cause);
        return;
    }
    py.PyEval_SaveThread(); /* this thread keeps its (main) thread state */
    thread_has_state = 1;
}

/* Whether Python (started) imports ctypes, which the FMU's Python code needs (its C extension _ctypes and the
 * libraries that loads); else 0 after sbf_fail() with Python's exception: an FMI library whose import of the slave
 * fails crashes the host (pythonfmu3) or reports a fatal error (PythonFMU). */
static int imports_ctypes(const char *where)
{
    int gil = py.PyGILState_Ensure();
    void *module = py.PyImport_ImportModule("ctypes"), *type = NULL, *value = NULL, *trace = NULL;
    if (module)
        py.Py_DecRef(module);
    else {
        py.PyErr_Fetch(&type, &value, &trace);
        void *text = value ? py.PyObject_Str(value) : NULL;
        const char *utf8 = text ? py.PyUnicode_AsUTF8(text) : NULL;
        sbf_fail("Python (%s) cannot import ctypes, which the FMU needs: %s", where, utf8 ? utf8 : "unknown error");
        py.Py_DecRef(text), py.Py_DecRef(type), py.Py_DecRef(value), py.Py_DecRef(trace); /* each may be NULL */
    }
    py.PyGILState_Release(gil);
    return module != NULL;
}

/* ---- the inner library's exit fault ----
 * PythonFMU 0.7.0 and pythonfmu3 0.3.4 keep their Python start-up object in a global std::shared_ptr, which their
 * function finalizePythonInterpreter() resets. On Linux the object is destroyed twice at process exit: by the
 * pointer's static destructor and again by the library's ELF destructor, which calls finalizePythonInterpreter()
 * on the pointer the first one left dangling (glibc then aborted the host at random: "corrupted double-linked list",
 * "double free"); the loader calls it once before either runs. On Windows the library's own DLL_PROCESS_DETACH
 * destroys it once, before the loader's (DLLs loaded later are detached first), and a call from the loader's exit
 * handlers, which run at the loader's DLL_PROCESS_DETACH, would destroy it again. Each platform does what it needs in
 * sbf_reset_inner_at_exit (platform.h). */

/* Keep this library loaded until the process ends (0 after sbf_fail() if it cannot be). Once sbf_start has run, the
 * library has code that runs after any call of the host: the destructor of every host thread's Python thread state
 * (sbf_at_thread_exit, run when the thread ends, which may be after the host's dlclose), the Ctrl-C handler
 * (sbf_defer_interrupts) and the exit handler (sbf_reset_inner_at_exit, Linux); Python, started once, cannot be
 * started again in the process, and the inner library it runs stays loaded too. Unloading it would leave those
 * pointing into unmapped memory (a host that unloads the FMU and then ends a thread that called it died with
 * SIGSEGV). So the library pins itself here (sbf_pin_loader); a host's unloading then only drops a reference. */
static int pin_library(void)
{
    char why[1024];
    if (sbf_pin_loader(why, sizeof why)) return 1;
    sbf_fail("cannot keep the FMU's binary loaded: %s", why);
    return 0;
}

/* The carried CPython's build of the inner library (SBF_BUNDLED_INNER), unpacked if it is not yet, opened; its path
 * in `path`. `first`: why the FMU's own did not load ("" where the FMU has none beside this library). NULL after
 * sbf_fail(). */
static void *open_carried_inner(char *path, size_t size, const char *first)
{
    char why[4096 + 256];
    if (!sbf_carried_path(SBF_BUNDLED_INNER, path, size, why, sizeof why)) {
        sbf_fail("cannot load the FMU's inner binary%s%s%s, and %s", *first ? " (" : "", first, *first ? ")" : "",
                 why);
        return NULL;
    }
    void *lib = sbf_open_library(path, 0);
    if (!lib)
        sbf_fail("cannot load the FMU's inner binary %s (%s): %s", path, *first ? "the build the FMU carries for "
                 "systems on which its own does not load" : "the one its packed CPython holds", sbf_library_error());
    return lib;
}

static void load_inner(sbf_resolve_inner resolve, void *python)
{
    char path[4096] = "", why[4096 + 256];
    if (*SBF_INNER_LIBRARY && !beside_this_library(SBF_INNER_LIBRARY, path, sizeof path)) return;
    if (!sbf_bind_inner_to_python(python, why, sizeof why)) {
        sbf_fail("cannot load the FMU's inner binary %s: %s", *path ? path : SBF_BUNDLED_INNER, why);
        return;
    }
    void *lib = *path ? sbf_open_library(path, 0) : NULL;
    if (!lib && *path && *bundled_inner_needs) { /* the system lacks its C++ runtime, or has an older one: the FMU's */
        load_bundled(bundled_inner_needs, 0);
        lib = sbf_open_library(path, 0);
    }
    if (!lib && *SBF_BUNDLED_INNER) { /* the same, or none beside this library: the carried build */
        char first[1024] = "";
        if (*path) snprintf(first, sizeof first, "%s", sbf_library_error());
        if (!(lib = open_carried_inner(path, sizeof path, first))) return;
    } else if (!lib) {
        sbf_fail("cannot load the FMU's inner binary %s%s: %s", path,
                 *bundled_inner_needs ? " (also with the C++ runtime the FMU carries)" : "", sbf_library_error());
        return;
    }
    if (resolve(lib, path)) sbf_reset_inner_at_exit(lib, path, "finalizePythonInterpreter");
}

/* Steps 1 and 2 of sbf_start, under the process-wide lock: the CPython library (NULL after sbf_fail()), started. */
static void *start_python(void)
{
    const char *where = "";
    void *lib = NULL;
    char why[4096 + 256];
    if (!sbf_process_lock(why, sizeof why)) {
        sbf_fail("%s", why);
        return NULL;
    }
    int found = find_libpython(&lib, &where) && python_new_enough(lib, where);
    if (found && !resolve_python(lib))
        sbf_fail("%s is not a usable CPython library: %s", where, sbf_library_error());
    else if (found && !py.Py_IsInitialized()) {
        if (!resolve_config_api(lib))
            sbf_fail("%s lacks the PyConfig API: CPython 3.8 or newer is needed (set %s)", where, LIBPYTHON_VARIABLE);
        else
            initialize_python(lib, where);
    }
    if (started == 0) imports_ctypes(where);
    if (started == 0) sbf_defer_interrupts(lib);
    sbf_process_unlock();
    return started == 0 ? lib : NULL;
}

/* Whether the FMU's files beside this library can be opened by their paths (sbf_path_fits); else 0 after
 * sbf_fail(). */
static int binaries_folder_fits(void)
{
    char self[4096], why[1024];
    if (!sbf_loader_path(self, sizeof self) || sbf_path_fits(self, why, sizeof why)) return 1;
    sbf_fail("the FMU's binary %s cannot start: %s", self, why);
    return 0;
}

int sbf_start(sbf_resolve_inner resolve)
{
    sbf_loader_lock();
    if (started == 0 && binaries_folder_fits() && pin_library()) {
        void *lib = start_python();
        if (started == 0) sbf_fast_resolve(lib);
        if (started == 0) load_inner(resolve, lib);
        if (started == 0) started = 1;
    }
    sbf_loader_unlock();
    return started == 1;
}

/* ---- Ctrl-C during a call into the model: see sbf_defer_interrupts (platform.h) ---- */

/* Whether Python has noted an interrupt that it has not acted on yet (taking it back) */
static int python_interrupt_pending(void)
{
    int gil = py.PyGILState_Ensure();
    int pending = py.PyOS_InterruptOccurred();
    py.PyGILState_Release(gil);
    return pending;
}

void sbf_call_begin(void) { sbf_interrupts_begin(py.PyOS_InterruptOccurred ? python_interrupt_pending : NULL); }

void sbf_call_end(void) { sbf_interrupts_end(); }

static int imported;                  /* this library's first instantiation is done */
static SBF_THREAD_LOCAL int importing; /* this thread makes it, holding the start lock */

void sbf_instantiate_begin(void)
{
    char why[1024];
    if (!imported && sbf_process_lock(why, sizeof why)) { /* without the lock (it was had at the start): as before */
        if (imported)
            sbf_process_unlock();
        else
            importing = 1;
    }
    sbf_call_begin();
}

void sbf_instantiate_end(void)
{
    sbf_call_end();
    if (!importing) return;
    importing = 0;
    imported = 1;
    sbf_process_unlock();
}

/* ---- host threads' Python thread states ----
 * A host thread without a Python thread state gets one on its first call, kept for its life: PyGILState_Ensure
 * makes it (and takes the GIL), PyEval_SaveThread gives the GIL back and leaves the state's count at 1, so the
 * inner library's per-call Ensure/Release neither make nor delete one. When the thread ends, delete_thread_state
 * (registered with sbf_at_thread_exit, which holds the state) deletes it: a host that calls from a new thread each
 * time keeps no state per call (about 4.4 kB each). It does so directly, not through PyGILState_Release: the
 * system clears every thread-specific value of the thread, Python's own record of the thread's state among them,
 * before or while it calls the destructors. A thread that has a state of its own (the Python threads of a
 * Python host) keeps it untouched. */

static void delete_thread_state(void *state)
{
    if (!py.Py_IsInitialized() || (py.Py_IsFinalizing && py.Py_IsFinalizing())) return; /* the interpreter goes */
    py.PyEval_RestoreThread(state); /* the GIL taken, the state current */
    py.PyThreadState_Clear(state);
    py.PyThreadState_DeleteCurrent(); /* and the GIL released */
}

void sbf_keep_thread_state(void)
{
    if (thread_has_state) return;
    thread_has_state = 1;
    if (py.PyGILState_GetThisThreadState()) return; /* the thread has a state of its own */
    py.PyGILState_Ensure();
    sbf_at_thread_exit(delete_thread_state, py.PyEval_SaveThread()); /* release the GIL, keep the state */
}

int sbf_model_fast_step(sbf_fast_path *fast, double t, double h, char *why, size_t why_size)
{
    sbf_call_begin();
    int outcome = sbf_fast_step(fast, t, h, why, why_size);
    sbf_call_end();
    return outcome;
}

const char *sbf_exception_text(const char *message, char *out, size_t size)
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

/* ---- the resource location ---- */

/* `text` percent-decoded (RFC 3986: every %XY to the byte XY) into `out`; 0 with the cause in `why` if an escape
 * is malformed, decodes to a NUL byte, or the result does not fit. */
static int percent_decode(const char *text, char *out, size_t size, char *why, size_t why_size)
{
    size_t n = 0;
    for (const char *c = text; *c; ++c) {
        unsigned int byte = (unsigned char)*c;
        if (*c == '%') {
            if (!isxdigit((unsigned char)c[1]) || !isxdigit((unsigned char)c[2])) {
                snprintf(why, why_size, "has a '%%' not followed by two hexadecimal digits (at character %d)",
                         (int)(c - text) + 1);
                return 0;
            }
            const char hex[3] = {c[1], c[2], '\0'};
            byte = (unsigned int)strtoul(hex, NULL, 16);
            if (byte == 0) {
                snprintf(why, why_size, "encodes a NUL byte (%%00)");
                return 0;
            }
            c += 2;
        }
        if (n + 1 >= size) {
            snprintf(why, why_size, "is too long");
            return 0;
        }
        out[n++] = (char)byte;
    }
    out[n] = '\0';
    return 1;
}

/* The path of `location` into `path` (see sbf_resource_folder); 0 with the cause in `why`. */
static int location_path(const char *location, char *path, size_t size, char *why, size_t why_size)
{
    char decoded[4096];
    if (!*location) return snprintf(why, why_size, "is empty"), 0;
    if (sbf_is_absolute_path(location)) {
        if (strlen(location) >= size) return snprintf(why, why_size, "is too long"), 0;
        strcpy(path, location);
        sbf_plain_path(path);
        return 1;
    }
    if (strncasecmp(location, "file:", 5) != 0)
        return snprintf(why, why_size, "is neither a file URI (file:///path) nor an absolute path"), 0;
    const char *rest = location + 5, *authority = "";
    size_t length = 0;
    if (strncmp(rest, "//", 2) == 0) {
        const char *slash = strchr(authority = rest + 2, '/');
        if (!slash) return snprintf(why, why_size, "has no path after its host"), 0;
        length = (size_t)(slash - authority);
        rest = slash;
    }
    if (rest[0] != '/') return snprintf(why, why_size, "is not an absolute file URI (file:///path)"), 0;
    if (!percent_decode(rest, decoded, sizeof decoded, why, why_size) ||
        !sbf_uri_path(authority, length, decoded, path, size, why, why_size))
        return 0;
    sbf_plain_path(path);
    return 1;
}

/* Whether `text` is well-formed UTF-8 (Unicode's table 3-7), which Python needs to take the folder's path. */
static int is_utf8(const unsigned char *text)
{
    while (*text) {
        unsigned char lead = *text++, low = 0x80, high = 0xBF;
        int more = lead < 0x80 ? 0 : lead < 0xC2 ? -1 : lead < 0xE0 ? 1 : lead < 0xF0 ? 2 : lead < 0xF5 ? 3 : -1;
        if (more < 0) return 0;
        if (lead == 0xE0) low = 0xA0;
        if (lead == 0xED) high = 0x9F; /* no surrogates */
        if (lead == 0xF0) low = 0x90;
        if (lead == 0xF4) high = 0x8F;
        for (; more > 0; --more, ++text, low = 0x80, high = 0xBF)
            if (*text < low || *text > high) return 0;
    }
    return 1;
}

/* Whether the folder `path` holds the FMU's slave module (slavemodule.txt naming <module>.py beside it, which the
 * inner library imports); else the missing file in `why`. */
static int holds_slave_module(const char *path, char *why, size_t why_size)
{
    char file[4096 + 64], module[256] = "", cause[256];
    snprintf(file, sizeof file, "%s/slavemodule.txt", path);
    FILE *list = sbf_open_text(file);
    if (list) {
        if (!fgets(module, sizeof module, list)) module[0] = '\0';
        fclose(list);
    }
    module[strcspn(module, "\r\n")] = '\0';
    if (!*module) return snprintf(why, why_size, "is not this FMU's resources folder: %s is missing or empty", file), 0;
    snprintf(file, sizeof file, "%s/%s.py", path, module);
    if (sbf_path_kind(file, cause, sizeof cause) != 2)
        return snprintf(why, why_size, "is not this FMU's resources folder: %s is missing", file), 0;
    return 1;
}

/* The resources folder of `location` into `path`; 0 with a message naming the location and the cause in `why`. */
static int resource_folder(const char *location, char *path, size_t size, char *why, size_t why_size)
{
    char cause[4096 + 256], error[256];
    int ok = 0, kind;
    if (!location)
        return snprintf(why, why_size, "the resource location is NULL"), 0;
    if (location_path(location, path, size, cause, sizeof cause)) {
        if (!is_utf8((const unsigned char *)path))
            snprintf(cause, sizeof cause, "names a folder whose path is not UTF-8 text, which Python cannot take");
        else if ((kind = sbf_path_kind(path, error, sizeof error)) == 0)
            snprintf(cause, sizeof cause, "names the folder %s, which does not exist (%s)", path, error);
        else if (kind != 1)
            snprintf(cause, sizeof cause, "names %s, which is not a folder", path);
        else
            ok = holds_slave_module(path, cause, sizeof cause);
    }
    if (!ok) snprintf(why, why_size, "the resource location \"%s\" %s", location, cause);
    return ok;
}

/* Whether the inner library (PythonFMU 0.7.0, pythonfmu3 0.3.4) takes `path` as it is: both replace every "%20" in
 * the resource location by a space and then cut its first "file://" out (CppfmuInstantiateSlave), and must be able
 * to open files under it (sbf_library_cannot_open). */
static int taken_as_is(const char *path)
{
    return !strstr(path, "%20") && !strstr(path, "file://") && !sbf_library_cannot_open(path);
}

/* The path the inner library is given for the resources folder `folder` (an absolute path), into `path`: `folder`
 * itself where the library takes it as it is, else another path to the same folder (sbf_folder_alias) that it does.
 * The slave then learns `folder` itself from the loader (sbf_bound_folder). 0 with the cause in `why` if neither. */
static int inner_library_path(const char *folder, char *path, size_t size, char *why, size_t why_size)
{
    char cause[1024];
    const char *unopenable = sbf_library_cannot_open(folder);
    if (taken_as_is(folder)) return snprintf(path, size, "%s", folder), 1;
    if (sbf_folder_alias(folder, path, size, cause, sizeof cause)) return 1;
    if (!sbf_path_fits(folder, cause, sizeof cause))
        return snprintf(why, why_size, "the resources folder %s cannot be handed to the FMU's library: %s", folder,
                        cause), 0;
    snprintf(why, why_size, "the resources folder %s cannot be handed to the FMU's library, which rewrites '%%20' and "
             "'file://' in it%s%s (%s): move the FMU to a folder whose name has neither%s", folder,
             unopenable ? " and cannot open it: " : "", unopenable ? unopenable : "", cause,
             unopenable ? ", in ASCII letters" : "");
    return 0;
}

int sbf_check_instance(const char *function, const char *name, const char *token_name, const char *token,
                       const char *location, char *folder, char *path, size_t size, char *why, size_t why_size)
{
    char cause[8192];
    if (!name)
        snprintf(cause, sizeof cause, "the instance name is NULL");
    else if (!token || strcmp(token, SBF_TOKEN) != 0)
        snprintf(cause, sizeof cause, "the %s %s%s%s is not this FMU's %s \"%s\" (see its modelDescription.xml)",
                 token_name, token ? "\"" : "", token ? token : "NULL", token ? "\"" : "", token_name, SBF_TOKEN);
    else if (resource_folder(location, folder, size, cause, sizeof cause) &&
             inner_library_path(folder, path, size, cause, sizeof cause))
        return 1;
    snprintf(why, why_size, "%s: %s", function, cause);
    return 0;
}

int sbf_call_refused(sbf_mode mode, unsigned allowed, const char *function, char *why, size_t why_size)
{
    static const char *const names[] = {
        [SBF_INSTANTIATED] = "Instantiated", [SBF_INITIALIZING] = "Initialization Mode", [SBF_STEPPING] = "Step Mode",
        [SBF_TERMINATED] = "Terminated", [SBF_EVENT] = "Event Mode", [SBF_CONTINUOUS] = "Continuous-Time Mode"};
    if (allowed & SBF_IN(mode)) return 0;
    int n = snprintf(why, why_size, "%s is not allowed in %s (allowed in", function, names[mode]);
    const char *separator = " ";
    for (size_t i = 0; i < sizeof names / sizeof *names; ++i) {
        if (!(allowed & SBF_IN(i)) || n < 0 || (size_t)n >= why_size) continue;
        n += snprintf(why + n, why_size - (size_t)n, "%s%s", separator, names[i]);
        separator = ", ";
    }
    if (n >= 0 && (size_t)n < why_size)
        snprintf(why + n, why_size - (size_t)n, "%s", mode == SBF_INITIALIZING
                 ? "; exiting Initialization Mode has not succeeded)" : ")");
    return 1;
}

int sbf_step_refused(sbf_mode mode, int exchange, const char *function, double t, char *why, size_t why_size)
{
    static const char *const refusal[] = {
        [SBF_INSTANTIATED] = "before initialization (enter and exit initialization mode first)",
        [SBF_INITIALIZING] = "during initialization (exiting initialization mode has not succeeded)",
        [SBF_STEPPING] = NULL,
        [SBF_TERMINATED] = "after termination (reset the instance to start again)",
        [SBF_EVENT] = "in Event Mode (call fmi3EnterStepMode first)",
        [SBF_CONTINUOUS] = "in Continuous-Time Mode"};
    const char *refused = exchange ? "for a model-exchange instance" : refusal[mode];
    if (!refused) return 0;
    snprintf(why, why_size, "%s at t = %g s is not allowed %s", function, t, refused);
    return 1;
}

int sbf_experiment_refused(const char *function, int tolerance_defined, double tolerance, double start,
                           int stop_defined, double stop, char *why, size_t why_size)
{
    const char *name = NULL;
    double value = 0.0;
    if (!isfinite(start))
        name = "startTime", value = start;
    else if (stop_defined && !isfinite(stop))
        name = "stopTime", value = stop;
    else if (tolerance_defined && !isfinite(tolerance))
        name = "tolerance", value = tolerance;
    if (!name) return 0;
    snprintf(why, why_size, "%s: %s = %g; allowed: a finite value", function, name, value);
    return 1;
}

/* ---- the host's log categories ---- */

void sbf_set_log_filter(sbf_log_filter *filter, int on, size_t n, const char *const *categories)
{
    for (size_t i = 0; i < filter->n_categories; ++i) free(filter->categories[i]);
    free(filter->categories);
    filter->categories = NULL;
    filter->n_categories = 0;
    filter->on = on;
    if (n == 0 || !categories) return;
    filter->categories = calloc(n, sizeof(char *));
    for (size_t i = 0; filter->categories && i < n; ++i)
        if (categories[i]) filter->categories[filter->n_categories++] = strdup(categories[i]);
}

/* The <LogCategories> of the model description: PythonFMU's Fmi2Slave.log_categories, pythonfmu3's
 * Fmi3SlaveBase.log_categories (the same names). */
static const char *const log_categories[] = {"logStatusWarning", "logStatusDiscard", "logStatusError",
                                             "logStatusFatal", "logAll"};
#define N_LOG_CATEGORIES (sizeof log_categories / sizeof *log_categories)

size_t sbf_listed_categories(const char *const **names)
{
    *names = log_categories;
    return N_LOG_CATEGORIES;
}

static int listed_category(const char *name)
{
    for (size_t k = 0; name && k < N_LOG_CATEGORIES; ++k)
        if (strcmp(name, log_categories[k]) == 0) return 1;
    return 0;
}

/* The category a message reaches the host with: its own if the model description lists it, else its status's
 * (OK and Pending: logAll); the libraries pass NULL, "" or "cppfmu", which no host can filter on. */
const char *sbf_category(int status, const char *category)
{
    static const char *const by_status[] = {"logAll", "logStatusWarning", "logStatusDiscard", "logStatusError",
                                            "logStatusFatal", "logAll"};
    if (listed_category(category)) return category;
    return status >= 0 && status < (int)(sizeof by_status / sizeof *by_status) ? by_status[status] : "logStatusError";
}

int sbf_known_categories(const char *function, size_t n, const char *const *categories, char *why, size_t size)
{
    for (size_t i = 0; i < n; ++i) {
        const char *name = categories ? categories[i] : NULL;
        if (listed_category(name)) continue;
        char shown[256];
        snprintf(shown, sizeof shown, name ? "\"%s\"" : "NULL", name);
        int used = snprintf(why, size, "%s: categories[%zu] = %s is not a log category of this FMU; the model "
                            "description lists", function, i, shown);
        for (size_t k = 0; k < N_LOG_CATEGORIES && used >= 0 && (size_t)used < size; ++k)
            used += snprintf(why + used, size - used, "%s %s", k ? "," : "", log_categories[k]);
        return 0;
    }
    return 1;
}

int sbf_log_wanted(const sbf_log_filter *filter, int status, const char *category)
{
    if (status >= 1 && status <= 4) return 1; /* warning, discard, error, fatal: always */
    if (!filter->on) return 0;
    if (filter->n_categories == 0) return 1;
    for (size_t i = 0; i < filter->n_categories; ++i)
        if (category && strcmp(category, filter->categories[i]) == 0) return 1;
    return 0;
}
