/* What the C hosts (host.c: FMI 2, host3.c: FMI 3) share: printing, failing, FMPy's communication points. */
#ifndef SBF_HOST_COMMON_H
#define SBF_HOST_COMMON_H
#ifdef _WIN32
#include "host_windows.h"
#else
#include <dlfcn.h>
#endif
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static pthread_mutex_t print_lock = PTHREAD_MUTEX_INITIALIZER;

static void say(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    pthread_mutex_lock(&print_lock);
    vprintf(format, args);
    fflush(stdout);
    pthread_mutex_unlock(&print_lock);
    va_end(args);
}

/* ---- the command line: host BINARY RESOURCES TOKEN MODE STOP STEP OUTPUT_VR [rVR=VALUE | iVR=VALUE ...] ---- */
static const char *resources, *token, *mode; /* the FMU's resources (as the FMI version passes them), its
                                                 GUID / instantiation token, the mode to run */
static double stop_time, step;               /* s */
static unsigned int output;                  /* value reference of the real output printed */
static int n_settings;
static char **settings;                      /* start values, set in this order */
static void *fmu_library;                    /* the FMU's binary, as dlopen gave it */

/* Open the FMU binary `binary` and load its functions `names` into `slots`, in order; its handle, or NULL after a
 * printed failure. */
static void *load_fmu(const char *binary, const char *const *names, size_t n, void **slots)
{
    void *lib = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        say("failed dlopen %s\n", dlerror());
        return NULL;
    }
    for (size_t i = 0; i < n; ++i)
        if (!(slots[i] = dlsym(lib, names[i]))) {
            say("failed dlsym %s\n", names[i]);
            return NULL;
        }
    return lib;
}

/* Parse the command line and load the FMU's functions `names` into `slots`, in order; 0 after a printed failure. */
static int start_host(int argc, char **argv, const char *const *names, size_t n, void **slots)
{
    if (argc < 8) {
        fprintf(stderr, "usage: %s BINARY RESOURCES TOKEN MODE STOP STEP OUTPUT_VR [rVR=VALUE|iVR=VALUE ...]\n", argv[0]);
        return 0;
    }
#ifdef _WIN32
    argv = utf8_arguments(argc);
#endif
    if (!(fmu_library = load_fmu(argv[1], names, n, slots))) return 0;
    resources = argv[2];
    token = argv[3];
    mode = argv[4];
    stop_time = strtod(argv[5], NULL);
    step = strtod(argv[6], NULL);
    output = (unsigned int)strtoul(argv[7], NULL, 10);
    settings = argv + 8;
    n_settings = argc - 8;
    return 1;
}

/* Setting i: its value reference, whether it is an integer, and its value's text */
static const char *setting(int i, unsigned int *vr, int *is_integer)
{
    *vr = (unsigned int)strtoul(settings[i] + 1, NULL, 10);
    *is_integer = settings[i][0] == 'i';
    return strchr(settings[i], '=') + 1;
}

static void check(const char *function, int status)
{
    if (status > 1) {
        say("failed %s %d\n", function, status);
        exit(1);
    }
}

/* FMPy's communication points: start + (n+1) h, the last one clipped to the stop time */
static int close_to(double a, double b) { return fabs(a - b) <= 1e-9 * fmax(fabs(a), fabs(b)); }
static int done(double t, double stop) { return t > stop || close_to(t, stop); }
static double next_point(long n, double stop)
{
    double next = (n + 1) * step;
    return next > stop && !close_to(next, stop) ? stop : next;
}

#ifndef _WIN32
/* The process's resident memory in kB (Linux /proc/self/statm), or -1 */
static long resident_kb(void)
{
    long pages = -1, resident = -1;
    FILE *statm = fopen("/proc/self/statm", "r");
    if (statm) {
        if (fscanf(statm, "%ld %ld", &pages, &resident) != 2) resident = -1;
        fclose(statm);
    }
    return resident < 0 ? -1 : resident * (sysconf(_SC_PAGESIZE) / 1024);
}
#endif

/* call(argument) on a new thread, created and joined */
static void on_new_thread(void *(*call)(void *), void *argument)
{
    pthread_t thread;
    if (pthread_create(&thread, NULL, call, argument) || pthread_join(thread, NULL)) {
        say("failed pthread_create\n");
        exit(1);
    }
}

/* One communication step of `instance` from `t` by `h` s, for a thread */
typedef struct {
    void *instance;
    double t, h;
} StepCall;

/* Mode "thread_steps": the communication steps of `instance` from t = 0 to the stop time, each made by
 * `do_step(StepCall *)` on a new thread; prints "rss_kb_warm K" after 100 steps, "rss_kb_end K", "steps N" and
 * "x T X" (X = read(instance)) at the end. */
static void steps_from_new_threads(void *instance, void *(*do_step)(void *), double (*read)(void *))
{
    double t = 0.0;
    long n = 0;
    for (; !done(t, stop_time); ++n) {
        if (n == 100) say("rss_kb_warm %ld\n", resident_kb());
        double next = next_point(n, stop_time);
        StepCall call = {instance, t, next - t};
        on_new_thread(do_step, &call);
        t = next;
    }
    say("rss_kb_end %ld\nsteps %ld\nx %.17g %.17g\n", resident_kb(), n, t, read(instance));
}

/* Mode "unload": `run(tag)` on two threads (tags "a" and "b"), which then wait; the FMU is unloaded (dlclose of the
 * host's handle, "unloaded R" with its result), and only then do the threads end. */
static pthread_barrier_t unload_ran, unload_done;
static void *(*unload_run)(void *);

static void *run_then_wait(void *tag)
{
    unload_run(tag);
    pthread_barrier_wait(&unload_ran);
    pthread_barrier_wait(&unload_done);
    return NULL;
}

static void unload_after_runs(void *(*run)(void *))
{
    pthread_t threads[2];
    static char *tags[] = {"a", "b"};
    unload_run = run;
    pthread_barrier_init(&unload_ran, NULL, 3);
    pthread_barrier_init(&unload_done, NULL, 3);
    for (int i = 0; i < 2; ++i)
        if (pthread_create(&threads[i], NULL, run_then_wait, tags[i])) exit(2);
    pthread_barrier_wait(&unload_ran);
    say("unloaded %d\n", dlclose(fmu_library));
    pthread_barrier_wait(&unload_done);
    for (int i = 0; i < 2; ++i) pthread_join(threads[i], NULL);
}

#endif
