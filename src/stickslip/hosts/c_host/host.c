/* A plain C FMI 2.0 co-simulation importer, as system simulators are: it opens an
 * FMU's binary with dlopen(RTLD_NOW | RTLD_LOCAL), nothing preloaded, no Python of
 * its own, and drives it the way FMPy's simulate_fmu does (same communication
 * points, so results compare bit for bit).
 *
 *   host BINARY RESOURCE_URI GUID MODE STOP STEP OUTPUT_VR [rVR=VALUE | iVR=VALUE ...]
 *
 * MODE   what it does (every logged message is printed as "log STATUS TEXT")
 * run    one instance, logging off; prints "x T X" at every communication point
 * bad    one instance with all settings, the last one invalid, logging off: prints
 *        "status exit CODE" of fmi2ExitInitializationMode, frees it, then runs a new
 *        instance without the last setting and prints its "x" lines
 * reset  like bad, but instead of a new instance it calls fmi2Reset ("status reset
 *        CODE") and runs the same instance again without the last setting
 * two    two instances stepped alternately on this thread: "a"/"b" lines like "x"
 * threads  two instances, each run on its own thread at the same time: "a"/"b" lines
 * state  runs to STOP/2, saves the state (fmi2GetFMUstate and serialized bytes), runs on
 *        to STOP ("x" lines), restores the state and runs on again ("r" lines), then
 *        restores the deserialized state and runs on again ("d" lines)
 * cycles N instantiate / run / terminate / free N times (N = $HOST_CYCLES): "c I T X"
 *        at the end of each cycle; the resident memory before cycle N/10 and at the end
 *        ("rss_kb_warm K", "rss_kb_end K")
 * bench  one run; prints "cpu_us_per_step U": process CPU time of fmi2DoStep + one
 *        fmi2GetReal per step, averaged over the steps
 * state_costs  runs to STOP, then prints "cost_us CALL U": the CPU time per call of fmi2DoStep (of STEP s) and of
 *        the FMU-state calls, in blocks of $HOST_ROUNDS calls (see state_costs in host_common.h)
 * thread_steps  one instance, each fmi2DoStep from a new thread: prints the resident memory
 *        after 100 steps and at the end ("rss_kb_warm K", "rss_kb_end K"), then "x T X" at the end
 * unload two threads each run an instance ("a"/"b" lines like "x") and then wait; the FMU is
 *        unloaded (dlclose) and only then do the threads end
 * pair   the FMU on one thread and a second FMU ($HOST_SECOND: "BINARY RESOURCES TOKEN OUTPUT_VR", its
 *        default start values, another binary: FMI 2, or FMI 3 co-simulation if BINARY is in an x86_64-linux
 *        folder, RESOURCES then a path) on another, both instantiated at the same time:
 *        "a T X" and "b T X" (its output) at the end of each run
 * races  thread "a" makes and frees an instance $HOST_ROUNDS times while thread "b" asks for instances at the
 *        resource location $HOST_RACE_RESOURCES again and again: "races ROUNDS FAILURES ATTEMPTS" (FAILURES: a's
 *        instantiations that returned NULL, each with its logged message; ATTEMPTS: b's; each distinct message of
 *        b logged once)
 * ramp   as run, but after initialization sets the first time derivative of the real input ($HOST_RAMP: "VR RATE")
 *        with fmi2SetRealInputDerivatives and prints "status ramp CODE" before the "x" lines
 * wave   as run, but before every step sets the real input ($HOST_WAVE: "VR AMPLITUDE") to AMPLITUDE sin(t) and its
 *        first time derivative to AMPLITUDE cos(t) (fmi2SetReal, fmi2SetRealInputDerivatives), t the step's start, as
 *        a co-simulation master sets a coupling force and its rate
 * With $HOST_LOGGING=1 every instance is made with loggingOn (else off).
 * Every line is flushed. The exit code is 0 when the mode ran to its end (a
 * failing FMI call ends the program with "failed FUNCTION STATUS" and code 1). */
#define _GNU_SOURCE
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "host_common.h"

typedef void *Component;
typedef unsigned int VR;
typedef int Status; /* 0 ok, 1 warning, 2 discard, 3 error, 4 fatal */
typedef void (*Logger)(void *, const char *, Status, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, Status);
    void *componentEnvironment;
} Callbacks;

/* The FMU's functions, in the order of `function_names` */
typedef struct {
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
    void (*free_instance)(Component);
    Status (*setup)(Component, int, double, double, int, double);
    Status (*enter)(Component);
    Status (*exit_init)(Component);
    Status (*terminate)(Component);
    Status (*reset)(Component);
    Status (*do_step)(Component, double, double, int);
    Status (*get_real)(Component, const VR *, size_t, double *);
    Status (*set_real)(Component, const VR *, size_t, const double *);
    Status (*set_integer)(Component, const VR *, size_t, const int *);
    Status (*get_state)(Component, void **);
    Status (*set_state)(Component, void *);
    Status (*free_state)(Component, void **);
    Status (*state_size)(Component, void *, size_t *);
    Status (*serialize)(Component, void *, char *, size_t);
    Status (*deserialize)(Component, const char *, size_t, void **);
    Status (*set_input_derivatives)(Component, const VR *, size_t, const int *, const double *);
} Functions;

static const char *const function_names[] = {
    "fmi2Instantiate", "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2DoStep", "fmi2GetReal", "fmi2SetReal",
    "fmi2SetInteger", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate", "fmi2SetRealInputDerivatives"};
#define N_FUNCTIONS (sizeof function_names / sizeof *function_names)

static Functions fmi; /* the FMU's (the second FMU of mode "pair" has its own) */

static void logger(void *env, const char *name, Status status, const char *category, const char *message, ...)
{
    char text[4096];
    va_list args;
    (void)env, (void)category;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    for (char *c = text; *c; ++c)
        if (*c == '\n') *c = ' ';
    say("log %d %s %s\n", status, name, text);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static Component instantiate(const char *name)
{
    const char *logging = getenv("HOST_LOGGING");
    Component c = fmi.instantiate(name, 1, token, resources, &callbacks, 0, logging && !strcmp(logging, "1"));
    if (!c) {
        say("failed fmi2Instantiate NULL\n");
        exit(1);
    }
    return c;
}

static Status initialize(Component c, int n)
{
    check("fmi2SetupExperiment", fmi.setup(c, 0, 0.0, 0.0, 1, stop_time));
    for (int i = 0; i < n; ++i) {
        VR vr;
        int is_integer;
        const char *value = setting(i, &vr, &is_integer);
        if (is_integer) {
            int v = atoi(value);
            check("fmi2SetInteger", fmi.set_integer(c, &vr, 1, &v));
        } else {
            double v = strtod(value, NULL);
            check("fmi2SetReal", fmi.set_real(c, &vr, 1, &v));
        }
    }
    check("fmi2EnterInitializationMode", fmi.enter(c));
    return fmi.exit_init(c);
}

static double read_output(Component c)
{
    double x;
    check("fmi2GetReal", fmi.get_real(c, &output, 1, &x));
    return x;
}

/* step from (t, n) to stop, printing "<tag> t x" at each point; returns the new n */
static long run_to(Component c, double *t, long n, double stop, const char *tag, double *cpu_seconds)
{
    struct timespec a, b;
    if (cpu_seconds) clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a); /* around the loop: a clock read costs as much as
                                                                   * a step of a compiled FMU */
    while (!done(*t, stop)) {
        double next = next_point(n, stop);
        check("fmi2DoStep", fmi.do_step(c, *t, next - *t, 1));
        double x = read_output(c);
        *t = next;
        ++n;
        if (tag) say("%s %.17g %.17g\n", tag, *t, x);
    }
    if (cpu_seconds) {
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
        *cpu_seconds += (b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec);
    }
    return n;
}

static void finish(Component c)
{
    check("fmi2Terminate", fmi.terminate(c));
    fmi.free_instance(c);
}

static void run_initialized(Component c, const char *tag)
{
    double t = 0.0;
    say("%s %.17g %.17g\n", tag, t, read_output(c));
    run_to(c, &t, 0, stop_time, tag, NULL);
    finish(c);
}

static void run_one(const char *name, const char *tag)
{
    Component c = instantiate(name);
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    run_initialized(c, tag);
}

static void *thread_main(void *tag)
{
    run_one(tag, tag);
    return NULL;
}

static void mode_two(void)
{
    Component a = instantiate("a"), b = instantiate("b");
    check("fmi2ExitInitializationMode", initialize(a, n_settings));
    check("fmi2ExitInitializationMode", initialize(b, n_settings));
    double ta = 0.0, tb = 0.0;
    say("a 0 %.17g\nb 0 %.17g\n", read_output(a), read_output(b));
    for (long n = 0; !done(ta, stop_time); ++n) {
        double stop = next_point(n, stop_time);
        run_to(a, &ta, n, stop, "a", NULL);
        run_to(b, &tb, n, stop, "b", NULL);
    }
    finish(a);
    finish(b);
}

static void mode_threads(void)
{
    pthread_t threads[2];
    static char *tags[] = {"a", "b"};
    for (int i = 0; i < 2; ++i)
        if (pthread_create(&threads[i], NULL, thread_main, tags[i])) exit(2);
    for (int i = 0; i < 2; ++i) pthread_join(threads[i], NULL);
}

static void mode_state(void)
{
    Component c = instantiate("state");
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    double t = 0.0, half = stop_time / 2;
    long n = run_to(c, &t, 0, half, NULL, NULL);
    void *state = NULL, *restored = NULL;
    size_t size;
    check("fmi2GetFMUstate", fmi.get_state(c, &state));
    check("fmi2SerializedFMUstateSize", fmi.state_size(c, state, &size));
    char *bytes = malloc(size);
    check("fmi2SerializeFMUstate", fmi.serialize(c, state, bytes, size));
    double t_saved = t;
    run_to(c, &t, n, stop_time, "x", NULL);
    check("fmi2SetFMUstate", fmi.set_state(c, state));
    t = t_saved;
    run_to(c, &t, n, stop_time, "r", NULL);
    check("fmi2DeSerializeFMUstate", fmi.deserialize(c, bytes, size, &restored));
    check("fmi2SetFMUstate", fmi.set_state(c, restored));
    t = t_saved;
    run_to(c, &t, n, stop_time, "d", NULL);
    check("fmi2FreeFMUstate", fmi.free_state(c, &state));
    check("fmi2FreeFMUstate", fmi.free_state(c, &restored));
    free(bytes);
    finish(c);
}

static void mode_bad(void)
{
    Component c = instantiate("bad");
    say("status exit %d\n", initialize(c, n_settings));
    fmi.free_instance(c);
    --n_settings;
    run_one("good", "x");
}

static void mode_ramp(void)
{
    const char *ramp = getenv("HOST_RAMP");
    VR vr;
    int order = 1;
    double rate;
    if (!ramp || sscanf(ramp, "%u %lf", &vr, &rate) != 2) {
        say("failed HOST_RAMP \"VR RATE\" not set\n");
        exit(1);
    }
    Component c = instantiate("ramp");
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    say("status ramp %d\n", fmi.set_input_derivatives(c, &vr, 1, &order, &rate));
    run_initialized(c, "x");
}

static void mode_wave(void)
{
    const char *wave = getenv("HOST_WAVE");
    VR vr;
    int order = 1;
    double amplitude, t = 0.0;
    if (!wave || sscanf(wave, "%u %lf", &vr, &amplitude) != 2) {
        say("failed HOST_WAVE \"VR AMPLITUDE\" not set\n");
        exit(1);
    }
    Component c = instantiate("wave");
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    say("x %.17g %.17g\n", t, read_output(c));
    for (long n = 0; !done(t, stop_time); ++n) {
        double next = next_point(n, stop_time), force = amplitude * sin(t), rate = amplitude * cos(t);
        check("fmi2SetReal", fmi.set_real(c, &vr, 1, &force));
        check("fmi2SetRealInputDerivatives", fmi.set_input_derivatives(c, &vr, 1, &order, &rate));
        check("fmi2DoStep", fmi.do_step(c, t, next - t, 1));
        t = next;
        say("x %.17g %.17g\n", t, read_output(c));
    }
    finish(c);
}

static void mode_reset(void)
{
    Component c = instantiate("bad");
    say("status exit %d\n", initialize(c, n_settings));
    say("status reset %d\n", fmi.reset(c));
    check("fmi2ExitInitializationMode", initialize(c, n_settings - 1));
    run_initialized(c, "x");
}

static void mode_cycles(void)
{
    const char *count = getenv("HOST_CYCLES");
    int cycles = count ? atoi(count) : 50;
    for (int i = 0; i < cycles; ++i) {
        if (i == cycles / 10) say("rss_kb_warm %ld\n", resident_kb());
        Component c = instantiate("cycle");
        check("fmi2ExitInitializationMode", initialize(c, n_settings));
        double t = 0.0;
        run_to(c, &t, 0, stop_time, NULL, NULL);
        say("c %d %.17g %.17g\n", i, t, read_output(c));
        finish(c);
    }
    say("rss_kb_end %ld\n", resident_kb());
}

static void mode_bench(void)
{
    Component c = instantiate("bench");
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    double t = 0.0, cpu = 0.0;
    long n = run_to(c, &t, 0, stop_time, NULL, &cpu);
    say("cpu_us_per_step %.6g\nsteps %ld\n", 1e6 * cpu / (double)n, n);
    finish(c);
}

static int step_for_costs(void *c, double t, double h) { return fmi.do_step(c, t, h, 1); }
static int serialize_for_costs(void *c, void *s, void *bytes, size_t n) { return fmi.serialize(c, s, bytes, n); }
static int deserialize_for_costs(void *c, const void *bytes, size_t n, void **s)
{
    return fmi.deserialize(c, bytes, n, s);
}

static void mode_state_costs(void)
{
    Component c = instantiate("costs");
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    double t = 0.0;
    run_to(c, &t, 0, stop_time, NULL, NULL);
    StateCalls calls = {{"fmi2DoStep", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2SerializedFMUstateSize",
                         "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate"},
                        step_for_costs, fmi.get_state, fmi.set_state, fmi.free_state, fmi.state_size,
                        serialize_for_costs, deserialize_for_costs};
    state_costs(c, t, &calls);
    finish(c);
}

static void *step_call(void *call)
{
    StepCall *s = call;
    check("fmi2DoStep", fmi.do_step(s->instance, s->t, s->h, 1));
    return NULL;
}

static void mode_thread_steps(void)
{
    Component c = instantiate("threads");
    check("fmi2ExitInitializationMode", initialize(c, n_settings));
    steps_from_new_threads(c, step_call, read_output);
    finish(c);
}

/* Mode "pair": the second FMU, run with its default start values from its own binary */
static pthread_barrier_t instantiating;

/* An FMI 3 co-simulation FMU's functions, for mode "pair" */
static const char *const fmi3_names[] = {"fmi3InstantiateCoSimulation", "fmi3EnterInitializationMode",
                                         "fmi3ExitInitializationMode", "fmi3DoStep", "fmi3GetFloat64",
                                         "fmi3Terminate", "fmi3FreeInstance"};
typedef struct {
    Component (*instantiate)(const char *, const char *, const char *, bool, bool, bool, bool, const VR *, size_t,
                             void *, void (*)(void *, Status, const char *, const char *), void *);
    Status (*enter)(Component, bool, double, double, bool, double);
    Status (*exit_init)(Component);
    Status (*do_step)(Component, double, double, bool, bool *, bool *, bool *, double *);
    Status (*get_float64)(Component, const VR *, size_t, double *, size_t);
    Status (*terminate)(Component);
    void (*free_instance)(Component);
} Fmi3Functions;

static void log_fmi3(void *env, Status status, const char *category, const char *message)
{
    (void)env, (void)category;
    say("log %d b %s\n", status, message);
}

/* The second FMU of mode "pair" as an FMI 3 co-simulation FMU (`path`: its resources folder): "b T X" at the end */
static void run_second_fmi3(const char *binary, const char *path, const char *token, VR vr)
{
    Fmi3Functions other;
    if (!load_fmu(binary, fmi3_names, sizeof fmi3_names / sizeof *fmi3_names, (void **)&other)) exit(1);
    pthread_barrier_wait(&instantiating);
    Component c = other.instantiate("b", token, path, false, false, false, false, NULL, 0, NULL, log_fmi3, NULL);
    if (!c) {
        say("failed fmi3InstantiateCoSimulation NULL\n");
        exit(1);
    }
    check("fmi3EnterInitializationMode", other.enter(c, false, 0.0, 0.0, true, stop_time));
    check("fmi3ExitInitializationMode", other.exit_init(c));
    double t = 0.0, value, last;
    bool event, terminate, early;
    for (long n = 0; !done(t, stop_time); ++n) {
        double next = next_point(n, stop_time);
        check("fmi3DoStep", other.do_step(c, t, next - t, true, &event, &terminate, &early, &last));
        t = next;
    }
    check("fmi3GetFloat64", other.get_float64(c, &vr, 1, &value, 1));
    say("b %.17g %.17g\n", t, value);
    check("fmi3Terminate", other.terminate(c));
    other.free_instance(c);
}

static void *run_second(void *line)
{
    char binary[4096], uri[4096], guid[256];
    unsigned int vr;
    Functions other;
    if (sscanf(line, "%4095s %4095s %255s %u", binary, uri, guid, &vr) != 4) exit(2);
    if (strstr(binary, "/x86_64-linux/")) {
        run_second_fmi3(binary, uri, guid, vr);
        return NULL;
    }
    if (!load_fmu(binary, function_names, N_FUNCTIONS, (void **)&other)) exit(1);
    pthread_barrier_wait(&instantiating);
    Component c = other.instantiate("b", 1, guid, uri, &callbacks, 0, 0);
    if (!c) {
        say("failed fmi2Instantiate NULL\n");
        exit(1);
    }
    check("fmi2SetupExperiment", other.setup(c, 0, 0.0, 0.0, 1, stop_time));
    check("fmi2EnterInitializationMode", other.enter(c));
    check("fmi2ExitInitializationMode", other.exit_init(c));
    double t = 0.0, value;
    for (long n = 0; !done(t, stop_time); ++n) {
        double next = next_point(n, stop_time);
        check("fmi2DoStep", other.do_step(c, t, next - t, 1));
        t = next;
    }
    check("fmi2GetReal", other.get_real(c, &vr, 1, &value));
    say("b %.17g %.17g\n", t, value);
    check("fmi2Terminate", other.terminate(c));
    other.free_instance(c);
    return NULL;
}

static void *run_first(void *tag)
{
    pthread_barrier_wait(&instantiating);
    run_one(tag, tag);
    return NULL;
}

static void mode_pair(void)
{
    pthread_t threads[2];
    char *second = getenv("HOST_SECOND");
    if (!second) exit(2);
    pthread_barrier_init(&instantiating, NULL, 2);
    if (pthread_create(&threads[0], NULL, run_first, "a") || pthread_create(&threads[1], NULL, run_second, second))
        exit(2);
    for (int i = 0; i < 2; ++i) pthread_join(threads[i], NULL);
}

/* Mode "races": thread "a" makes and frees instances; thread "b" meanwhile asks for instances at another resource
 * location, again and again, so that the two threads' checks of their locations overlap in many of a's rounds. */
static int race_rounds;
static volatile int race_over;
static long race_failures, race_attempts;

/* The logger of mode "races": each distinct message of "b" printed once */
static void race_logger(void *env, const char *name, Status status, const char *category, const char *message, ...)
{
    static char seen[8][1024];
    static int n_seen;
    static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
    char text[1024];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    pthread_mutex_lock(&lock);
    int known = 0;
    for (int i = 0; i < n_seen && !known; ++i) known = !strcmp(seen[i], text);
    if (!known && n_seen < 8) strcpy(seen[n_seen++], text);
    pthread_mutex_unlock(&lock);
    if (strcmp(name, "b") || !known) logger(env, name, status, category, "%s", text);
}

static const Callbacks race_callbacks = {race_logger, calloc, free, NULL, NULL};

static void *race_thread(void *name)
{
    int first = !strcmp(name, "a");
    const char *location = first ? resources : getenv("HOST_RACE_RESOURCES");
    for (int round = 0; first ? round < race_rounds : !race_over; ++round) {
        Component c = fmi.instantiate(name, 1, token, location, &race_callbacks, 0, 0);
        if (c) fmi.free_instance(c);
        if (first && !c) ++race_failures;
        if (!first) ++race_attempts;
    }
    race_over = 1;
    return NULL;
}

static void mode_races(void)
{
    const char *rounds = getenv("HOST_ROUNDS");
    pthread_t threads[2];
    race_rounds = rounds ? atoi(rounds) : 1000;
    if (!getenv("HOST_RACE_RESOURCES")) exit(2);
    if (pthread_create(&threads[0], NULL, race_thread, "a") || pthread_create(&threads[1], NULL, race_thread, "b"))
        exit(2);
    for (int i = 0; i < 2; ++i) pthread_join(threads[i], NULL);
    say("races %d %ld %ld\n", race_rounds, race_failures, race_attempts);
}

int main(int argc, char **argv)
{
    if (!start_host(argc, argv, function_names, N_FUNCTIONS, (void **)&fmi)) return argc < 8 ? 2 : 1;
    if (!strcmp(mode, "run")) run_one("run", "x");
    else if (!strcmp(mode, "bad")) mode_bad();
    else if (!strcmp(mode, "reset")) mode_reset();
    else if (!strcmp(mode, "ramp")) mode_ramp();
    else if (!strcmp(mode, "wave")) mode_wave();
    else if (!strcmp(mode, "two")) mode_two();
    else if (!strcmp(mode, "threads")) mode_threads();
    else if (!strcmp(mode, "state")) mode_state();
    else if (!strcmp(mode, "cycles")) mode_cycles();
    else if (!strcmp(mode, "bench")) mode_bench();
    else if (!strcmp(mode, "state_costs")) mode_state_costs();
    else if (!strcmp(mode, "thread_steps")) mode_thread_steps();
    else if (!strcmp(mode, "unload")) unload_after_runs(thread_main);
    else if (!strcmp(mode, "pair")) mode_pair();
    else if (!strcmp(mode, "races")) mode_races();
    else {
        fprintf(stderr, "unknown mode %s\n", mode);
        return 2;
    }
    say("done\n");
    return 0;
}
