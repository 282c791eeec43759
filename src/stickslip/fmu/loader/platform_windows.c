/* platform.h for Windows (x86_64, MinGW-w64): LoadLibraryExW and GetProcAddress, module handles, a named mutex per
 * process, a console control handler for Ctrl-C, fiber-local storage for thread-exit callbacks, and paths handed to
 * the system as UTF-16. */
#define WIN32_LEAN_AND_MEAN
#define UNICODE
#include "platform.h"

#include "carried.h"

#include <windows.h>
#include <psapi.h>
#include <tlhelp32.h>

#include <ctype.h>
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <wchar.h>

#define WIDE_PATH 32768 /* the longest path Windows takes, in UTF-16 units */
/* The longest folder path (UTF-16 units) handed as it is to programs that are not long-path aware (CPython's path
 * calculation, the FMI library's DLL), which take paths below MAX_PATH (260): room is left for the FMU's own names
 * below the folder (the longest, in resources/, has about 70 characters). A longer one is handed in its short
 * (8.3) form. */
#define LONG_PATH (MAX_PATH - 100)

static SBF_THREAD_LOCAL char library_error[512];

/* `text` (UTF-8) as UTF-16 in memory of the caller's (free it), or NULL if it is not UTF-8. Every path is converted
 * into memory of its own call: two threads instantiating at once made each other's checks fail through a shared
 * buffer ("... is missing", "... which is not a folder"). */
static wchar_t *to_wide(const char *text)
{
    int n = MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, text, -1, NULL, 0);
    wchar_t *wide = n > 0 ? malloc((size_t)n * sizeof *wide) : NULL;
    if (wide && MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, text, -1, wide, n) != n) {
        free(wide);
        wide = NULL;
    }
    return wide;
}

/* The length of `text` (UTF-8) in UTF-16 units, as Windows counts a path's length */
static size_t wide_length(const char *text)
{
    int n = MultiByteToWideChar(CP_UTF8, 0, text, -1, NULL, 0);
    return n > 0 ? (size_t)n - 1 : strlen(text);
}

/* `wide` (UTF-16) as UTF-8 into `text`; 0 if it does not fit */
static int from_wide(const wchar_t *wide, char *text, size_t size)
{
    return WideCharToMultiByte(CP_UTF8, 0, wide, -1, text, (int)size, NULL, NULL) > 0;
}

/* The system's text of the error `code` into library_error */
static void note_error(DWORD code)
{
    wchar_t text[256];
    char utf8[512];
    DWORD n = FormatMessageW(FORMAT_MESSAGE_FROM_SYSTEM | FORMAT_MESSAGE_IGNORE_INSERTS, NULL, code, 0, text,
                             sizeof text / sizeof *text, NULL);
    while (n > 0 && (text[n - 1] == L'\r' || text[n - 1] == L'\n' || text[n - 1] == L'.')) text[--n] = L'\0';
    if (n == 0 || !from_wide(text, utf8, sizeof utf8)) snprintf(utf8, sizeof utf8, "error");
    snprintf(library_error, sizeof library_error, "%s (Windows error %lu)", utf8, (unsigned long)code);
}

/* ---- libraries ---- */

/* A path with a folder is loaded with its own folder searched first for the libraries it needs (the CPython
 * library's vcruntime140.dll, say); a bare name is searched as Windows searches for any library. */
void *sbf_open_library(const char *path, int global)
{
    (void)global; /* a Windows library's symbols are looked up in it, never in a global scope */
    wchar_t *wide = to_wide(path);
    if (!wide) {
        snprintf(library_error, sizeof library_error, "the path is not UTF-8 text");
        return NULL;
    }
    int has_folder = wcschr(wide, L'\\') || wcschr(wide, L'/');
    HMODULE library = LoadLibraryExW(wide, NULL, has_folder ? LOAD_WITH_ALTERED_SEARCH_PATH : 0);
    if (!library) note_error(GetLastError());
    free(wide);
    return library;
}

void *sbf_symbol(void *library, const char *name)
{
    void *symbol = (void *)GetProcAddress((HMODULE)library, name);
    if (!symbol) note_error(GetLastError());
    return symbol;
}

const char *sbf_library_error(void) { return *library_error ? library_error : "unknown error"; }

/* Whether `name` is the file name of a CPython library (python3XY.dll, not the forwarder python3.dll) */
static int is_python_library(const wchar_t *name)
{
    size_t n = wcslen(name);
    return n > 11 && _wcsnicmp(name, L"python3", 7) == 0 && _wcsicmp(name + n - 4, L".dll") == 0 &&
           iswdigit(name[7]) && !_wcsnicmp(name + n - 6, L"_d.dll", 6) == 0;
}

int sbf_unusable_stdio(char *why, size_t why_size)
{
    static const DWORD streams[] = {STD_INPUT_HANDLE, STD_OUTPUT_HANDLE, STD_ERROR_HANDLE};
    static const char *const names[] = {"input", "output", "error"};
    BY_HANDLE_FILE_INFORMATION info;
    for (int i = 0; i < 3; ++i) {
        HANDLE handle = GetStdHandle(streams[i]);
        if (!handle || handle == INVALID_HANDLE_VALUE || GetFileType(handle) != FILE_TYPE_DISK ||
            GetFileInformationByHandle(handle, &info))
            continue;
        note_error(GetLastError());
        snprintf(why, why_size, "The host's standard %s is a file that the system cannot describe "
                 "(GetFileInformationByHandle: %s; Wine 8.0 does this), and CPython 3.12 and newer cannot start with "
                 "it: run the host with its standard input, output and error on a console, a pipe or NUL",
                 names[i], library_error);
        return 1;
    }
    return 0;
}

int sbf_process_python(void **library)
{
    HMODULE modules[1024];
    DWORD bytes = 0;
    wchar_t name[MAX_PATH];
    if (!K32EnumProcessModules(GetCurrentProcess(), modules, sizeof modules, &bytes)) return 0;
    for (size_t i = 0; i < bytes / sizeof *modules && i < sizeof modules / sizeof *modules; ++i)
        if (K32GetModuleBaseNameW(GetCurrentProcess(), modules[i], name, MAX_PATH) && is_python_library(name) &&
            GetProcAddress(modules[i], "Py_IsInitialized")) {
            *library = modules[i];
            return 1;
        }
    return 0;
}

/* The path (UTF-8) of the module holding `address` into `path`; 0 if there is none */
static int module_path(const void *address, char *path, size_t size)
{
    HMODULE module;
    if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCWSTR)address, &module))
        return 0;
    wchar_t *wide = malloc(2 * WIDE_PATH * sizeof *wide), *short_path = wide + WIDE_PATH;
    DWORD n = wide ? GetModuleFileNameW(module, wide, WIDE_PATH) : 0, m = 0;
    if (n >= LONG_PATH && n < WIDE_PATH) /* CPython starts from its DLL's path, as loaded: the short one */
        m = GetShortPathNameW(wide, short_path, WIDE_PATH);
    int found = n > 0 && n < WIDE_PATH && from_wide(m > 0 && m < n ? short_path : wide, path, size);
    free(wide);
    return found;
}

int sbf_loader_path(char *path, size_t size) { return module_path((const void *)&sbf_loader_path, path, size); }

int sbf_pin_loader(char *why, size_t why_size)
{
    HMODULE module;
    if (GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_PIN,
                           (LPCWSTR)(const void *)&sbf_pin_loader, &module))
        return 1;
    note_error(GetLastError());
    snprintf(why, why_size, "%s", library_error);
    return 0;
}

/* The inner library's DLL_PROCESS_DETACH destroys its Python start-up object once, and comes before the loader's
 * (Windows detaches the libraries in the reverse of the order they were loaded in): an exit handler of the loader's
 * runs at the loader's detach, and resetting the object there decremented the freed object's count (a write into
 * freed memory: Wine's heap check found the block overwritten). So nothing is done. */
void sbf_reset_inner_at_exit(void *library, const char *path, const char *reset)
{
    (void)library, (void)path, (void)reset;
}

/* The length of the folder part of `path` (with its last separator) */
static size_t folder_length(const char *path)
{
    const char *slash = strrchr(path, '/'), *backslash = strrchr(path, '\\');
    if (backslash > slash) slash = backslash;
    return slash ? (size_t)(slash - path + 1) : 0;
}

#ifndef SBF_BUNDLED_LIBPYTHON
#define SBF_BUNDLED_LIBPYTHON ""
#endif

/* The path of the python3.dll that the FMU carries beside its own CPython library (SBF_BUNDLED_LIBPYTHON, a path
 * below its "python" folder, unpacked where needed: carried.c) into `path`, if that library has the file name of the CPython library `python_path` (the
 * forwarder names the library of its version, which is then the one already loaded); 0 if not. */
static int bundled_forwarder(const char *python_path, char *path, size_t size)
{
    char relative[4096], why[4096];
    const char *bundled = SBF_BUNDLED_LIBPYTHON, *name = python_path + folder_length(python_path);
    size_t bundled_folder = folder_length(bundled);
    if (!*bundled || _stricmp(bundled + bundled_folder, name) != 0) return 0;
    snprintf(relative, sizeof relative, "%.*spython3.dll", (int)bundled_folder, bundled);
    return sbf_carried_path(relative, path, size, why, sizeof why);
}

int sbf_bind_inner_to_python(void *python, char *why, size_t why_size)
{
    char path[4096], python_path[4096], carried[4096];
    if (GetModuleHandleW(L"python3.dll")) return 1;
    if (!module_path((const void *)GetProcAddress((HMODULE)python, "Py_IsInitialized"), python_path,
                     sizeof python_path))
        return snprintf(why, why_size, "cannot locate the CPython library"), 0;
    snprintf(path, sizeof path, "%.*spython3.dll", (int)folder_length(python_path), python_path);
    if (sbf_open_library(path, 0)) return 1;
    int found = snprintf(why, why_size, "it needs python3.dll, which is not beside the CPython library (%s: %s)",
                         path, library_error);
    if (!bundled_forwarder(python_path, carried, sizeof carried)) return 0;
    if (sbf_open_library(carried, 0)) return 1;
    snprintf(why + found, why_size - (size_t)found, ", nor loads from the FMU (%s: %s)", carried, library_error);
    return 0;
}

/* python.exe in the CPython library's folder (the layout of python.org's installers and embeddable packages) */
void sbf_python_program_name(void *python_function, char *name, size_t size)
{
    char path[4096];
    if (!module_path(python_function, path, sizeof path)) {
        snprintf(name, size, "python.exe");
        return;
    }
    snprintf(name, size, "%.*spython.exe", (int)folder_length(path), path);
}

static SRWLOCK loader_lock = SRWLOCK_INIT;

void sbf_loader_lock(void) { AcquireSRWLockExclusive(&loader_lock); }

void sbf_loader_unlock(void) { ReleaseSRWLockExclusive(&loader_lock); }

/* ---- the process-wide start lock: a mutex named after the process, which every loader copy opens ---- */
static HANDLE process_lock;

int sbf_process_lock(char *why, size_t why_size)
{
    if (!process_lock) {
        wchar_t name[64];
        swprintf(name, sizeof name / sizeof *name, L"Local\\sbf_python_start_lock.%lu",
                 (unsigned long)GetCurrentProcessId());
        process_lock = CreateMutexW(NULL, FALSE, name);
        if (!process_lock) {
            note_error(GetLastError());
            return snprintf(why, why_size, "cannot create the process's start lock: %s", library_error), 0;
        }
    }
    if (WaitForSingleObject(process_lock, INFINITE) == WAIT_FAILED) {
        note_error(GetLastError());
        return snprintf(why, why_size, "cannot take the process's start lock: %s", library_error), 0;
    }
    return 1;
}

void sbf_process_unlock(void) { ReleaseMutex(process_lock); }

/* ---- the host's SIGINT handler: CPython's C runtime's (the UCRT's for python.org's builds, not this library's
 * msvcrt), reached through CPython's PyOS_getsig and PyOS_setsig ---- */
typedef void (*sigint_handler)(int);
static sigint_handler (*python_getsig)(int), (*python_setsig)(int, sigint_handler);
static sigint_handler host_sigint = SIG_ERR;

/* PyOS_getsig and PyOS_setsig of the CPython library `python` (NULL where it lacks them) */
static void resolve_python_signals(void *python)
{
    *(void **)&python_getsig = sbf_symbol(python, "PyOS_getsig");
    *(void **)&python_setsig = sbf_symbol(python, "PyOS_setsig");
}

void sbf_save_host_signals(void *python)
{
    resolve_python_signals(python);
    host_sigint = python_getsig ? python_getsig(SIGINT) : SIG_ERR;
}

void sbf_restore_host_signals(void)
{
    if (python_setsig && host_sigint != SIG_ERR) python_setsig(SIGINT, host_sigint);
}

/* ---- Ctrl-C during a call into the model ----
 * Windows hands Ctrl-C (and GenerateConsoleCtrlEvent's CTRL_C_EVENT; Wine turns a SIGINT into one) to a process on a
 * new thread, which runs the console control handlers, the last registered first. The C runtime's, registered when
 * CPython set its SIGINT handler, calls that handler, and Python raises KeyboardInterrupt in the main thread at its
 * next Python instruction: while that thread is inside a call into the model, an instruction of the slave's, which
 * the inner library then reports as the slave's failure ("[doStep] KeyboardInterrupt()"). So once Python is ready,
 * the first loader copy in the process registers a handler of its own, which runs before the C runtime's, and
 * reports every Ctrl-C handled: while the main thread (the process's oldest) is inside a call into any copy's model,
 * it only notes it, and the end of that call hands it to CPython's SIGINT handler on the main thread, so that the
 * host gets it when the call returns. Otherwise it hands it on itself, on its own thread; a call that the main
 * thread begins meanwhile waits until it has, then takes it back from Python if Python has not acted on it yet
 * (PyOS_InterruptOccurred) and defers it too. Where CPython's SIGINT handler is the default or ignores it (a host
 * that is not Python keeps its own, the default), the event goes on to the next handler, as without the FMU. The
 * state is one word in memory that every loader copy in the process shares (named after the process, as the start
 * lock is); a call's state changes are two interlocked additions on the main thread, and a thread-local read on
 * the others. */
#define IN_CALL 0x100     /* per call of the main thread into a model */
#define HANDING 0x2       /* per Ctrl-C being handed to Python on the console's thread */
#define HANDING_MASK 0xFE
#define DEFERRED 0x1      /* a Ctrl-C waits for the main thread's calls to end */
static struct {
    volatile LONG state;  /* IN_CALL, HANDING and DEFERRED, added up */
    volatile LONG handed; /* a Ctrl-C was handed to Python since the main thread last took one back */
} *interrupts;            /* NULL until sbf_defer_interrupts */
static DWORD main_thread;
static SBF_THREAD_LOCAL int on_main_thread = -1; /* -1 not known yet */

/* CPython's SIGINT handler, NULL where it is the default or ignores the signal */
static sigint_handler python_sigint(void)
{
    sigint_handler handler = python_getsig ? python_getsig(SIGINT) : SIG_DFL;
    return handler == SIG_DFL || handler == SIG_IGN || handler == SIG_ERR ? NULL : handler;
}

static BOOL WINAPI on_console_event(DWORD event)
{
    sigint_handler handler = event == CTRL_C_EVENT ? python_sigint() : NULL;
    if (!handler) return FALSE;
    LONG state = interrupts->state, seen;
    for (;; state = seen) {
        LONG next = state >= IN_CALL ? state | DEFERRED : state + HANDING;
        if ((seen = InterlockedCompareExchange(&interrupts->state, next, state)) == state) break;
    }
    if (state >= IN_CALL) return TRUE; /* the main thread's call hands it on when it ends */
    handler(SIGINT);
    InterlockedExchange(&interrupts->handed, 1);
    InterlockedExchangeAdd(&interrupts->state, -HANDING);
    return TRUE;
}

/* The id of the process's oldest thread, its main one (0 if it cannot be had) */
static DWORD oldest_thread(void)
{
    DWORD oldest = 0;
    ULONGLONG oldest_start = ~0ULL;
    HANDLE snapshot = CreateToolhelp32Snapshot(TH32CS_SNAPTHREAD, 0);
    THREADENTRY32 entry = {.dwSize = sizeof entry};
    for (BOOL more = snapshot != INVALID_HANDLE_VALUE && Thread32First(snapshot, &entry); more;
         more = Thread32Next(snapshot, &entry)) {
        HANDLE thread = entry.th32OwnerProcessID == GetCurrentProcessId()
                            ? OpenThread(THREAD_QUERY_LIMITED_INFORMATION, FALSE, entry.th32ThreadID) : NULL;
        FILETIME start, end, kernel, user;
        if (thread && GetThreadTimes(thread, &start, &end, &kernel, &user) &&
            ((ULONGLONG)start.dwHighDateTime << 32 | start.dwLowDateTime) < oldest_start) {
            oldest_start = (ULONGLONG)start.dwHighDateTime << 32 | start.dwLowDateTime;
            oldest = entry.th32ThreadID;
        }
        if (thread) CloseHandle(thread);
    }
    if (snapshot != INVALID_HANDLE_VALUE) CloseHandle(snapshot);
    return oldest;
}

void sbf_defer_interrupts(void *python)
{
    wchar_t name[64];
    resolve_python_signals(python);
    if (!python_getsig) return;
    python_sigint(); /* the C runtime registers its console handler when first asked: before this library's */
    swprintf(name, sizeof name / sizeof *name, L"Local\\sbf_interrupts.%lu", (unsigned long)GetCurrentProcessId());
    HANDLE shared = CreateFileMappingW(INVALID_HANDLE_VALUE, NULL, PAGE_READWRITE, 0, sizeof *interrupts, name);
    int first = shared && GetLastError() != ERROR_ALREADY_EXISTS;
    void *state = shared ? MapViewOfFile(shared, FILE_MAP_ALL_ACCESS, 0, 0, sizeof *interrupts) : NULL;
    if (!state) return;
    main_thread = oldest_thread();
    interrupts = state;
    if (first) SetConsoleCtrlHandler(on_console_event, TRUE);
}

void sbf_interrupts_begin(int (*interrupt_pending)(void))
{
    if (!interrupts) return;
    if (on_main_thread < 0) on_main_thread = GetCurrentThreadId() == main_thread;
    if (!on_main_thread) return;
    if (InterlockedExchangeAdd(&interrupts->state, IN_CALL) & HANDING_MASK)
        while (interrupts->state & HANDING_MASK) SwitchToThread(); /* until Python has it, to take it back */
    if (interrupts->handed && InterlockedExchange(&interrupts->handed, 0) && interrupt_pending && interrupt_pending())
        InterlockedOr(&interrupts->state, DEFERRED);
}

void sbf_interrupts_end(void)
{
    if (on_main_thread != 1) return;
    LONG state = InterlockedExchangeAdd(&interrupts->state, -IN_CALL) - IN_CALL, seen;
    for (; state < IN_CALL && (state & DEFERRED); state = seen)
        if ((seen = InterlockedCompareExchange(&interrupts->state, state & ~DEFERRED, state)) == state) {
            sigint_handler handler = python_sigint();
            if (handler) handler(SIGINT);
            return;
        }
}

/* ---- threads: a fiber-local slot whose callback runs when the thread ends ---- */
static DWORD exit_slot = FLS_OUT_OF_INDEXES;
static void (*exit_destructor)(void *);
static INIT_ONCE exit_slot_once = INIT_ONCE_STATIC_INIT;

static void WINAPI run_exit_destructor(void *value)
{
    if (value) exit_destructor(value);
}

static BOOL CALLBACK create_exit_slot(INIT_ONCE *once, void *parameter, void **context)
{
    (void)once, (void)parameter, (void)context;
    exit_slot = FlsAlloc(run_exit_destructor);
    return TRUE;
}

void sbf_at_thread_exit(void (*destructor)(void *), void *value)
{
    exit_destructor = destructor;
    InitOnceExecuteOnce(&exit_slot_once, create_exit_slot, NULL, NULL);
    if (exit_slot != FLS_OUT_OF_INDEXES) FlsSetValue(exit_slot, value);
}

/* ---- paths ---- */

static int has_drive(const char *path) { return isalpha((unsigned char)path[0]) && (path[1] == ':' || path[1] == '|'); }

int sbf_is_absolute_path(const char *location)
{
    return (has_drive(location) && location[1] == ':' && (location[2] == '\\' || location[2] == '/')) ||
           ((location[0] == '\\' || location[0] == '/') && (location[1] == '\\' || location[1] == '/'));
}

/* file:///C:/x and file://localhost/C:/x: C:\x; file://host/share/x and file:////host/share/x: \\host\share\x */
int sbf_uri_path(const char *host, size_t host_length, const char *uri_path, char *path, size_t size, char *why,
                 size_t why_size)
{
    int local = host_length == 0 || (host_length == 9 && _strnicmp(host, "localhost", 9) == 0);
    int written;
    if (local && has_drive(uri_path + 1) && (uri_path[3] == '/' || uri_path[3] == '\0'))
        written = snprintf(path, size, "%c:%s", uri_path[1], uri_path[3] ? uri_path + 3 : "/");
    else if (local && uri_path[1] == '/')
        written = snprintf(path, size, "%s", uri_path); /* file:////host/share: the UNC path in the URI's path */
    else if (!local)
        written = snprintf(path, size, "//%.*s%s", (int)host_length, host, uri_path);
    else
        return snprintf(why, why_size, "names no drive: a local file URI on Windows is file:///C:/path"), 0;
    if (written < 0 || (size_t)written >= size) return snprintf(why, why_size, "is too long"), 0;
    for (char *c = path; *c; ++c)
        if (*c == '/') *c = '\\';
    return 1;
}

int sbf_path_kind(const char *path, char *why, size_t why_size)
{
    struct _stat64 st;
    wchar_t *wide = to_wide(path);
    if (!wide) return snprintf(why, why_size, "the path is not UTF-8 text"), 0;
    size_t n = wcslen(wide); /* _wstat64 finds no folder whose name ends with a separator, save a drive's root */
    while (n > 3 && (wide[n - 1] == L'\\' || wide[n - 1] == L'/')) wide[--n] = L'\0';
    int found = _wstat64(wide, &st) == 0;
    free(wide);
    if (!found) return snprintf(why, why_size, "%s", strerror(errno)), 0;
    return (st.st_mode & S_IFMT) == S_IFDIR ? 1 : (st.st_mode & S_IFMT) == S_IFREG ? 2 : 3;
}

FILE *sbf_open_text(const char *path)
{
    wchar_t *wide = to_wide(path);
    FILE *file = wide ? _wfopen(wide, L"r") : NULL;
    free(wide);
    return file;
}

const char *sbf_library_cannot_open(const char *path)
{
    for (const unsigned char *c = (const unsigned char *)path; *c; ++c)
        if (*c >= 0x80) return "its path is not ASCII";
    return wide_length(path) < LONG_PATH ? NULL : "its path is too long";
}

int sbf_path_fits(const char *path, char *why, size_t why_size)
{
    if (wide_length(path) < LONG_PATH) return 1;
    snprintf(why, why_size, "its path has %zu characters, and the programs it runs that are not long-path aware (the "
             "CPython it carries, the FMI library) take at most %d there (Windows' MAX_PATH of %d, less the FMU's own "
             "file names below it); the volume has no short (8.3) name for it either: extract the FMU to a folder "
             "with a shorter path (e.g. C:\\fmus\\<name>)", wide_length(path), LONG_PATH - 1, MAX_PATH);
    return 0;
}

void sbf_plain_path(char *path)
{
    if (strncmp(path, "\\\\?\\UNC\\", 8) == 0)
        memmove(path + 2, path + 8, strlen(path + 8) + 1); /* \\?\UNC\host\share: \\host\share */
    else if (strncmp(path, "\\\\?\\", 4) == 0 && has_drive(path + 4))
        memmove(path, path + 4, strlen(path + 4) + 1); /* \\?\C:\x: C:\x */
}

/* The folder's short (8.3) path, where the volume keeps short names (ASCII names) */
int sbf_folder_alias(const char *folder, char *path, size_t size, char *why, size_t why_size)
{
    wchar_t *wide = to_wide(folder), *short_path = malloc(WIDE_PATH * sizeof *short_path);
    DWORD n = wide && short_path ? GetShortPathNameW(wide, short_path, WIDE_PATH) : 0;
    int found = n > 0 && n < WIDE_PATH && from_wide(short_path, path, size) && !strstr(path, "%20") &&
                !strstr(path, "file://") && !sbf_library_cannot_open(path);
    free(wide);
    free(short_path);
    if (found) return 1;
    snprintf(why, why_size, "its volume has no short name for it");
    return 0;
}

/* ---- files and folders ---- */

/* The system's text of the last error into `why` */
static void last_error(char *why, size_t why_size)
{
    note_error(GetLastError());
    snprintf(why, why_size, "%s", library_error);
}

long long sbf_file_size(const char *path)
{
    WIN32_FILE_ATTRIBUTE_DATA data;
    wchar_t *wide = to_wide(path);
    BOOL found = wide && GetFileAttributesExW(wide, GetFileExInfoStandard, &data);
    free(wide);
    if (!found || (data.dwFileAttributes & FILE_ATTRIBUTE_DIRECTORY)) return -1;
    return ((long long)data.nFileSizeHigh << 32) | data.nFileSizeLow;
}

unsigned char *sbf_read_file(const char *path, size_t *size, char *why, size_t why_size)
{
    wchar_t *wide = to_wide(path);
    HANDLE file = wide ? CreateFileW(wide, GENERIC_READ, FILE_SHARE_READ, NULL, OPEN_EXISTING, 0, NULL)
                       : INVALID_HANDLE_VALUE;
    free(wide);
    LARGE_INTEGER length;
    unsigned char *data = NULL;
    DWORD got = 0;
    if (file != INVALID_HANDLE_VALUE && GetFileSizeEx(file, &length) && length.QuadPart < 0x7FFFFFFF &&
        (data = malloc((size_t)length.QuadPart + 1)) && ReadFile(file, data, (DWORD)length.QuadPart, &got, NULL) &&
        got == (DWORD)length.QuadPart)
        *size = got;
    else {
        last_error(why, why_size);
        free(data);
        data = NULL;
    }
    if (file != INVALID_HANDLE_VALUE) CloseHandle(file);
    return data;
}

int sbf_write_file(const char *path, const void *data, size_t n, char *why, size_t why_size)
{
    wchar_t *wide = to_wide(path);
    HANDLE file = wide ? CreateFileW(wide, GENERIC_WRITE, 0, NULL, CREATE_NEW, FILE_ATTRIBUTE_NORMAL, NULL)
                       : INVALID_HANDLE_VALUE;
    free(wide);
    DWORD written = 0;
    int ok = file != INVALID_HANDLE_VALUE && WriteFile(file, data, (DWORD)n, &written, NULL) && written == n;
    if (!ok) last_error(why, why_size);
    if (file != INVALID_HANDLE_VALUE && !CloseHandle(file) && ok) ok = 0, last_error(why, why_size);
    return ok;
}

int sbf_make_folder(const char *path, char *why, size_t why_size)
{
    wchar_t *wide = to_wide(path);
    BOOL made = wide && CreateDirectoryW(wide, NULL);
    DWORD code = GetLastError(), attributes = wide ? GetFileAttributesW(wide) : INVALID_FILE_ATTRIBUTES;
    free(wide);
    if (made || (attributes != INVALID_FILE_ATTRIBUTES && (attributes & FILE_ATTRIBUTE_DIRECTORY))) return 1;
    note_error(code);
    snprintf(why, why_size, "%s", library_error);
    return 0;
}

void sbf_remove(const char *path)
{
    wchar_t *wide = to_wide(path);
    if (wide && !DeleteFileW(wide)) RemoveDirectoryW(wide);
    free(wide);
}

int sbf_rename_folder(const char *from, const char *to, char *why, size_t why_size)
{
    wchar_t *wide_from = to_wide(from), *wide_to = to_wide(to);
    BOOL moved = wide_from && wide_to && MoveFileExW(wide_from, wide_to, 0);
    DWORD code = GetLastError(), attributes = wide_to ? GetFileAttributesW(wide_to) : INVALID_FILE_ATTRIBUTES;
    free(wide_from);
    free(wide_to);
    if (moved) return 1;
    if (attributes != INVALID_FILE_ATTRIBUTES) return 0;
    note_error(code);
    snprintf(why, why_size, "%s", library_error);
    return -1;
}

int sbf_cache_root(char *path, size_t size)
{
    const wchar_t *local = _wgetenv(L"LOCALAPPDATA");
    char utf8[4096];
    if (!local || !*local || !from_wide(local, utf8, sizeof utf8)) return 0;
    int n = snprintf(path, size, "%s\\stickslip\\python", utf8);
    return n > 0 && (size_t)n < size;
}

const char *sbf_unique_name(int counter)
{
    static SBF_THREAD_LOCAL char name[64];
    snprintf(name, sizeof name, "%lu-%lu-%d", (unsigned long)GetCurrentProcessId(),
             (unsigned long)GetCurrentThreadId(), counter);
    return name;
}
