/* The CPython the FMU carries for hosts that have none, packed into one file of the FMU and unpacked into the
 * user's cache only where the loader starts it (carried.c). */
#ifndef SBF_CARRIED_H
#define SBF_CARRIED_H
#include <stddef.h>

/* the carried CPython's build of the inner library that needs glibc alone (a path as SBF_BUNDLED_LIBPYTHON),
 * loaded where the FMU's does not load, instead of SBF_BUNDLED_INNER_NEEDS, or always where the FMU has none beside
 * the loader (runtime.c); "" if none */
#ifndef SBF_BUNDLED_INNER
#define SBF_BUNDLED_INNER ""
#endif

/* Whether this FMU carries a CPython for this platform */
int sbf_carries_python(void);
/* The path of the carried CPython's file `relative` (a path of the build's below "python/", e.g.
 * "python/libpython3.11.so.1.0") into `path`, the CPython unpacked first if no process has; 0 with a message saying
 * where it was to be unpacked, why it could not and what to set (not SBF_LIBPYTHON for SBF_BUNDLED_INNER, which
 * no other CPython stands in for), in `why`. */
int sbf_carried_path(const char *relative, char *path, size_t size, char *why, size_t why_size);
/* The bytes the unpacked CPython takes */
double sbf_carried_bytes(void);

#endif
