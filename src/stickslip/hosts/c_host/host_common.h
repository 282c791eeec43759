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

/* The FMU-state calls of one FMI version, for mode "state_costs" (each returns the call's status) */
typedef struct {
    const char *names[6]; /* doStep, GetFMUstate, SetFMUstate, SerializedFMUstateSize, SerializeFMUstate,
                           * DeSerializeFMUstate, as the FMI version names them */
    int (*step)(void *instance, double t, double h);
    int (*get)(void *instance, void **state);
    int (*set)(void *instance, void *state);
    int (*free_state)(void *instance, void **state);
    int (*size)(void *instance, void *state, size_t *size);
    int (*serialize)(void *instance, void *state, void *bytes, size_t size);
    int (*deserialize)(void *instance, const void *bytes, size_t size, void **state);
} StateCalls;

/* Process CPU time in s */
static double cpu_now(void)
{
    struct timespec now;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
    return now.tv_sec + 1e-9 * now.tv_nsec;
}

/* Mode "state_costs" from time `t` (s) of an initialized instance: CPU time per call, in blocks of $HOST_ROUNDS calls
 * (default 1000), the blocks taken in turn 5 times and the median of each printed as "cost_us CALL U" (microseconds):
 * doStep of STEP s; GetFMUstate + FreeFMUstate; SetFMUstate of one state; SetFMUstate + doStep (back to the state,
 * one step on); SerializedFMUstateSize + SerializeFMUstate, each of a state of its own (a loader may keep the bytes of
 * the state serialized last); DeSerializeFMUstate + FreeFMUstate of those bytes. */
enum { COST_STEP, COST_GET, COST_SET, COST_SET_STEP, COST_SERIALIZE, COST_DESERIALIZE, N_COSTS, COST_REPEATS = 5 };

static int compare_doubles(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* CPU seconds per call of block `kind` of `rounds` calls, the instance at *t (s) and *t moved by its steps */
static double state_cost_block(void *c, double *t, int kind, int rounds, const StateCalls *f)
{
    void **states = calloc((size_t)rounds, sizeof *states);
    size_t size = 0;
    char *bytes = NULL;
    if (kind == COST_SET || kind == COST_SET_STEP) check(f->names[1], f->get(c, &states[0]));
    if (kind == COST_SERIALIZE)
        for (int i = 0; i < rounds; ++i) check(f->names[1], f->get(c, &states[i]));
    if (kind == COST_DESERIALIZE) {
        check(f->names[1], f->get(c, &states[0]));
        check(f->names[3], f->size(c, states[0], &size));
        bytes = malloc(size);
        check(f->names[4], f->serialize(c, states[0], bytes, size));
    }
    double start = cpu_now(), saved = *t;
    for (int i = 0; i < rounds; ++i) {
        void *copy = NULL;
        switch (kind) {
        case COST_STEP: check(f->names[0], f->step(c, *t, step)); *t += step; break;
        case COST_GET: check(f->names[1], f->get(c, &copy)); check("FreeFMUstate", f->free_state(c, &copy)); break;
        case COST_SET: check(f->names[2], f->set(c, states[0])); break;
        case COST_SET_STEP:
            check(f->names[2], f->set(c, states[0]));
            check(f->names[0], f->step(c, saved, step));
            break;
        case COST_SERIALIZE:
            check(f->names[3], f->size(c, states[i], &size));
            char *out = malloc(size);
            check(f->names[4], f->serialize(c, states[i], out, size));
            free(out);
            break;
        default:
            check(f->names[5], f->deserialize(c, bytes, size, &copy));
            check("FreeFMUstate", f->free_state(c, &copy));
        }
    }
    double cost = (cpu_now() - start) / rounds;
    if (kind == COST_SET_STEP) *t = saved + step;
    for (int i = 0; i < rounds; ++i)
        if (states[i]) check("FreeFMUstate", f->free_state(c, &states[i]));
    free(states);
    free(bytes);
    return cost;
}

static void state_costs(void *instance, double t, const StateCalls *f)
{
    const char *count = getenv("HOST_ROUNDS");
    int rounds = count ? atoi(count) : 1000;
    static const char *labels[N_COSTS] = {"doStep", "GetFMUstate+FreeFMUstate", "SetFMUstate", "SetFMUstate+doStep",
                                          "SerializedFMUstateSize+SerializeFMUstate",
                                          "DeSerializeFMUstate+FreeFMUstate"};
    double costs[N_COSTS][COST_REPEATS];
    for (int repeat = 0; repeat < COST_REPEATS; ++repeat)
        for (int kind = 0; kind < N_COSTS; ++kind)
            costs[kind][repeat] = state_cost_block(instance, &t, kind, rounds, f);
    for (int kind = 0; kind < N_COSTS; ++kind) {
        qsort(costs[kind], COST_REPEATS, sizeof costs[kind][0], compare_doubles);
        say("cost_us %s %.6g\n", labels[kind], 1e6 * costs[kind][COST_REPEATS / 2]);
    }
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
