/* A plain C FMI 3.0 importer: as host.c (FMI 2), it opens an FMU's binary with dlopen(RTLD_NOW | RTLD_LOCAL),
 * nothing preloaded, no Python of its own. Co-simulation is driven the way FMPy's simulate_fmu does (same
 * communication points, so results compare bit for bit); model exchange with an integrator and an event
 * locator of its own, as a C simulator would (see run_me).
 *
 *   host3 BINARY RESOURCE_PATH TOKEN MODE STOP STEP OUTPUT_VR [rVR=VALUE | iVR=VALUE ...]  (i: fmi3SetInt64)
 *
 * RESOURCE_PATH is the FMU's resources folder with a trailing slash (FMI 3 passes a path, not a URI).
 * MODE    what it does (every logged message is printed as "log STATUS INSTANCE TEXT")
 * run     one co-simulation instance, logging off; prints "x T X" at every communication point
 * bad     one instance with all settings, the last one invalid, logging off: prints "status exit CODE" of
 *         fmi3ExitInitializationMode, frees it, then runs a new instance without the last setting ("x" lines)
 * me-run  as run, with a model-exchange instance: classical RK4, steps of at most $HOST_ME_STEP s (default
 *         STEP) ending on the output points, state events located on each step's interpolant. Prints "x T X"
 *         at the output points (after any event there) and, with $HOST_ME_COUNTER (the value reference of an
 *         Int32 output), "e T N" after each state event: its time and that output.
 * me-bad  as bad, with model-exchange instances
 * early   as run, with earlyReturnAllowed, driven as fmusim --early-return-allowed does (Reference-FMUs'
 *         FMI3CSSimulation.c): after an early return the next step starts at lastSuccessfulTime and ends on the
 *         next output point. Prints "early T" at each early return, then "x T X" there too.
 * events  as early, with eventModeUsed as well (fmusim --early-return-allowed --event-mode-used): Event Mode after
 *         initialization and at each early return that asks for event handling (fmi3EnterEventMode,
 *         fmi3UpdateDiscreteStates until no more update is needed, fmi3EnterStepMode). At such an event, "x T X"
 *         before Event Mode and again after it, each followed by "m T MODE" ($HOST_MODE_VR: the value reference of
 *         the Int32 output read, default none).
 * state   one co-simulation instance: runs to STOP/2, saves the FMU state (fmi3GetFMUState and serialized bytes),
 *         runs on to STOP ("x" lines), restores the state and runs on again ("r" lines), then restores the
 *         deserialized state and runs on again ("d" lines)
 * state_costs  one co-simulation instance run to STOP, then "cost_us CALL U": the CPU time per call of fmi3DoStep
 *         (of STEP s) and of the FMU-state calls, in blocks of $HOST_ROUNDS calls (state_costs in host_common.h)
 * thread_steps  one co-simulation instance, each fmi3DoStep from a new thread: prints the resident memory
 *         after 100 steps and at the end ("rss_kb_warm K", "rss_kb_end K"), then "x T X" at the end
 * unload  two threads each run a co-simulation instance ("x" lines) and then wait; the FMU is unloaded
 *         (dlclose) and only then do the threads end
 * With $HOST_LOGGING=1 every instance is made with loggingOn (else off).
 * Every line is flushed. The exit code is 0 when the mode ran to its end (a failing FMI call ends the
 * program with "failed FUNCTION STATUS" and code 1). */
#define _GNU_SOURCE
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "host_common.h"

typedef void *Instance;
typedef uint32_t VR;
typedef int Status; /* 0 ok, 1 warning, 2 discard, 3 error, 4 fatal */
typedef void (*LogMessage)(void *environment, Status, const char *category, const char *message);

static struct {
    Instance (*instantiate)(const char *, const char *, const char *, bool, bool, bool, bool, const VR *, size_t,
                            void *, LogMessage, void *);
    void (*free_instance)(Instance);
    Status (*enter)(Instance, bool, double, double, bool, double);
    Status (*exit_init)(Instance);
    Status (*terminate)(Instance);
    Status (*do_step)(Instance, double, double, bool, bool *, bool *, bool *, double *);
    Status (*get_float64)(Instance, const VR *, size_t, double *, size_t);
    Status (*set_float64)(Instance, const VR *, size_t, const double *, size_t);
    Status (*set_int64)(Instance, const VR *, size_t, const int64_t *, size_t);
    /* model exchange */
    Instance (*instantiate_me)(const char *, const char *, const char *, bool, bool, void *, LogMessage);
    Status (*get_int32)(Instance, const VR *, size_t, int32_t *, size_t);
    Status (*n_states)(Instance, size_t *);
    Status (*n_indicators)(Instance, size_t *);
    Status (*update)(Instance, bool *, bool *, bool *, bool *, bool *, double *);
    Status (*enter_event_mode)(Instance);
    Status (*enter_continuous_time_mode)(Instance);
    Status (*set_time)(Instance, double);
    Status (*get_states)(Instance, double *, size_t);
    Status (*set_states)(Instance, const double *, size_t);
    Status (*get_derivatives)(Instance, double *, size_t);
    Status (*get_indicators)(Instance, double *, size_t);
    Status (*enter_step_mode)(Instance);
    /* FMU states */
    Status (*get_state)(Instance, void **);
    Status (*set_state)(Instance, void *);
    Status (*free_state)(Instance, void **);
    Status (*state_size)(Instance, void *, size_t *);
    Status (*serialize)(Instance, void *, unsigned char *, size_t);
    Status (*deserialize)(Instance, const unsigned char *, size_t, void **);
} fmi;

static bool model_exchange; /* the mode's instances are model-exchange ones */
static bool early_return, event_mode; /* co-simulation instances: earlyReturnAllowed, eventModeUsed */


/* the instance environment is the instance's name */
static void log_message(void *environment, Status status, const char *category, const char *message)
{
    char text[4096];
    (void)category;
    snprintf(text, sizeof text, "%s", message ? message : "");
    for (char *c = text; *c; ++c)
        if (*c == '\n') *c = ' ';
    say("log %d %s %s\n", status, (const char *)environment, text);
}

static Instance instantiate(const char *name)
{
    const char *logging_text = getenv("HOST_LOGGING");
    bool logging = logging_text && !strcmp(logging_text, "1");
    Instance c = model_exchange
        ? fmi.instantiate_me(name, token, resources, false, logging, (void *)name, log_message)
        : fmi.instantiate(name, token, resources, false, logging, event_mode, early_return, NULL, 0, (void *)name,
                          log_message, NULL);
    if (!c) {
        say("failed %s NULL\n", model_exchange ? "fmi3InstantiateModelExchange" : "fmi3InstantiateCoSimulation");
        exit(1);
    }
    return c;
}

static Status initialize(Instance c, int n)
{
    for (int i = 0; i < n; ++i) {
        VR vr;
        int is_integer;
        const char *value = setting(i, &vr, &is_integer);
        if (is_integer) {
            int64_t v = atoll(value); /* the integer parameters are enumerations: set as Int64 (FMI 3) */
            check("fmi3SetInt64", fmi.set_int64(c, &vr, 1, &v, 1));
        } else {
            double v = strtod(value, NULL);
            check("fmi3SetFloat64", fmi.set_float64(c, &vr, 1, &v, 1));
        }
    }
    check("fmi3EnterInitializationMode", fmi.enter(c, false, 0.0, 0.0, true, stop_time));
    return fmi.exit_init(c);
}

static double read_output(Instance c)
{
    double x;
    check("fmi3GetFloat64", fmi.get_float64(c, &output, 1, &x, 1));
    return x;
}

static void run_cs(Instance c)
{
    double t = 0.0;
    say("x %.17g %.17g\n", t, read_output(c));
    for (long n = 0; !done(t, stop_time); ++n) {
        double next = next_point(n, stop_time), last_successful;
        bool event_needed, terminate, early_return;
        check("fmi3DoStep", fmi.do_step(c, t, next - t, true, &event_needed, &terminate, &early_return,
                                        &last_successful));
        t = next;
        say("x %.17g %.17g\n", t, read_output(c));
    }
}

/* "x T X" and, with $HOST_MODE_VR, "m T MODE" at time t */
static void sample(Instance c, double t)
{
    const char *mode_vr = getenv("HOST_MODE_VR");
    say("x %.17g %.17g\n", t, read_output(c));
    if (mode_vr) {
        VR vr = (VR)strtoul(mode_vr, NULL, 10);
        int32_t value;
        check("fmi3GetInt32", fmi.get_int32(c, &vr, 1, &value, 1));
        say("m %.17g %d\n", t, (int)value);
    }
}

/* fmi3UpdateDiscreteStates until the FMU needs no more update (Event Mode) */
static void update_discrete_states(Instance c)
{
    bool again = true, terminate, nominals_changed, values_changed, next_defined;
    double next_time;
    while (again)
        check("fmi3UpdateDiscreteStates", fmi.update(c, &again, &terminate, &nominals_changed, &values_changed,
                                                     &next_defined, &next_time));
}

/* fmusim's co-simulation loop with early return (modes early and events) */
static void run_cs_early(Instance c)
{
    double t = 0.0;
    if (event_mode) { /* FMI 3.0 section 4.2: Event Mode after initialization */
        update_discrete_states(c);
        check("fmi3EnterStepMode", fmi.enter_step_mode(c));
    }
    sample(c, t);
    for (long n = 0; !done(t, stop_time);) {
        double next = next_point(n, stop_time), last_successful;
        bool event_needed, terminate, returned;
        check("fmi3DoStep", fmi.do_step(c, t, next - t, true, &event_needed, &terminate, &returned,
                                        &last_successful));
        if (returned && last_successful < next) {
            t = last_successful;
            say("early %.17g\n", t);
        } else {
            t = next, ++n;
        }
        sample(c, t);
        if (event_mode && event_needed) {
            check("fmi3EnterEventMode", fmi.enter_event_mode(c));
            update_discrete_states(c);
            check("fmi3EnterStepMode", fmi.enter_step_mode(c));
            sample(c, t);
        }
    }
}

/* ---- model exchange: classical RK4, state events located by bisection on the step's Hermite interpolant ---- */

enum { MAX_STATES = 8, MAX_INDICATORS = 8 };
/* a located event lies at most this far past the crossing on the interpolant: 1e-14 s, relative beyond t = 1 s
 * (about 50 ulp of t) */
#define EVENT_TIME_TOLERANCE 1e-14

static size_t nx, nz; /* numbers of continuous states and of event indicators */

/* A point of the solution: time (s), the continuous states and their derivatives */
typedef struct {
    double t, x[MAX_STATES], dx[MAX_STATES];
} Point;

static void put(Instance c, double t, const double *x)
{
    check("fmi3SetTime", fmi.set_time(c, t));
    check("fmi3SetContinuousStates", fmi.set_states(c, x, nx));
}

static void derivatives(Instance c, double t, const double *x, double *dx)
{
    put(c, t, x);
    check("fmi3GetContinuousStateDerivatives", fmi.get_derivatives(c, dx, nx));
}

static void indicators(Instance c, double t, const double *x, double *z)
{
    put(c, t, x);
    check("fmi3GetEventIndicators", fmi.get_indicators(c, z, nz));
}

/* b: a advanced to t_end by one classical RK4 step, with the derivatives there */
static void rk4(Instance c, const Point *a, double t_end, Point *b)
{
    static const double stage[3] = {0.5, 0.5, 1.0}; /* where stages 2-4 sit in the step */
    double h = t_end - a->t, k[3][MAX_STATES], y[MAX_STATES];
    const double *slope = a->dx;
    for (int s = 0; s < 3; ++s) {
        for (size_t i = 0; i < nx; ++i) y[i] = a->x[i] + stage[s] * h * slope[i];
        derivatives(c, a->t + stage[s] * h, y, k[s]);
        slope = k[s];
    }
    b->t = t_end;
    for (size_t i = 0; i < nx; ++i)
        b->x[i] = a->x[i] + h / 6.0 * (a->dx[i] + 2.0 * k[0][i] + 2.0 * k[1][i] + k[2][i]);
    derivatives(c, b->t, b->x, b->dx);
}

/* x at t in [a.t, b.t] on the cubic Hermite interpolant of the step a -> b (error O(h^4), as RK4's own) */
static void interpolate(const Point *a, const Point *b, double t, double *x)
{
    double h = b->t - a->t, s = (t - a->t) / h, r = 1.0 - s;
    for (size_t i = 0; i < nx; ++i)
        x[i] = r * r * ((1.0 + 2.0 * s) * a->x[i] + s * h * a->dx[i])
             + s * s * ((3.0 - 2.0 * s) * b->x[i] - r * h * b->dx[i]);
}

/* FMI 3: a state event is an indicator changing between the domains z > 0 (1) and z <= 0 (-1) */
static int domain(double z) { return z > 0.0 ? 1 : -1; }

/* Some indicator left its domain (0: none yet) */
static bool crossed(const int *domains, const double *z)
{
    for (size_t j = 0; j < nz; ++j)
        if (domains[j] && domain(z[j]) != domains[j]) return true;
    return false;
}

/* The domains at an accepted point. An indicator that restarted on exactly 0 (this FMU's m v_rel after a
 * breakaway or an overshoot) has none until it leaves 0, as CVode's root finder does: that is no event. */
static void track_domains(int *domains, const double *z)
{
    for (size_t j = 0; j < nz; ++j)
        if (z[j] != 0.0 || domains[j]) domains[j] = domain(z[j]);
}

/* The first state event in (a.t, b.t]: bisection on the interpolant until the crossing is bracketed within
 * the tolerance; returns the bracket's end past the crossing (s), with the states there in x */
static double locate(Instance c, const Point *a, const Point *b, const int *domains, double *x)
{
    double lo = a->t, hi = b->t, y[MAX_STATES], z[MAX_INDICATORS];
    memcpy(x, b->x, nx * sizeof *x);
    while (hi - lo > EVENT_TIME_TOLERANCE * fmax(1.0, fabs(hi))) {
        double mid = 0.5 * (lo + hi);
        interpolate(a, b, mid, y);
        indicators(c, mid, y, z);
        if (crossed(domains, z)) {
            hi = mid;
            memcpy(x, y, nx * sizeof *x);
        } else {
            lo = mid;
        }
    }
    return hi;
}

/* In Event Mode: fmi3UpdateDiscreteStates until no more updates are needed; false if the FMU asks to stop.
 * Time events are not handled (this FMU defines none): one fails the run. */
static bool event_iteration(Instance c)
{
    bool need_update = true, terminate = false, nominals_changed, values_changed, time_event;
    double next_time;
    while (need_update && !terminate) {
        check("fmi3UpdateDiscreteStates", fmi.update(c, &need_update, &terminate, &nominals_changed,
                                                     &values_changed, &time_event, &next_time));
        if (time_event) {
            say("failed fmi3UpdateDiscreteStates time event at %.17g\n", next_time);
            exit(1);
        }
    }
    check("fmi3EnterContinuousTimeMode", fmi.enter_continuous_time_mode(c));
    return !terminate;
}

/* Start (again) at a->t: the FMU's states (an event update may change them), their derivatives, new domains */
static void restart(Instance c, Point *a, int *domains)
{
    double z[MAX_INDICATORS];
    check("fmi3GetContinuousStates", fmi.get_states(c, a->x, nx));
    derivatives(c, a->t, a->x, a->dx);
    indicators(c, a->t, a->x, z);
    memset(domains, 0, nz * sizeof *domains);
    track_domains(domains, z);
}

/* The end of the next step from t: the steps to the output point `next` evenly spaced, none longer than h */
static double step_end(double t, double next, double h)
{
    double n = ceil((next - t) / h * (1.0 - 1e-12));
    return n <= 1.0 ? next : t + (next - t) / n;
}

/* After fmi3ExitInitializationMode (the instance is in Event Mode): the event iteration, then RK4 steps of
 * $HOST_ME_STEP s to each output point; a step across a state event is cut back to the event, where the
 * instance goes through Event Mode and the integrator restarts. The FMU holds the last point set, so the
 * outputs read at an output point are those of the accepted point (or of the event update) there. */
static void run_me(Instance c)
{
    const char *h_text = getenv("HOST_ME_STEP"), *counter_text = getenv("HOST_ME_COUNTER");
    const double h = h_text ? strtod(h_text, NULL) : step;
    VR counter = counter_text ? (VR)strtoul(counter_text, NULL, 10) : 0;
    check("fmi3GetNumberOfContinuousStates", fmi.n_states(c, &nx));
    check("fmi3GetNumberOfEventIndicators", fmi.n_indicators(c, &nz));
    if (nx > MAX_STATES || nz > MAX_INDICATORS) {
        say("failed sizes %zu states %zu indicators\n", nx, nz);
        exit(1);
    }
    Point a = {.t = 0.0}, b;
    int domains[MAX_INDICATORS];
    double z[MAX_INDICATORS];
    if (!event_iteration(c)) return;
    restart(c, &a, domains);
    say("x %.17g %.17g\n", a.t, read_output(c));
    for (long n = 0; !done(a.t, stop_time);) {
        double next = next_point(n, stop_time);
        rk4(c, &a, step_end(a.t, next, h), &b);
        indicators(c, b.t, b.x, z);
        if (crossed(domains, z)) {
            double x[MAX_STATES];
            a.t = locate(c, &a, &b, domains, x);
            put(c, a.t, x);
            check("fmi3EnterEventMode", fmi.enter_event_mode(c));
            bool go_on = event_iteration(c);
            if (counter_text) {
                int32_t count;
                check("fmi3GetInt32", fmi.get_int32(c, &counter, 1, &count, 1));
                say("e %.17g %d\n", a.t, (int)count);
            }
            if (!go_on) break;
            restart(c, &a, domains);
        } else {
            a = b;
            track_domains(domains, z);
        }
        if (a.t == next) {
            say("x %.17g %.17g\n", a.t, read_output(c));
            ++n;
        }
    }
}

/* Co-simulation steps from *t (the n-th communication point) until `until`, each output printed after `tag` */
static long steps_to(Instance c, double *t, long n, double until, const char *tag)
{
    for (; !done(*t, until); ++n) {
        double next = next_point(n, until), last_successful;
        bool event_needed, terminate, returned_early;
        check("fmi3DoStep", fmi.do_step(c, *t, next - *t, true, &event_needed, &terminate, &returned_early,
                                        &last_successful));
        *t = next;
        if (tag) say("%s %.17g %.17g\n", tag, *t, read_output(c));
    }
    return n;
}

/* Mode "state": the FMU state at STOP/2 (got and serialized), the run on to STOP ("x"), again from the state got
 * ("r") and from the deserialized one ("d") */
static void mode_state(void)
{
    Instance c = instantiate("state");
    check("fmi3ExitInitializationMode", initialize(c, n_settings));
    double t = 0.0, t_saved;
    long n = steps_to(c, &t, 0, stop_time / 2, NULL);
    void *state = NULL, *restored = NULL;
    size_t size;
    check("fmi3GetFMUState", fmi.get_state(c, &state));
    check("fmi3SerializedFMUStateSize", fmi.state_size(c, state, &size));
    unsigned char *bytes = malloc(size);
    check("fmi3SerializeFMUState", fmi.serialize(c, state, bytes, size));
    t_saved = t;
    steps_to(c, &t, n, stop_time, "x");
    check("fmi3SetFMUState", fmi.set_state(c, state));
    t = t_saved;
    steps_to(c, &t, n, stop_time, "r");
    check("fmi3DeserializeFMUState", fmi.deserialize(c, bytes, size, &restored));
    check("fmi3SetFMUState", fmi.set_state(c, restored));
    t = t_saved;
    steps_to(c, &t, n, stop_time, "d");
    check("fmi3FreeFMUState", fmi.free_state(c, &state));
    check("fmi3FreeFMUState", fmi.free_state(c, &restored));
    free(bytes);
    check("fmi3Terminate", fmi.terminate(c));
    fmi.free_instance(c);
}

static int step_for_costs(void *c, double t, double h)
{
    bool event = false, terminate = false, early = false;
    double reached = 0.0;
    return fmi.do_step(c, t, h, true, &event, &terminate, &early, &reached);
}
static int serialize_for_costs(void *c, void *s, void *bytes, size_t n) { return fmi.serialize(c, s, bytes, n); }
static int deserialize_for_costs(void *c, const void *bytes, size_t n, void **s)
{
    return fmi.deserialize(c, bytes, n, s);
}

/* Mode "state_costs": the run to STOP, then the costs of the FMU-state calls (state_costs in host_common.h) */
static void mode_state_costs(void)
{
    Instance c = instantiate("costs");
    check("fmi3ExitInitializationMode", initialize(c, n_settings));
    double t = 0.0;
    steps_to(c, &t, 0, stop_time, NULL);
    StateCalls calls = {{"fmi3DoStep", "fmi3GetFMUState", "fmi3SetFMUState", "fmi3SerializedFMUStateSize",
                         "fmi3SerializeFMUState", "fmi3DeserializeFMUState"},
                        step_for_costs, fmi.get_state, fmi.set_state, fmi.free_state, fmi.state_size,
                        serialize_for_costs, deserialize_for_costs};
    state_costs(c, t, &calls);
    check("fmi3Terminate", fmi.terminate(c));
    fmi.free_instance(c);
}

static void run_one(const char *name)
{
    Instance c = instantiate(name);
    check("fmi3ExitInitializationMode", initialize(c, n_settings));
    if (model_exchange)
        run_me(c);
    else if (early_return)
        run_cs_early(c);
    else
        run_cs(c);
    check("fmi3Terminate", fmi.terminate(c));
    fmi.free_instance(c);
}

static void *run_on_thread(void *name)
{
    run_one(name);
    return NULL;
}

static void mode_bad(void)
{
    Instance c = instantiate("bad");
    say("status exit %d\n", initialize(c, n_settings));
    fmi.free_instance(c);
    --n_settings;
    run_one("good");
}

static void *step_call(void *call)
{
    StepCall *s = call;
    bool event_needed, terminate, early_return;
    double last_successful;
    check("fmi3DoStep", fmi.do_step(s->instance, s->t, s->h, true, &event_needed, &terminate, &early_return,
                                    &last_successful));
    return NULL;
}

static void mode_thread_steps(void)
{
    Instance c = instantiate("threads");
    check("fmi3ExitInitializationMode", initialize(c, n_settings));
    steps_from_new_threads(c, step_call, read_output);
    check("fmi3Terminate", fmi.terminate(c));
    fmi.free_instance(c);
}

int main(int argc, char **argv)
{
    static const char *const names[] = {
        "fmi3InstantiateCoSimulation", "fmi3FreeInstance", "fmi3EnterInitializationMode", "fmi3ExitInitializationMode",
        "fmi3Terminate", "fmi3DoStep", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3SetInt64",
        "fmi3InstantiateModelExchange", "fmi3GetInt32", "fmi3GetNumberOfContinuousStates",
        "fmi3GetNumberOfEventIndicators", "fmi3UpdateDiscreteStates", "fmi3EnterEventMode",
        "fmi3EnterContinuousTimeMode", "fmi3SetTime", "fmi3GetContinuousStates", "fmi3SetContinuousStates",
        "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators", "fmi3EnterStepMode", "fmi3GetFMUState",
        "fmi3SetFMUState", "fmi3FreeFMUState", "fmi3SerializedFMUStateSize", "fmi3SerializeFMUState",
        "fmi3DeserializeFMUState"};
    if (!start_host(argc, argv, names, sizeof names / sizeof *names, (void **)&fmi)) return argc < 8 ? 2 : 1;
    model_exchange = !strncmp(mode, "me-", 3);
    const char *what = model_exchange ? mode + 3 : mode;
    early_return = !strcmp(mode, "early") || !strcmp(mode, "events");
    event_mode = !strcmp(mode, "events");
    if (!strcmp(what, "run") || early_return) run_one("run");
    else if (!strcmp(what, "bad")) mode_bad();
    else if (!strcmp(mode, "state")) mode_state();
    else if (!strcmp(mode, "state_costs")) mode_state_costs();
    else if (!strcmp(mode, "thread_steps")) mode_thread_steps();
    else if (!strcmp(mode, "unload")) unload_after_runs(run_on_thread);
    else {
        fprintf(stderr, "unknown mode %s\n", mode);
        return 2;
    }
    say("done\n");
    return 0;
}
