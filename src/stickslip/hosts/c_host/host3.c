/* A plain C FMI 3.0 co-simulation importer: as host.c (FMI 2), it opens an FMU's binary with
 * dlopen(RTLD_NOW | RTLD_LOCAL), nothing preloaded, no Python of its own, and drives it the way FMPy's
 * simulate_fmu does (same communication points, so results compare bit for bit).
 *
 *   host3 BINARY RESOURCE_PATH TOKEN MODE STOP STEP OUTPUT_VR [rVR=VALUE | iVR=VALUE ...]
 *
 * RESOURCE_PATH is the FMU's resources folder with a trailing slash (FMI 3 passes a path, not a URI).
 * MODE   what it does (every logged message is printed as "log STATUS INSTANCE TEXT")
 * run    one co-simulation instance, logging off; prints "x T X" at every communication point
 * bad    one instance with all settings, the last one invalid, logging off: prints "status exit CODE" of
 *        fmi3ExitInitializationMode, frees it, then runs a new instance without the last setting ("x" lines)
 * Every line is flushed. The exit code is 0 when the mode ran to its end (a failing FMI call ends the
 * program with "failed FUNCTION STATUS" and code 1). */
#define _GNU_SOURCE
#include <dlfcn.h>
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
    Status (*set_int32)(Instance, const VR *, size_t, const int32_t *, size_t);
} fmi;


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
    Instance c = fmi.instantiate(name, token, resources, false, false, false, false, NULL, 0, (void *)name,
                                 log_message, NULL);
    if (!c) {
        say("failed fmi3InstantiateCoSimulation NULL\n");
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
            int32_t v = atoi(value);
            check("fmi3SetInt32", fmi.set_int32(c, &vr, 1, &v, 1));
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

static void run_one(const char *name)
{
    Instance c = instantiate(name);
    check("fmi3ExitInitializationMode", initialize(c, n_settings));
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
    check("fmi3Terminate", fmi.terminate(c));
    fmi.free_instance(c);
}

static void mode_bad(void)
{
    Instance c = instantiate("bad");
    say("status exit %d\n", initialize(c, n_settings));
    fmi.free_instance(c);
    --n_settings;
    run_one("good");
}

int main(int argc, char **argv)
{
    static const char *const names[] = {
        "fmi3InstantiateCoSimulation", "fmi3FreeInstance", "fmi3EnterInitializationMode", "fmi3ExitInitializationMode",
        "fmi3Terminate", "fmi3DoStep", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3SetInt32"};
    if (!start_host(argc, argv, names, sizeof names / sizeof *names, (void **)&fmi)) return argc < 8 ? 2 : 1;
    if (!strcmp(mode, "run")) run_one("run");
    else if (!strcmp(mode, "bad")) mode_bad();
    else {
        fprintf(stderr, "unknown mode %s\n", mode);
        return 2;
    }
    say("done\n");
    return 0;
}
