/* platform.h for Linux (glibc): dlopen and the dynamic linker's global scope, ELF symbol tables, POSIX threads and
 * signals, /proc/self/fd. */
#define _GNU_SOURCE
#include "platform.h"

#include <dlfcn.h>
#include <elf.h>
#include <errno.h>
#include <fcntl.h>
#include <link.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#ifndef SBF_START_GUARD
#error "define SBF_START_GUARD: the file name of the process-wide start guard library beside this library"
#endif

/* ---- libraries ---- */

void *sbf_open_library(const char *path, int global)
{
    return dlopen(path, RTLD_NOW | (global ? RTLD_GLOBAL : RTLD_LOCAL));
}

void *sbf_symbol(void *library, const char *name) { return dlsym(library, name); }

const char *sbf_library_error(void)
{
    const char *error = dlerror();
    return error ? error : "unknown error";
}

int sbf_unusable_stdio(char *why, size_t why_size)
{
    (void)why, (void)why_size;
    return 0;
}

int sbf_process_python(void **library)
{
    if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) return 0;
    *library = RTLD_DEFAULT;
    return 1;
}

int sbf_bind_inner_to_python(void *python, char *why, size_t why_size)
{
    (void)python, (void)why, (void)why_size;
    return 1;
}

int sbf_loader_path(char *path, size_t size)
{
    Dl_info self;
    if (!dladdr((void *)&sbf_loader_path, &self) || !self.dli_fname) return 0;
    snprintf(path, size, "%s", self.dli_fname);
    return 1;
}

/* The function `name` in the full symbol table (SHT_SYMTAB) of the ELF file `path`, loaded at `base`; NULL if
 * absent. PythonFMU does not export finalizePythonInterpreter (sbf_reset_inner_at_exit). */
static void *elf_function(const char *path, ElfW(Addr) base, const char *name)
{
    void *function = NULL;
    struct stat st;
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
                    function = (void *)(base + symbol->st_value);
                    break;
                }
        }
    }
    munmap((void *)file, size);
    return function;
}

/* The function `name` of `library` (loaded from `path`): its exported symbol, else its entry in the file's full
 * symbol table; NULL if neither. */
static void *find_function(void *library, const char *path, const char *name)
{
    void *function = dlsym(library, name);
    struct link_map *map;
    if (function || dlinfo(library, RTLD_DI_LINKMAP, &map) != 0) return function;
    return elf_function(path, map->l_addr, name);
}

/* The inner library's static destructor and its ELF destructor (which calls the reset) each destroy the object: the
 * exit handler registered here, after the library was loaded, runs before its static destructor (exit handlers run
 * last-in, first-out) and so before both, which then find nothing to destroy. */
static void (*inner_reset)(void);

static void reset_inner(void) { inner_reset(); }

void sbf_reset_inner_at_exit(void *library, const char *path, const char *reset)
{
    *(void **)&inner_reset = find_function(library, path, reset);
    if (inner_reset) atexit(reset_inner);
}

/* The loader pins itself with RTLD_NODELETE rather than being linked with -z nodelete: a host that loads it and
 * unloads it without instantiating (to read its functions, say) still unloads it, and the pin holds however the
 * library was linked. dlclose of the host's handle then only drops a reference. */
int sbf_pin_loader(char *why, size_t why_size)
{
    Dl_info self;
    if (dladdr((void *)&sbf_pin_loader, &self) && self.dli_fname &&
        dlopen(self.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE))
        return 1;
    snprintf(why, why_size, "%s", sbf_library_error());
    return 0;
}

/* <prefix>/bin/pythonX.Y of the library's installation if it exists, else a name in the library's folder; Python
 * then looks for its standard library upwards from there (the default, "python3" looked up in PATH, may find
 * another installation's). */
void sbf_python_program_name(void *python_function, char *name, size_t size)
{
    Dl_info library;
    if (!dladdr(python_function, &library) || !library.dli_fname) {
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

static pthread_mutex_t loader_lock = PTHREAD_MUTEX_INITIALIZER;

void sbf_loader_lock(void) { pthread_mutex_lock(&loader_lock); }

void sbf_loader_unlock(void) { pthread_mutex_unlock(&loader_lock); }

/* ---- the process-wide start lock ----
 * Every FMU built with this loader (the block's FMI 2 and FMI 3 FMUs, the coupling FMU, and each copy of them in
 * another folder) is a separate library with its own statics, so a lock of its own cannot keep two of them from
 * starting Python at once on two threads (which crashed the host). The lock is the symbol sbf_python_start_lock of
 * the tiny start guard library (start_guard.c) that every FMU ships beside its loader: each loader opens its own
 * copy with RTLD_GLOBAL (and RTLD_NODELETE), then looks the symbol up with dlsym(RTLD_DEFAULT), which searches the
 * global scope in load order and so answers every copy with the definition of the guard loaded first, for the life
 * of the process (dlopen and dlsym are serialized by the dynamic linker). The symbol's name is the guard's only
 * export. */
static pthread_mutex_t *process_lock;

int sbf_process_lock(char *why, size_t why_size)
{
    char path[4096];
    if (!process_lock) {
        if (!sbf_loader_path(path, sizeof path))
            return snprintf(why, why_size, "cannot locate the FMU's binaries folder"), 0;
        char *slash = strrchr(path, '/');
        snprintf(slash ? slash + 1 : path, sizeof path - (slash ? slash + 1 - path : 0), "%s", SBF_START_GUARD);
        if (!dlopen(path, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE))
            return snprintf(why, why_size, "cannot load the FMU's start guard %s: %s", path, dlerror()), 0;
        process_lock = dlsym(RTLD_DEFAULT, "sbf_python_start_lock");
        if (!process_lock)
            return snprintf(why, why_size, "the FMU's start guard %s lacks sbf_python_start_lock: %s", path,
                            dlerror()), 0;
    }
    pthread_mutex_lock(process_lock);
    return 1;
}

void sbf_process_unlock(void) { pthread_mutex_unlock(process_lock); }

static const int kept_signals[] = {SIGINT, SIGPIPE, SIGXFSZ};
#define N_KEPT (sizeof kept_signals / sizeof *kept_signals)
static struct sigaction host_handlers[N_KEPT];

void sbf_save_host_signals(void *python)
{
    (void)python;
    for (size_t i = 0; i < N_KEPT; ++i) sigaction(kept_signals[i], NULL, &host_handlers[i]);
}

void sbf_restore_host_signals(void)
{
    for (size_t i = 0; i < N_KEPT; ++i) sigaction(kept_signals[i], &host_handlers[i], NULL);
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
static SBF_THREAD_LOCAL int on_main_thread = -1; /* -1 not known yet */

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

void sbf_defer_interrupts(void *python)
{
    struct sigaction now, wrapper;
    (void)python;
    if (sigaction(SIGINT, NULL, &now) != 0) return;
    if (now.sa_flags & SA_SIGINFO ? !now.sa_sigaction : now.sa_handler == SIG_DFL || now.sa_handler == SIG_IGN) return;
    host_sigint = now;
    wrapper = now;
    wrapper.sa_sigaction = deferring_handler;
    wrapper.sa_flags = (now.sa_flags | SA_SIGINFO) & ~SA_RESETHAND;
    sigaction(SIGINT, &wrapper, NULL);
}

void sbf_interrupts_begin(int (*interrupt_pending)(void))
{
    if (on_main_thread < 0) on_main_thread = syscall(SYS_gettid) == getpid();
    if (!on_main_thread) return;
    main_in_model = main_in_model + 1;
    atomic_signal_fence(memory_order_seq_cst);
    if (sigint_passed_on && interrupt_pending) { /* take back what Python has not acted on yet */
        sigint_passed_on = 0;
        if (interrupt_pending()) sigint_deferred = 1;
    }
}

void sbf_interrupts_end(void)
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

/* ---- threads ---- */

static pthread_key_t exit_key;
static pthread_once_t exit_key_once = PTHREAD_ONCE_INIT;
static void (*exit_destructor)(void *);

static void run_exit_destructor(void *value) { exit_destructor(value); }

static void create_exit_key(void) { pthread_key_create(&exit_key, run_exit_destructor); }

void sbf_at_thread_exit(void (*destructor)(void *), void *value)
{
    exit_destructor = destructor;
    pthread_once(&exit_key_once, create_exit_key);
    pthread_setspecific(exit_key, value);
}

/* ---- paths ---- */

int sbf_is_absolute_path(const char *location) { return location[0] == '/'; }

int sbf_uri_path(const char *host, size_t host_length, const char *uri_path, char *path, size_t size, char *why,
                 size_t why_size)
{
    if (host_length && !(host_length == 9 && strncasecmp(host, "localhost", 9) == 0))
        return snprintf(why, why_size, "names the host '%.*s': only local folders can be used (file:///path or "
                        "file://localhost/path)", (int)host_length, host), 0;
    if (strlen(uri_path) >= size) return snprintf(why, why_size, "is too long"), 0;
    strcpy(path, uri_path);
    return 1;
}

int sbf_path_kind(const char *path, char *why, size_t why_size)
{
    struct stat st;
    if (stat(path, &st) != 0) return snprintf(why, why_size, "%s", strerror(errno)), 0;
    return S_ISDIR(st.st_mode) ? 1 : S_ISREG(st.st_mode) ? 2 : 3;
}

FILE *sbf_open_text(const char *path) { return fopen(path, "r"); }

const char *sbf_library_cannot_open(const char *path)
{
    (void)path;
    return NULL;
}

int sbf_path_fits(const char *path, char *why, size_t why_size)
{
    (void)path, (void)why, (void)why_size;
    return 1;
}

void sbf_plain_path(char *path) { (void)path; }

/* Descriptors of folders kept open for sbf_folder_alias, one per folder, for the life of the process: Python's
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

/* The same folder reached through /proc/self/fd/N, N a descriptor of its parent, kept open (the folder's own name
 * after it, so that the slave finds the FMU's binaries beside it). */
int sbf_folder_alias(const char *folder, char *path, size_t size, char *why, size_t why_size)
{
    size_t end = strlen(folder), start;
    while (end > 1 && folder[end - 1] == '/') --end;
    for (start = end; start > 0 && folder[start - 1] != '/';) --start;
    char parent[4096];
    snprintf(parent, sizeof parent, "%.*s", (int)(start ? start : 1), folder);
    int fd = folder_fd(parent);
    if (fd >= 0) snprintf(path, size, "/proc/self/fd/%d/%s", fd, folder + start);
    if (fd >= 0 && !strstr(path, "%20") && !strstr(path, "file://")) return 1;
    snprintf(why, why_size, "%s", fd < 0 ? strerror(errno) : "so does the folder's own name");
    return 0;
}

/* ---- files and folders ---- */

long long sbf_file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode) ? (long long)st.st_size : -1;
}

unsigned char *sbf_read_file(const char *path, size_t *size, char *why, size_t why_size)
{
    struct stat st;
    unsigned char *data = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd >= 0 && fstat(fd, &st) == 0 && (data = malloc((size_t)st.st_size + 1))) {
        size_t done = 0;
        for (ssize_t n; done < (size_t)st.st_size && (n = read(fd, data + done, (size_t)st.st_size - done)) > 0;)
            done += (size_t)n;
        if (done != (size_t)st.st_size) free(data), data = NULL, errno = EIO;
        *size = done;
    }
    if (!data) snprintf(why, why_size, "%s", strerror(errno));
    if (fd >= 0) close(fd);
    return data;
}

int sbf_write_file(const char *path, const void *data, size_t n, char *why, size_t why_size)
{
    errno = 0;
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    size_t done = 0;
    for (ssize_t k; fd >= 0 && done < n && (k = write(fd, (const char *)data + done, n - done)) > 0;) done += (size_t)k;
    int ok = fd >= 0 && done == n;
    if (fd >= 0 && close(fd) != 0) ok = 0;
    if (!ok) snprintf(why, why_size, "%s", strerror(errno ? errno : EIO));
    return ok;
}

int sbf_make_folder(const char *path, char *why, size_t why_size)
{
    struct stat st;
    if (mkdir(path, 0755) == 0 || (errno == EEXIST && stat(path, &st) == 0 && S_ISDIR(st.st_mode))) return 1;
    snprintf(why, why_size, "%s", strerror(errno));
    return 0;
}

void sbf_remove(const char *path) { remove(path); }

int sbf_rename_folder(const char *from, const char *to, char *why, size_t why_size)
{
    if (rename(from, to) == 0) return 1;
    if (errno == EEXIST || errno == ENOTEMPTY) return 0;
    snprintf(why, why_size, "%s", strerror(errno));
    return -1;
}

int sbf_cache_root(char *path, size_t size)
{
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    int n = xdg && *xdg ? snprintf(path, size, "%s/stickslip/python", xdg)
            : home && *home ? snprintf(path, size, "%s/.cache/stickslip/python", home) : -1;
    return n > 0 && (size_t)n < size;
}

const char *sbf_unique_name(int counter)
{
    static SBF_THREAD_LOCAL char name[64];
    snprintf(name, sizeof name, "%ld-%ld-%d", (long)getpid(), (long)syscall(SYS_gettid), counter);
    return name;
}
