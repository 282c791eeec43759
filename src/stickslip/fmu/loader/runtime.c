/* The loader's shared part (runtime.h): CPython found and started, the inner library loaded.
 *
 * On the first instantiation a front calls sbf_start, which
 *   1. finds a CPython: the process's own if it has one (never a second one), else the shared library
 *      named by $SBF_LIBPYTHON, else the one the FMU was built with (SBF_BUILD_LIBPYTHON), else its
 *      soname (SBF_LIBPYTHON_SONAME); it is loaded with RTLD_GLOBAL so that Python's extension modules
 *      find its symbols;
 *   2. starts that Python if nobody has, with the standard library of the library's own installation,
 *      through PyConfig, so that a broken installation (a wrong PYTHONHOME) is an error status and a
 *      logged message, not an exit of the host; the host's handlers of SIGINT, SIGPIPE and SIGXFSZ are kept;
 *   3. loads the inner library (PythonFMU's or pythonfmu3's binary, SBF_INNER_LIBRARY beside this one)
 *      and lets the front resolve its entry points.
 * Steps 1 and 2 run under a process-wide lock that every copy of the loader in the process shares (see
 * process_start_lock), and sbf_start first pins this library in memory (see pin_library).
 * Each host thread gets one Python thread state, kept for the thread's life (sbf_keep_thread_state).
 * The resource location a host passes is decoded and checked here for both fronts (sbf_check_instance), and the
 * inner library is handed a path to that folder that it does not rewrite (inner_library_path).
 * A SIGINT that arrives while the process's main thread is inside a call into the model reaches the host's handler
 * when that call returns (sbf_call_begin).
 * What depends on the operating system (Linux, glibc) is in this file only.
 * At process exit the inner library's Python start-up object is reset once before its own destructors run
 * (see reset_inner_python_state).
 */
#define _GNU_SOURCE
#include "runtime.h"

#include <ctype.h>
#include <dlfcn.h>
#include <elf.h>
#include <errno.h>
#include <fcntl.h>
#include <link.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#ifndef SBF_INNER_LIBRARY
#error "define SBF_INNER_LIBRARY: the file name of the inner FMU binary beside this library"
#endif
#ifndef SBF_TOKEN
#error "define SBF_TOKEN: the FMU's GUID (FMI 2) or instantiation token (FMI 3)"
#endif
#ifndef SBF_START_GUARD
#error "define SBF_START_GUARD: the file name of the process-wide start guard library beside this library"
#endif
#ifndef SBF_BUILD_LIBPYTHON
#define SBF_BUILD_LIBPYTHON ""
#endif
#ifndef SBF_LIBPYTHON_SONAME
#define SBF_LIBPYTHON_SONAME ""
#endif
#define LIBPYTHON_VARIABLE "SBF_LIBPYTHON"

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
    void (*PyConfig_InitPythonConfig)(void *);
    PyStatus (*PyConfig_SetBytesArgv)(void *, long, char *const *);
    PyStatus (*Py_InitializeFromConfig)(const void *);
    void (*PyConfig_Clear)(void *);
    int (*PyStatus_Exception)(PyStatus);
} py;
enum { PyGILState_LOCKED, PyGILState_UNLOCKED };
#define PYCONFIG_BYTES 16384 /* room for any CPython 3.8-3.13 PyConfig (about 0.5 kB) */

static pthread_mutex_t start_lock = PTHREAD_MUTEX_INITIALIZER;
static int started;           /* 0 not tried, 1 ready, -1 failed (start_error says why) */
static char start_error[2048];
static __thread int thread_has_state; /* this host thread owns a Python thread state */

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
#define RESOLVE(symbol) (*(void **)&py.symbol = dlsym(lib, #symbol)) != NULL
    *(void **)&py.Py_IsFinalizing = dlsym(lib, "Py_IsFinalizing");
    if (!py.Py_IsFinalizing) *(void **)&py.Py_IsFinalizing = dlsym(lib, "_Py_IsFinalizing");
    *(void **)&py.PyOS_InterruptOccurred = dlsym(lib, "PyOS_InterruptOccurred");
    return RESOLVE(Py_IsInitialized) && RESOLVE(PyGILState_Ensure) && RESOLVE(PyGILState_Release) &&
           RESOLVE(PyGILState_GetThisThreadState) && RESOLVE(PyEval_SaveThread) && RESOLVE(PyEval_RestoreThread) &&
           RESOLVE(PyThreadState_Clear) && RESOLVE(PyThreadState_DeleteCurrent);
}

static int resolve_config_api(void *lib)
{
    return RESOLVE(PyConfig_InitPythonConfig) && RESOLVE(PyConfig_SetBytesArgv) && RESOLVE(Py_InitializeFromConfig) &&
           RESOLVE(PyConfig_Clear) && RESOLVE(PyStatus_Exception);
#undef RESOLVE
}

/* A CPython library: the process's own (RTLD_DEFAULT), or the first that loads (RTLD_GLOBAL). 0 after sbf_fail(). */
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
            sbf_fail("cannot load the CPython library named by %s=%s: %s. Set %s to the path of a CPython 3 shared "
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
    sbf_fail("no CPython shared library found; tried %s. This FMU runs its model in Python: install CPython 3 with "
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
        sbf_fail("Python (%s) failed to start: %s%s%s. Check PYTHONHOME (%s) and PYTHONPATH: unset them, or point "
             "them at this Python's installation, or set %s to another CPython 3 shared library.",
             where, status.func ? status.func : "", status.func ? ": " : "",
             status.err_msg ? status.err_msg : "unknown error", home ? home : "not set", LIBPYTHON_VARIABLE);
        return;
    }
    py.PyEval_SaveThread(); /* this thread keeps its (main) thread state */
    thread_has_state = 1;
}

/* ---- the inner library's exit fault ----
 * PythonFMU 0.7.0 and pythonfmu3 0.3.4 keep their Python start-up object in a global std::shared_ptr, which is
 * destroyed twice at process exit: by its static destructor (an exit handler) and again by the library's ELF
 * destructor, which calls finalizePythonInterpreter() to reset the pointer the first one left dangling. The
 * second one decrements a reference count in freed memory (and may free the object again): glibc then aborts
 * the host at exit at random ("corrupted double-linked list", "double free"). Resetting the pointer once,
 * through that same function, before either runs makes both harmless: the handler registered here, after the
 * library was loaded, runs before its static destructor (exit handlers run last-in, first-out). */
static void (*inner_reset_python_state)(void);

static void reset_inner_python_state(void) { inner_reset_python_state(); }

/* The function `name` of the loaded library `lib` (opened from `path`): its dynamic symbol, else its entry in
 * the file's full symbol table (PythonFMU does not export finalizePythonInterpreter); NULL if neither. */
static void *find_function(void *lib, const char *path, const char *name)
{
    void *function = dlsym(lib, name);
    struct link_map *map;
    struct stat st;
    if (function || dlinfo(lib, RTLD_DI_LINKMAP, &map) != 0) return function;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return NULL;
    const unsigned char *file = MAP_FAILED;
    if (fstat(fd, &st) == 0 && (size_t)st.st_size >= sizeof(Elf64_Ehdr))
        file = mmap(NULL, st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
    close(fd);
    if (file == MAP_FAILED) return NULL;
    size_t size = st.st_size, name_size = strlen(name) + 1;
    const Elf64_Ehdr *header = (const void *)file;
    if (memcmp(header->e_ident, ELFMAG, SELFMAG) == 0 && header->e_ident[EI_CLASS] == ELFCLASS64 &&
        header->e_shentsize == sizeof(Elf64_Shdr) && header->e_shoff + header->e_shnum * sizeof(Elf64_Shdr) <= size) {
        const Elf64_Shdr *sections = (const void *)(file + header->e_shoff);
        for (size_t i = 0; i < header->e_shnum && !function; ++i) {
            const Elf64_Shdr *symbols = &sections[i];
            if (symbols->sh_type != SHT_SYMTAB || symbols->sh_link >= header->e_shnum) continue;
            const Elf64_Shdr *strings = &sections[symbols->sh_link];
            if (symbols->sh_offset + symbols->sh_size > size || strings->sh_offset + strings->sh_size > size) continue;
            const Elf64_Sym *symbol = (const void *)(file + symbols->sh_offset);
            for (size_t j = 0; j < symbols->sh_size / sizeof *symbol; ++j, ++symbol)
                if (ELF64_ST_TYPE(symbol->st_info) == STT_FUNC && symbol->st_value &&
                    symbol->st_name + name_size <= strings->sh_size &&
                    memcmp(file + strings->sh_offset + symbol->st_name, name, name_size) == 0) {
                    function = (void *)(map->l_addr + symbol->st_value);
                    break;
                }
        }
    }
    munmap((void *)file, size);
    return function;
}

/* The path of the file `name` beside this library into `path`; 0 after sbf_fail() if this library cannot be found. */
static int beside_this_library(const char *name, char *path, size_t size)
{
    Dl_info self;
    if (!dladdr((void *)&sbf_start, &self) || !self.dli_fname) {
        sbf_fail("cannot locate the FMU's binaries folder");
        return 0;
    }
    const char *slash = strrchr(self.dli_fname, '/');
    int dir_length = slash ? (int)(slash - self.dli_fname + 1) : 0;
    snprintf(path, size, "%.*s%s", dir_length, self.dli_fname, name);
    return 1;
}

/* Keep this library loaded until the process ends (0 after sbf_fail() if it cannot be). Once sbf_start has run, the
 * library has code that runs after any call of the host: the destructor of every host thread's Python thread state
 * (owned_state_key, run by glibc when the thread ends, which may be after the host's dlclose), the SIGINT handler
 * (sbf_call_begin) and the exit handler (reset_inner_python_state); Python, started once, cannot be started again
 * in the process, and the inner library it runs stays loaded too. Unloading it would leave those pointing into
 * unmapped memory (a host that unloads the FMU and then ends a thread that called it died with SIGSEGV). So the
 * library pins itself with RTLD_NODELETE here, rather than being linked with -z nodelete: a host that loads it and
 * unloads it without instantiating (to read its functions, say) still unloads it, and the pin holds however the
 * library was linked. dlclose of the host's handle then only drops a reference. */
static int pin_library(void)
{
    Dl_info self;
    if (dladdr((void *)&sbf_start, &self) && self.dli_fname &&
        dlopen(self.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE))
        return 1;
    sbf_fail("cannot keep the FMU's binary loaded: %s", dlerror());
    return 0;
}

/* The lock under which the first copy of the loader in the process starts Python, NULL after sbf_fail(). Every FMU
 * built with this loader (the block's FMI 2 and FMI 3 FMUs, the coupling FMU, and each copy of them in another
 * folder) is a separate library with its own statics, so a lock of its own cannot keep two of them from starting
 * Python at once on two threads (which crashed the host). The lock is the symbol sbf_python_start_lock of the tiny
 * start guard library (start_guard.c) that every FMU ships beside its loader: each loader opens its own copy with
 * RTLD_GLOBAL (and RTLD_NODELETE), then looks the symbol up with dlsym(RTLD_DEFAULT), which searches the global
 * scope in load order and so answers every copy with the definition of the guard loaded first, for the life of the
 * process (dlopen and dlsym are serialized by the dynamic linker). The symbol's name is the guard's only export. */
static pthread_mutex_t *process_start_lock(void)
{
    char path[4096];
    if (!beside_this_library(SBF_START_GUARD, path, sizeof path)) return NULL;
    if (!dlopen(path, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE)) {
        sbf_fail("cannot load the FMU's start guard %s: %s", path, dlerror());
        return NULL;
    }
    pthread_mutex_t *lock = dlsym(RTLD_DEFAULT, "sbf_python_start_lock");
    if (!lock) sbf_fail("the FMU's start guard %s lacks sbf_python_start_lock: %s", path, dlerror());
    return lock;
}

static void load_inner(sbf_resolve_inner resolve)
{
    char path[4096];
    if (!beside_this_library(SBF_INNER_LIBRARY, path, sizeof path)) return;
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        sbf_fail("cannot load the FMU's inner binary %s: %s", path, dlerror());
        return;
    }
    if (!resolve(lib, path)) return;
    *(void **)&inner_reset_python_state = find_function(lib, path, "finalizePythonInterpreter");
    if (inner_reset_python_state) atexit(reset_inner_python_state);
}

static void defer_sigint_in_model_calls(void);

/* Steps 1 and 2 of sbf_start, under the process-wide lock: the CPython library (NULL after sbf_fail()), started. */
static void *start_python(void)
{
    const char *where = "";
    void *lib = NULL;
    pthread_mutex_t *process_lock = process_start_lock();
    if (!process_lock) return NULL;
    pthread_mutex_lock(process_lock);
    int found = find_libpython(&lib, &where);
    if (found && !resolve_python(lib))
        sbf_fail("%s is not a usable CPython library: %s", where, dlerror());
    else if (found && !py.Py_IsInitialized()) {
        if (!resolve_config_api(lib))
            sbf_fail("%s lacks the PyConfig API: CPython 3.8 or newer is needed (set %s)", where, LIBPYTHON_VARIABLE);
        else
            initialize_python(where);
    }
    if (started == 0) defer_sigint_in_model_calls();
    pthread_mutex_unlock(process_lock);
    return started == 0 ? lib : NULL;
}

int sbf_start(sbf_resolve_inner resolve)
{
    pthread_mutex_lock(&start_lock);
    if (started == 0 && pin_library()) {
        void *lib = start_python();
        if (started == 0) sbf_fast_resolve(lib);
        if (started == 0) load_inner(resolve);
        if (started == 0) started = 1;
    }
    pthread_mutex_unlock(&start_lock);
    return started == 1;
}

/* ---- Ctrl-C during a call into the model ----
 * A Python host (FMPy, ...) runs its SIGINT handler, which raises KeyboardInterrupt, in its main thread at the next
 * Python instruction that thread runs. When the signal arrives while that thread is inside a call into the model,
 * that instruction is the slave's: the inner library then reports the KeyboardInterrupt as the slave's failure
 * (an error status, the call maybe half done). Blocking SIGINT in the calling thread is not enough: the kernel
 * then hands the signal to another thread of the host (a Python host has some: numpy's BLAS pool, its own), whose
 * run of the handler trips Python's flag all the same. So the handler that the process has when Python is ready is
 * wrapped, once per loader copy (under the process-wide lock, so copies chain): while the main thread is inside a
 * call into the model, the wrapper only notes the signal, and the call's end raises it again, so that the host's
 * handler runs after the call returns, on that thread. Calls from other threads are not waited for (Python runs its
 * handlers in the main thread only). A SIGINT that reached Python's handler just before a call, which Python has
 * noted but not yet acted on, would be acted on in the model's code all the same (or lost, in a call whose Python
 * exceptions the loader clears): the wrapper notes that it passed one on, and the next call on the main thread
 * takes it back from Python (PyOS_InterruptOccurred) and defers it too. Costs per call: a thread-local read, and on
 * the main thread two counter updates (and, once after each SIGINT, taking the GIL). A default or ignored SIGINT is
 * left alone; a handler the host installs later replaces the wrapper. */
static struct sigaction host_sigint;        /* the handler wrapped */
static volatile sig_atomic_t main_in_model; /* depth of calls into the model on the process's main thread */
static volatile sig_atomic_t sigint_deferred;
static volatile sig_atomic_t sigint_passed_on; /* the wrapper called the host's handler since the last call began */
static __thread int on_main_thread = -1;    /* -1 not known yet */

static void deferring_handler(int signal, siginfo_t *info, void *context)
{
    if (main_in_model) {
        sigint_deferred = 1;
        return;
    }
    sigint_passed_on = 1;
    if (host_sigint.sa_flags & SA_SIGINFO)
        host_sigint.sa_sigaction(signal, info, context);
    else
        host_sigint.sa_handler(signal);
}

static void defer_sigint_in_model_calls(void)
{
    struct sigaction now, wrapper;
    if (sigaction(SIGINT, NULL, &now) != 0) return;
    if (now.sa_flags & SA_SIGINFO ? !now.sa_sigaction : now.sa_handler == SIG_DFL || now.sa_handler == SIG_IGN) return;
    host_sigint = now;
    wrapper = now;
    wrapper.sa_sigaction = deferring_handler;
    wrapper.sa_flags = (now.sa_flags | SA_SIGINFO) & ~SA_RESETHAND;
    sigaction(SIGINT, &wrapper, NULL);
}

void sbf_call_begin(void)
{
    if (on_main_thread < 0) on_main_thread = syscall(SYS_gettid) == getpid();
    if (!on_main_thread) return;
    main_in_model = main_in_model + 1;
    atomic_signal_fence(memory_order_seq_cst);
    if (sigint_passed_on && py.PyOS_InterruptOccurred) { /* take back what Python has not acted on yet */
        sigint_passed_on = 0;
        int gil = py.PyGILState_Ensure();
        if (py.PyOS_InterruptOccurred()) sigint_deferred = 1;
        py.PyGILState_Release(gil);
    }
}

void sbf_call_end(void)
{
    if (on_main_thread != 1) return;
    atomic_signal_fence(memory_order_seq_cst);
    main_in_model = main_in_model - 1;
    atomic_signal_fence(memory_order_seq_cst);
    if (main_in_model == 0 && sigint_deferred) {
        sigint_deferred = 0;
        raise(SIGINT);
    }
}

/* ---- host threads' Python thread states ----
 * A host thread without a Python thread state gets one on its first call, kept for its life: PyGILState_Ensure
 * makes it (and takes the GIL), PyEval_SaveThread gives the GIL back and leaves the state's count at 1, so the
 * inner library's per-call Ensure/Release neither make nor delete one. When the thread ends, delete_thread_state
 * (the destructor of owned_state_key, which holds the state) deletes it: a host that calls from a new thread each
 * time keeps no state per call (about 4.4 kB each). It does so directly, not through PyGILState_Release: glibc
 * clears every thread-specific value of the thread, Python's own record of the thread's state among them,
 * before or while it calls the destructors. A thread that has a state of its own (the Python threads of a
 * Python host) keeps it untouched. */
static pthread_key_t owned_state_key;
static pthread_once_t owned_state_once = PTHREAD_ONCE_INIT;

static void delete_thread_state(void *state)
{
    if (!py.Py_IsInitialized() || (py.Py_IsFinalizing && py.Py_IsFinalizing())) return; /* the interpreter goes */
    py.PyEval_RestoreThread(state); /* the GIL taken, the state current */
    py.PyThreadState_Clear(state);
    py.PyThreadState_DeleteCurrent(); /* and the GIL released */
}

static void create_owned_state_key(void) { pthread_key_create(&owned_state_key, delete_thread_state); }

void sbf_keep_thread_state(void)
{
    if (thread_has_state) return;
    thread_has_state = 1;
    if (py.PyGILState_GetThisThreadState()) return; /* the thread has a state of its own */
    pthread_once(&owned_state_once, create_owned_state_key);
    py.PyGILState_Ensure();
    pthread_setspecific(owned_state_key, py.PyEval_SaveThread()); /* release the GIL, keep the state */
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
    if (!*location) return snprintf(why, why_size, "is empty"), 0;
    if (location[0] == '/') {
        if (strlen(location) >= size) return snprintf(why, why_size, "is too long"), 0;
        strcpy(path, location);
        return 1;
    }
    if (strncasecmp(location, "file:", 5) != 0)
        return snprintf(why, why_size, "is neither a file URI (file:///path) nor an absolute path"), 0;
    const char *rest = location + 5;
    if (strncmp(rest, "//", 2) == 0) {
        const char *authority = rest + 2, *slash = strchr(authority, '/');
        size_t length = slash ? (size_t)(slash - authority) : strlen(authority);
        if (!slash) return snprintf(why, why_size, "has no path after its host"), 0;
        if (length && !(length == 9 && strncasecmp(authority, "localhost", 9) == 0))
            return snprintf(why, why_size, "names the host '%.*s': only local folders can be used (file:///path or "
                            "file://localhost/path)", (int)length, authority), 0;
        rest = slash;
    }
    if (rest[0] != '/') return snprintf(why, why_size, "is not an absolute file URI (file:///path)"), 0;
    return percent_decode(rest, path, size, why, why_size);
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
    char file[4096 + 64], module[256] = "";
    struct stat st;
    snprintf(file, sizeof file, "%s/slavemodule.txt", path);
    FILE *list = fopen(file, "r");
    if (list) {
        if (!fgets(module, sizeof module, list)) module[0] = '\0';
        fclose(list);
    }
    module[strcspn(module, "\r\n")] = '\0';
    if (!*module) return snprintf(why, why_size, "is not this FMU's resources folder: %s is missing or empty", file), 0;
    snprintf(file, sizeof file, "%s/%s.py", path, module);
    if (stat(file, &st) != 0 || !S_ISREG(st.st_mode))
        return snprintf(why, why_size, "is not this FMU's resources folder: %s is missing", file), 0;
    return 1;
}

/* The resources folder of `location` into `path`; 0 with a message naming the location and the cause in `why`. */
static int resource_folder(const char *location, char *path, size_t size, char *why, size_t why_size)
{
    char cause[4096 + 256];
    struct stat st;
    int ok = 0;
    if (!location)
        return snprintf(why, why_size, "the resource location is NULL"), 0;
    if (location_path(location, path, size, cause, sizeof cause)) {
        if (!is_utf8((const unsigned char *)path))
            snprintf(cause, sizeof cause, "names a folder whose path is not UTF-8 text, which Python cannot take");
        else if (stat(path, &st) != 0)
            snprintf(cause, sizeof cause, "names the folder %s, which does not exist (%s)", path, strerror(errno));
        else if (!S_ISDIR(st.st_mode))
            snprintf(cause, sizeof cause, "names %s, which is not a folder", path);
        else
            ok = holds_slave_module(path, cause, sizeof cause);
    }
    if (!ok) snprintf(why, why_size, "the resource location \"%s\" %s", location, cause);
    return ok;
}

/* Whether the inner library (PythonFMU 0.7.0, pythonfmu3 0.3.4) takes `path` as it is: both replace every "%20" in
 * the resource location by a space and then cut its first "file://" out (CppfmuInstantiateSlave). */
static int taken_as_is(const char *path) { return !strstr(path, "%20") && !strstr(path, "file://"); }

/* Descriptors of folders kept open for inner_library_path, one per folder, for the life of the process: Python's
 * import system keeps the path made from one in sys.path and reads modules through it later. */
static struct {
    pthread_mutex_t lock;
    size_t n;
    struct { dev_t device; ino_t inode; int fd; } kept[64];
} folder_fds = {.lock = PTHREAD_MUTEX_INITIALIZER};

/* An open descriptor of the folder `path` (one kept per folder), or -1 with errno set */
static int folder_fd(const char *path)
{
    struct stat st;
    int fd = -1;
    if (stat(path, &st) != 0) return -1;
    pthread_mutex_lock(&folder_fds.lock);
    for (size_t i = 0; i < folder_fds.n && fd < 0; ++i)
        if (folder_fds.kept[i].device == st.st_dev && folder_fds.kept[i].inode == st.st_ino) fd = folder_fds.kept[i].fd;
    if (fd < 0 && (fd = open(path, O_PATH | O_DIRECTORY | O_CLOEXEC)) >= 0 &&
        folder_fds.n < sizeof folder_fds.kept / sizeof *folder_fds.kept)
        folder_fds.kept[folder_fds.n++] = (typeof(folder_fds.kept[0])){st.st_dev, st.st_ino, fd};
    pthread_mutex_unlock(&folder_fds.lock);
    return fd;
}

/* The path the inner library is given for the resources folder `folder` (an absolute path), into `path`: `folder`
 * itself where the library takes it as it is, else the same folder reached through /proc/self/fd/N, N a descriptor
 * of its parent, kept open (the folder's own name after it, so that the slave finds the FMU's binaries beside it).
 * The slave then learns `folder` itself from the loader (sbf_bound_folder). 0 with the cause in `why` if neither. */
static int inner_library_path(const char *folder, char *path, size_t size, char *why, size_t why_size)
{
    if (taken_as_is(folder)) return snprintf(path, size, "%s", folder), 1;
    size_t end = strlen(folder), start;
    while (end > 1 && folder[end - 1] == '/') --end;
    for (start = end; start > 0 && folder[start - 1] != '/';) --start;
    char parent[4096];
    snprintf(parent, sizeof parent, "%.*s", (int)(start ? start : 1), folder);
    int fd = folder_fd(parent);
    if (fd >= 0) snprintf(path, size, "/proc/self/fd/%d/%s", fd, folder + start);
    if (fd >= 0 && taken_as_is(path)) return 1;
    snprintf(why, why_size, "the resources folder %s cannot be handed to the FMU's library, which rewrites '%%20' and "
             "'file://' in it (%s): move the FMU to a folder whose name has neither", folder,
             fd < 0 ? strerror(errno) : "so does the folder's own name");
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

int sbf_step_refused(sbf_mode mode, const char *function, double t, char *why, size_t why_size)
{
    static const char *const refusal[] = {
        [SBF_INSTANTIATED] = "before initialization (enter and exit initialization mode first)",
        [SBF_INITIALIZING] = "during initialization (exiting initialization mode has not succeeded)",
        [SBF_STEPPING] = NULL,
        [SBF_TERMINATED] = "after termination (reset the instance to start again)",
        [SBF_EXCHANGING] = "for a model-exchange instance",
        [SBF_EVENT] = "in Event Mode (call fmi3EnterStepMode first)"};
    if (!refusal[mode]) return 0;
    snprintf(why, why_size, "%s at t = %g s is not allowed %s", function, t, refusal[mode]);
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
