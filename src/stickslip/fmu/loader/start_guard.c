/* The loaders' process-wide start guard: a library every FMU with this loader ships beside it, which each loader
 * opens with RTLD_GLOBAL, so that every copy of the loader in a process (the block's FMUs, the coupling FMU, copies
 * in other folders) finds the same lock through dlsym(RTLD_DEFAULT, "sbf_python_start_lock"): the definition in
 * the copy of this library that was loaded first. Under it the first loader to get there starts CPython (runtime.c,
 * process_start_lock). Its only symbol; keep its name and type as they are, for FMUs built by other versions. */
#include <pthread.h>

__attribute__((visibility("default"))) pthread_mutex_t sbf_python_start_lock = PTHREAD_MUTEX_INITIALIZER;
