/* What the C hosts (host.c: FMI 2, host3.c: FMI 3) share: printing, failing, FMPy's communication points. */
#ifndef SBF_HOST_COMMON_H
#define SBF_HOST_COMMON_H
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

static double step; /* communication step, s */

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

#endif
