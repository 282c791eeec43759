/* The CPython the FMU carries for hosts that have none, packed into one file of the FMU and unpacked into the
 * user's cache only where the loader starts it (carried.c). */
#ifndef SBF_CARRIED_H
#define SBF_CARRIED_H
#include <stddef.h>

/* Whether this FMU carries a CPython for this platform */
int sbf_carries_python(void);
/* The path of the carried CPython's file `relative` (a path of the build's below "python/", e.g.
 * "python/libpython3.11.so.1.0") into `path`, the CPython unpacked first if no process has; 0 with a message saying
 * where it was to be unpacked, why it could not and what to set, in `why`. */
int sbf_carried_path(const char *relative, char *path, size_t size, char *why, size_t why_size);
/* The bytes the unpacked CPython takes */
double sbf_carried_bytes(void);

#endif
