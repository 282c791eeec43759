/* What differs between the operating systems the loader runs on, behind one interface: loading a library and
 * finding its symbols, the path of the loader's own binary, file-system paths and the resource location's file
 * URIs, thread-local storage and thread-exit callbacks, the process-wide lock under which CPython is started once,
 * the host's signal handlers, and Ctrl-C during a call into the model. platform_posix.c implements it for Linux
 * (glibc), platform_windows.c for Windows (x86_64, built with MinGW-w64); the rest of the loader is the same source
 * on both. Paths are UTF-8 text throughout; the Windows side hands them to the system as UTF-16. */
#ifndef SBF_PLATFORM_H
#define SBF_PLATFORM_H
#include <stddef.h>
#include <stdio.h>

#ifdef _WIN32
#define SBF_EXPORT __declspec(dllexport)
#else
#define SBF_EXPORT __attribute__((visibility("default")))
#endif
/* a variable of which each thread has its own copy */
#define SBF_THREAD_LOCAL _Thread_local

/* ---- libraries ---- */
/* Whether a library the FMU carries for its CPython is loaded only where the system has none by its file name
 * (Linux: the system's libffi, zlib... where present), or always from the FMU (Windows: the extension modules'
 * DLLs, which Windows would look for beside them) */
#ifdef _WIN32
#define SBF_SYSTEM_LIBRARIES_FIRST 0
#else
#define SBF_SYSTEM_LIBRARIES_FIRST 1
#endif
/* The library at `path` loaded (its symbols visible to libraries loaded later where `global`, as RTLD_GLOBAL), or
 * NULL with the system's reason in sbf_library_error(). */
void *sbf_open_library(const char *path, int global);
/* The symbol `name` of `library`, NULL if it has none. */
void *sbf_symbol(void *library, const char *name);
/* Why the last sbf_open_library or sbf_symbol of this thread failed */
const char *sbf_library_error(void);
/* 1 with why in `why` if a standard stream of the process is one CPython cannot start with (Windows under Wine 8.0: a
 * regular file, on whose handle GetFileInformationByHandle fails, so that CPython 3.12 and newer cannot create
 * sys.stdin/stdout/stderr: "init_sys_streams"), else 0 (Linux: always). */
int sbf_unusable_stdio(char *why, size_t why_size);
/* 1 with the CPython library already in this process (a Python host) in *library, else 0. */
int sbf_process_python(void **library);
/* Make the CPython library `python` (a handle as above) the one the inner library, loaded next, binds to; 0 with the
 * reason in `why`. (Linux: it binds through the global scope. Windows: PythonFMU's binaries import python3.dll, the
 * stable ABI's forwarder, which is loaded from beside `python` first, else the one the FMU carries beside its own
 * CPython library, where that has the file name of `python`.) */
int sbf_bind_inner_to_python(void *python, char *why, size_t why_size);
/* The path of the loader's own binary into `path` (Windows: its short form where the path is too long to hand to
 * programs that are not long-path aware and the volume has one); 0 if it cannot be found. */
int sbf_loader_path(char *path, size_t size);
/* Keep the loader's binary loaded until the process ends (see runtime.c, sbf_start); 0 with the reason in `why`. */
int sbf_pin_loader(char *why, size_t why_size);
/* Make the inner library (`library`, loaded from `path`) destroy its Python start-up object once at process exit,
 * given the name of its function that resets it (see runtime.c, the inner library's exit fault). Linux: that function
 * (in the file's full symbol table: it is not exported) is called by an exit handler registered now, which runs
 * before the library's destructors. Windows: nothing (the library's own detach destroys the object once). */
void sbf_reset_inner_at_exit(void *library, const char *path, const char *reset);
/* The program name CPython derives its prefix from, for the CPython library holding `python_function` (one of its
 * functions): the interpreter executable of that installation, so that the library and the standard library
 * found belong together. */
void sbf_python_program_name(void *python_function, char *name, size_t size);

/* ---- starting CPython once per process ---- */
/* Take and give back this loader copy's own lock (sbf_start's) */
void sbf_loader_lock(void);
void sbf_loader_unlock(void);
/* Take the lock that every copy of the loader in the process shares (every FMU with this loader ships its own
 * copy); 0 with the reason in `why` if it cannot be had. sbf_process_unlock gives it back. */
int sbf_process_lock(char *why, size_t why_size);
void sbf_process_unlock(void);
/* Around the start of the CPython library `python`: the host's handlers of the signals Python would take over are
 * saved, then restored (Windows: SIGINT's in that CPython's C runtime, through its PyOS_getsig and PyOS_setsig). */
void sbf_save_host_signals(void *python);
void sbf_restore_host_signals(void);
/* Once the CPython library `python` is ready (under the process lock): Ctrl-C during calls into the model reaches
 * the host after them (see sbf_call_begin in runtime.h). */
void sbf_defer_interrupts(void *python);
/* The interrupt bookkeeping of sbf_call_begin/sbf_call_end; `interrupt_pending` (may be NULL) tells whether Python
 * has noted an interrupt it has not acted on (it takes it back). */
void sbf_interrupts_begin(int (*interrupt_pending)(void));
void sbf_interrupts_end(void);

/* ---- threads ---- */
/* Call `destructor(value)` when the calling thread ends (once per thread; `value` not NULL). */
void sbf_at_thread_exit(void (*destructor)(void *), void *value);

/* ---- paths and resource locations ---- */
/* Whether `location` is an absolute path of the system (/x on Linux; C:\x, C:/x, \\host\share on Windows) */
int sbf_is_absolute_path(const char *location);
/* The path of a file URI whose authority is `host` (`host_length` bytes, 0 for file:/// or file:/x) and whose
 * percent-decoded path is `uri_path` (starting with '/') into `path`; 0 with the cause in `why`. */
int sbf_uri_path(const char *host, size_t host_length, const char *uri_path, char *path, size_t size, char *why,
                 size_t why_size);
/* What is at `path`: 1 a folder, 2 a regular file, 3 something else, 0 nothing (the system's reason in `why`). */
int sbf_path_kind(const char *path, char *why, size_t why_size);
/* The text file `path` opened for reading, or NULL. */
FILE *sbf_open_text(const char *path);
/* NULL if the FMI library's binary can open files under the folder `path` by that path, else why not (Linux: it
 * always can; Windows: if the path is ASCII, since PythonFMU's and pythonfmu3's DLLs open files through the ANSI
 * code page, and short enough for programs that are not long-path aware, see sbf_path_fits) */
const char *sbf_library_cannot_open(const char *path);
/* Whether the FMU's files below the folder `path` can be opened by that path by the programs the loader runs (Linux:
 * always; Windows: the path is below MAX_PATH less room for the FMU's own names), else 0 with why not and what to
 * do in `why`. */
int sbf_path_fits(const char *path, char *why, size_t why_size);
/* `path` (an absolute path) in its plain form, in place: Windows' \\?\C:\x and \\?\UNC\host\share\x as C:\x and
 * \\host\share\x (the same folder; the loader's checks and the FMI library take the plain form); Linux: as it is. */
void sbf_plain_path(char *path);
/* Another path to the folder `folder` that the FMI library's binary can open and that has neither "%20" nor "file://"
 * in it, into `path`; 0 with the cause in `why` if the system has none. */
int sbf_folder_alias(const char *folder, char *path, size_t size, char *why, size_t why_size);

/* ---- files and folders (the carried CPython's cache, carried.c) ---- */
#ifdef _WIN32
#define SBF_SEPARATOR '\\'
#else
#define SBF_SEPARATOR '/'
#endif
/* The size of the regular file `path` in bytes, -1 if there is none. */
long long sbf_file_size(const char *path);
/* The whole file `path` in memory of the caller's (free it), its size in *size; NULL with the system's reason. */
unsigned char *sbf_read_file(const char *path, size_t *size, char *why, size_t why_size);
/* Write `data` (`n` bytes) to the new file `path`; 0 with the system's reason (a full disk among them). */
int sbf_write_file(const char *path, const void *data, size_t n, char *why, size_t why_size);
/* Make the folder `path` (1 also if it exists); 0 with the system's reason. */
int sbf_make_folder(const char *path, char *why, size_t why_size);
/* Remove the file or empty folder `path`, if it can. */
void sbf_remove(const char *path);
/* Rename the folder `from` to `to`: 1 done, 0 `to` exists, -1 another failure (the system's reason in `why`). */
int sbf_rename_folder(const char *from, const char *to, char *why, size_t why_size);
/* The user's cache folder for the carried CPython into `path` (Linux: $XDG_CACHE_HOME/stickslip/python, else
 * $HOME/.cache/stickslip/python; Windows: %LOCALAPPDATA%\\stickslip\\python); 0 if the variables are not set. */
int sbf_cache_root(char *path, size_t size);
/* A name no other process or thread of the machine uses now: the process and thread ids and `counter` */
const char *sbf_unique_name(int counter);

#endif
