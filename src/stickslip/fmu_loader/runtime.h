/* What both FMI fronts of the loader share: finding and starting CPython, loading the library they
 * forward to, Python thread states of host threads, and the filter of the host's log categories.
 * See runtime.c; the fronts are fmi2_front.c (PythonFMU) and fmi3_front.c (pythonfmu3). */
#ifndef SBF_RUNTIME_H
#define SBF_RUNTIME_H
#include <stddef.h>

/* Called once, under the start lock, with the inner library (dlopen'ed beside this one) and its path:
 * resolves the front's entry points; returns 0 after sbf_fail() if one is missing. */
typedef int (*sbf_resolve_inner)(void *library, const char *path);

/* Python and the inner library ready (once per process); 0 with sbf_start_error() saying why if not. */
int sbf_start(sbf_resolve_inner resolve);
const char *sbf_start_error(void);
void sbf_fail(const char *format, ...) __attribute__((format(printf, 1, 2)));

/* Give this host thread a Python thread state for its life (the inner library's per-call
 * PyGILState_Ensure/Release then only take and give back the GIL). */
void sbf_keep_thread_state(void);

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
/* Warnings, discards, errors and fatals always; other messages only as the host asked. */
int sbf_log_wanted(const sbf_log_filter *filter, int status, const char *category);

#endif
