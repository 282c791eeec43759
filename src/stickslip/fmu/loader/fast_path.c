/* The loader's fast path (fast_path.h): the slave's step call made directly, the outputs kept in C. */
#define _GNU_SOURCE
#include "fast_path.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "platform.h"
#include "state_bytes.h"

/* ---- CPython: the functions the fast path calls (stable C API) ---- */
typedef void PyObject;
static struct {
    int (*PyGILState_Ensure)(void);
    void (*PyGILState_Release)(int);
    PyObject *(*PyObject_CallMethod)(PyObject *, const char *, const char *, ...);
    PyObject *(*PyObject_CallFunctionObjArgs)(PyObject *, ...);
    PyObject *(*PyFloat_FromDouble)(double);
    PyObject *(*PyLong_FromLong)(long);
    PyObject *(*PyTuple_New)(ptrdiff_t);
    int (*PyTuple_SetItem)(PyObject *, ptrdiff_t, PyObject *);
    double (*PyFloat_AsDouble)(PyObject *);
    long (*PyLong_AsLong)(PyObject *);
    ptrdiff_t (*PyTuple_Size)(PyObject *);
    PyObject *(*PyTuple_GetItem)(PyObject *, ptrdiff_t);
    void (*Py_IncRef)(PyObject *);
    void (*Py_DecRef)(PyObject *);
    PyObject *(*PyErr_Occurred)(void);
    void (*PyErr_Fetch)(PyObject **, PyObject **, PyObject **);
    void (*PyErr_NormalizeException)(PyObject **, PyObject **, PyObject **);
    void (*PyErr_Clear)(void);
    PyObject *(*PyObject_Repr)(PyObject *);
    PyObject *(*PyObject_Str)(PyObject *);
    const char *(*PyUnicode_AsUTF8)(PyObject *);
    int (*PyObject_IsTrue)(PyObject *);
    PyObject *(*PyObject_GetAttrString)(PyObject *, const char *);
    PyObject *(*PyBytes_FromStringAndSize)(const char *, ptrdiff_t);
    ptrdiff_t (*PyBytes_Size)(PyObject *);
    char *(*PyBytes_AsString)(PyObject *);
} py;
static PyObject *py_none; /* Py_None */
static int available;     /* every function above was found: slaves can bind */
static int stepping;      /* and steps and reads take the fast path (not turned off by SBF_FAST_PATH=0) */

void sbf_fast_resolve(void *lib)
{
    const char *setting = getenv(SBF_FAST_PATH_VARIABLE);
    stepping = !(setting && strcmp(setting, "0") == 0); /* off: steps and reads go the inner library's way */
#define RESOLVE(symbol) (*(void **)&py.symbol = sbf_symbol(lib, #symbol)) != NULL
    available = RESOLVE(PyGILState_Ensure) && RESOLVE(PyGILState_Release) && RESOLVE(PyObject_CallMethod) &&
                RESOLVE(PyObject_CallFunctionObjArgs) && RESOLVE(PyFloat_FromDouble) && RESOLVE(PyFloat_AsDouble) &&
                RESOLVE(PyLong_FromLong) && RESOLVE(PyTuple_New) && RESOLVE(PyTuple_SetItem) &&
                RESOLVE(PyLong_AsLong) && RESOLVE(PyTuple_Size) && RESOLVE(PyTuple_GetItem) && RESOLVE(Py_IncRef) &&
                RESOLVE(Py_DecRef) && RESOLVE(PyErr_Occurred) && RESOLVE(PyErr_Fetch) &&
                RESOLVE(PyErr_NormalizeException) && RESOLVE(PyErr_Clear) && RESOLVE(PyObject_Repr) &&
                RESOLVE(PyObject_Str) && RESOLVE(PyUnicode_AsUTF8) && RESOLVE(PyObject_IsTrue) &&
                RESOLVE(PyObject_GetAttrString) &&
                RESOLVE(PyBytes_FromStringAndSize) && RESOLVE(PyBytes_Size) && RESOLVE(PyBytes_AsString) &&
                (py_none = sbf_symbol(lib, "_Py_NoneStruct")) != NULL;
#undef RESOLVE
    sbf_state_bytes_resolve(lib); /* without its functions, the slave's Python makes every state's bytes */
}

static PyObject *kept_sets(sbf_fast_path *fast); /* the inputs kept, as the slave takes them (below) */

/* ---- binding: the slave offers itself while the inner library constructs it ---- */
static SBF_THREAD_LOCAL sbf_fast_path *binding;

void sbf_fast_binding(sbf_fast_path *fast) { binding = fast; }

SBF_EXPORT const char *sbf_bound_folder(void) { return binding ? binding->folder : NULL; }

/* Forget the bytes of the state serialized last (under the GIL) */
static void drop_serialized(sbf_fast_path *fast)
{
    if (fast->serialized_state) py.Py_DecRef(fast->serialized_state);
    free(fast->serialized);
    fast->serialized_state = NULL;
    fast->serialized = NULL;
    fast->serialized_size = fast->serialized_room = 0;
}

/* Drop the references of the FMU states the host freed since the last state call (under the GIL) */
static void drop_freed(sbf_fast_path *fast)
{
    while (fast->n_freed) py.Py_DecRef(fast->freed[--fast->n_freed]);
}

/* Forget the slave's state calls and the plan of its states' bytes (under the GIL) */
static void drop_state_calls(sbf_fast_path *fast)
{
    void **calls[] = {&fast->save, &fast->restore, &fast->to_bytes, &fast->from_bytes};
    for (size_t i = 0; i < sizeof calls / sizeof *calls; ++i) {
        if (*calls[i]) py.Py_DecRef(*calls[i]);
        *calls[i] = NULL;
    }
    sbf_plan_free(fast->plan);
    fast->plan = NULL;
}

/* Forget the state got last while the step call was kept (under the GIL) */
static void drop_clean_state(sbf_fast_path *fast)
{
    if (fast->clean_state) py.Py_DecRef(fast->clean_state);
    fast->clean_state = NULL;
}

/* Forget the step, outputs and rewind calls, and with them the clean state (under the GIL) */
static void drop_step_call(sbf_fast_path *fast)
{
    void **calls[] = {&fast->step, &fast->outputs, &fast->rewind};
    for (size_t i = 0; i < sizeof calls / sizeof *calls; ++i) {
        if (*calls[i]) py.Py_DecRef(*calls[i]);
        *calls[i] = NULL;
    }
    drop_clean_state(fast);
}

/* Called by the slave (through ctypes.PyDLL, the GIL held) while the inner library constructs it on this thread:
 * `slave` is the slave object, `first` the value reference of its first output, `kinds` one letter per output
 * ('r' real, 'i' integer). 1 if bound; 0 if no instance of this library is being made here or the offer is
 * malformed. */
SBF_EXPORT int sbf_bind_slave(PyObject *slave, unsigned first, const char *kinds)
{
    sbf_fast_path *fast = binding;
    size_t n = kinds ? strlen(kinds) : 0;
    if (!fast || !available || !slave || n == 0 || n > SBF_MAX_OUTPUTS || strspn(kinds, "ri") != n) return 0;
    drop_step_call(fast);
    drop_serialized(fast);
    drop_freed(fast);
    if (fast->slave) py.Py_DecRef(fast->slave);
    drop_state_calls(fast);
    py.Py_IncRef(slave);
    *fast = (sbf_fast_path){.slave = slave, .first = first, .n = n, .folder = fast->folder};
    memcpy(fast->kinds, kinds, n);
    fast->save = py.PyObject_GetAttrString(slave, "save_state"); /* none: the states go the inner library's way */
    fast->restore = fast->save ? py.PyObject_GetAttrString(slave, "restore_state") : NULL;
    fast->to_bytes = fast->restore ? py.PyObject_GetAttrString(slave, "_fmu_state_to_bytes") : NULL;
    fast->from_bytes = fast->to_bytes ? py.PyObject_GetAttrString(slave, "state_from_bytes") : NULL;
    if (!fast->from_bytes) drop_state_calls(fast);
    fast->plan = fast->from_bytes ? sbf_plan_new(slave) : NULL;
    py.PyErr_Clear();
    return 1;
}

/* ---- the step ---- */

/* The pending Python exception in `why`, cleared: "[<call>] <repr>" as the inner libraries word a failed call, or
 * its message alone where `call` is NULL (a refusal whose message says it all). */
static void exception_text(const char *call, char *why, size_t size)
{
    PyObject *type = NULL, *value = NULL, *traceback = NULL;
    py.PyErr_Fetch(&type, &value, &traceback);
    py.PyErr_NormalizeException(&type, &value, &traceback);
    PyObject *shown = value ? (call ? py.PyObject_Repr(value) : py.PyObject_Str(value)) : NULL;
    const char *text = shown ? py.PyUnicode_AsUTF8(shown) : NULL;
    if (call)
        snprintf(why, size, "[%s] %s", call, text ? text : "unknown error");
    else
        snprintf(why, size, "%s", text ? text : "unknown error");
    py.PyErr_Clear();
    PyObject *held[] = {shown, type, value, traceback};
    for (size_t i = 0; i < sizeof held / sizeof *held; ++i)
        if (held[i]) py.Py_DecRef(held[i]);
}

/* The first outputs `result` (a tuple of 1 to fast->n numbers, or NULL after an exception) into the buffer,
 * `fresh` set to their count; 0 (`fresh` 0; a Python exception set, or none if the tuple's length is wrong) if
 * they are not that. */
static int keep_outputs(sbf_fast_path *fast, PyObject *result)
{
    ptrdiff_t k = result ? py.PyTuple_Size(result) : 0;
    fast->fresh = 0;
    if (k < 1 || k > (ptrdiff_t)fast->n) return 0;
    for (size_t i = 0; i < (size_t)k; ++i) {
        PyObject *item = py.PyTuple_GetItem(result, (ptrdiff_t)i);
        if (fast->kinds[i] == 'r')
            fast->reals[i] = py.PyFloat_AsDouble(item);
        else
            fast->integers[i] = py.PyLong_AsLong(item);
    }
    if (py.PyErr_Occurred()) return 0;
    fast->fresh = (size_t)k;
    return 1;
}

/* The slave's step call and outputs call (and rewind call, if it gives one), asked for (the calls fast_step_call()
 * gives) if none is kept: 1 if there are, 0 if the slave has none now (its next step goes the inner library's way),
 * -1 on an exception (set, or none for a malformed answer). Under the GIL. */
static int have_step_call(sbf_fast_path *fast)
{
    if (fast->step) return 1;
    PyObject *calls = py.PyObject_CallMethod(fast->slave, "fast_step_call", NULL);
    if (!calls) return -1;
    ptrdiff_t n = calls == py_none ? 0 : py.PyTuple_Size(calls);
    int found = calls == py_none ? 0 : n == 2 || n == 3 ? 1 : -1;
    if (found == 1) {
        fast->step = py.PyTuple_GetItem(calls, 0);
        fast->outputs = py.PyTuple_GetItem(calls, 1);
        fast->rewind = n == 3 ? py.PyTuple_GetItem(calls, 2) : NULL;
        py.Py_IncRef(fast->step);
        py.Py_IncRef(fast->outputs);
        if (fast->rewind) py.Py_IncRef(fast->rewind);
    }
    py.Py_DecRef(calls);
    return found;
}

/* sbf_fast_step with the inputs kept handed over in the same call (the slave's step_kept), under the GIL: -1 if the
 * slave took them but cannot take the step itself (forward it) */
static int kept_step(sbf_fast_path *fast, double t, double h, char *why, size_t why_size)
{
    PyObject *sets = kept_sets(fast);
    PyObject *result = sets ? py.PyObject_CallMethod(fast->slave, "step_kept", "(ddO)", t, h, sets) : NULL;
    if (sets) py.Py_DecRef(sets);
    drop_clean_state(fast); /* the instance's inputs changed since it was got */
    if (result == py_none) {
        py.Py_DecRef(result);
        return -1;
    }
    fast->moved = 1; /* a failed step may have moved the state part of the way */
    int outcome = keep_outputs(fast, result) ? 0 : 1;
    if (outcome) exception_text("doStep", why, why_size);
    if (result) py.Py_DecRef(result);
    if (outcome == 0 && !fast->step && have_step_call(fast) < 0) /* for the reads of the other outputs, and the */
        py.PyErr_Clear();                                           /* steps without inputs set before them */
    return outcome;
}

int sbf_fast_step(sbf_fast_path *fast, double t, double h, char *why, size_t why_size)
{
    if (!fast->slave || !stepping) return -1;
    int gil = py.PyGILState_Ensure();
    if (fast->n_kept) {
        int outcome = kept_step(fast, t, h, why, why_size);
        py.PyGILState_Release(gil);
        return outcome;
    }
    int outcome = -1;
    int found = have_step_call(fast);
    if (found != 0) {
        PyObject *result = NULL;
        if (found == 1) {
            PyObject *time = py.PyFloat_FromDouble(t), *size = py.PyFloat_FromDouble(h);
            if (time && size) result = py.PyObject_CallFunctionObjArgs(fast->step, time, size, NULL);
            if (time) py.Py_DecRef(time);
            if (size) py.Py_DecRef(size);
        }
        fast->moved = 1; /* a failed step may have moved the state part of the way */
        outcome = keep_outputs(fast, result) ? 0 : 1;
        if (outcome) exception_text("doStep", why, why_size);
        if (result) py.Py_DecRef(result);
    }
    py.PyGILState_Release(gil);
    return outcome;
}

/* The inputs kept handed to the slave (its take_kept), under the GIL; the step call is forgotten (the slave gives a
 * new one that applies them, as after a set forwarded). */
static void hand_over(sbf_fast_path *fast)
{
    PyObject *sets = kept_sets(fast);
    PyObject *done = sets ? py.PyObject_CallMethod(fast->slave, "take_kept", "(O)", sets) : NULL;
    if (sets) py.Py_DecRef(sets);
    if (done) py.Py_DecRef(done);
    py.PyErr_Clear(); /* none: kept_inputs allowed every value */
    drop_step_call(fast);
}

void sbf_fast_forward(sbf_fast_path *fast, int changes)
{
    if (changes) fast->fresh = 0;
    if (!fast->moved && !fast->n_kept && !(changes && fast->step)) return;
    int gil = py.PyGILState_Ensure();
    if (fast->moved) {
        PyObject *done = py.PyObject_CallMethod(fast->slave, "outputs_changed", NULL);
        if (done)
            py.Py_DecRef(done);
        else
            py.PyErr_Clear();
        fast->moved = 0;
    }
    if (fast->n_kept) hand_over(fast);
    if (changes) drop_step_call(fast);
    py.PyGILState_Release(gil);
}

void sbf_fast_unbind(sbf_fast_path *fast)
{
    if (fast->slave) {
        int gil = py.PyGILState_Ensure();
        drop_step_call(fast);
        drop_serialized(fast);
        drop_freed(fast);
        drop_state_calls(fast);
        py.Py_DecRef(fast->slave);
        py.PyGILState_Release(gil);
    }
    *fast = (sbf_fast_path){.folder = fast->folder};
}

void sbf_fast_rebinding(sbf_fast_path *fast)
{
    sbf_fast_unbind(fast);
    binding = fast;
}

/* ---- the reads ---- */

/* Every output at the current state into the buffer (the outputs call); 0 if that fails (forward the read). */
static int complete_outputs(sbf_fast_path *fast)
{
    int gil = py.PyGILState_Ensure();
    PyObject *result = py.PyObject_CallFunctionObjArgs(fast->outputs, NULL);
    int kept = keep_outputs(fast, result) && fast->fresh == fast->n;
    if (result) py.Py_DecRef(result);
    if (!kept) {
        py.PyErr_Clear();
        fast->fresh = 0;
    }
    py.PyGILState_Release(gil);
    return kept;
}

/* 1 if every value reference of vr[0..n) is an output of kind `kind` and the buffer holds it at the current state
 * (asked for if the step left only the first outputs) */
static int buffered(sbf_fast_path *fast, char kind, const unsigned *vr, size_t n)
{
    size_t needed = 0; /* outputs 0..needed-1 hold the ones asked for */
    if (!stepping || !fast->fresh || (n && !vr)) return 0;
    for (size_t i = 0; i < n; ++i) {
        if (vr[i] < fast->first || vr[i] - fast->first >= fast->n || fast->kinds[vr[i] - fast->first] != kind)
            return 0;
        if (vr[i] - fast->first >= needed) needed = vr[i] - fast->first + 1;
    }
    return needed <= fast->fresh || complete_outputs(fast);
}

int sbf_fast_reals(sbf_fast_path *fast, const unsigned *vr, size_t n, double *values)
{
    if (!buffered(fast, 'r', vr, n) || (n && !values)) return 0;
    for (size_t i = 0; i < n; ++i) values[i] = fast->reals[vr[i] - fast->first];
    return 1;
}

int sbf_fast_integers(sbf_fast_path *fast, const unsigned *vr, size_t n, int *values)
{
    if (!buffered(fast, 'i', vr, n) || (n && !values)) return 0;
    for (size_t i = 0; i < n; ++i) values[i] = (int)fast->integers[vr[i] - fast->first];
    return 1;
}

/* ---- the slave's time ---- */

int sbf_slave_time(sbf_fast_path *fast, double *t)
{
    if (!fast->slave) return 0;
    int gil = py.PyGILState_Ensure();
    PyObject *result = py.PyObject_CallMethod(fast->slave, "fmu_time", NULL);
    double value = result ? py.PyFloat_AsDouble(result) : 0.0;
    int answered = result && !py.PyErr_Occurred();
    if (answered) *t = value;
    py.PyErr_Clear();
    if (result) py.Py_DecRef(result);
    py.PyGILState_Release(gil);
    return answered;
}

/* 1 (`why` saying so) if no slave is bound to answer `function` */
static int unbound(const sbf_fast_path *fast, const char *function, char *why, size_t why_size)
{
    if (fast->slave) return 0;
    snprintf(why, why_size, "%s: not available: the slave did not bind to this library (a CPython without the "
             "functions the loader calls, or the inner library's own binary)", function);
    return 1;
}

/* ---- FMI 3's early return and event mode ---- */

int sbf_slave_event_step(sbf_fast_path *fast, double t, double h, int event_mode, double *reached, int *stopped,
                         char *why, size_t why_size)
{
    if (!fast->slave) return -1;
    int gil = py.PyGILState_Ensure();
    drop_step_call(fast); /* the first step may start a new trajectory */
    PyObject *sets = kept_sets(fast); /* handed over with the step */
    PyObject *result =
        sets ? py.PyObject_CallMethod(fast->slave, "step_to_event", "(ddiO)", t, h, event_mode, sets) : NULL;
    if (sets) py.Py_DecRef(sets);
    fast->moved = 1; /* a failed step may have moved the state part of the way */
    fast->fresh = 0;
    int outcome = 1;
    if (result && py.PyTuple_Size(result) == 3) {
        double time = py.PyFloat_AsDouble(py.PyTuple_GetItem(result, 0));
        long at_event = py.PyLong_AsLong(py.PyTuple_GetItem(result, 1));
        if (!py.PyErr_Occurred() && keep_outputs(fast, py.PyTuple_GetItem(result, 2)))
            *reached = time, *stopped = at_event != 0, outcome = 0;
    }
    if (outcome) {
        if (!py.PyErr_Occurred()) snprintf(why, why_size, "[doStep] step_to_event gave no (time, stopped, outputs)");
        else exception_text("doStep", why, why_size);
    }
    if (result) py.Py_DecRef(result);
    py.PyGILState_Release(gil);
    return outcome;
}

int sbf_slave_apply_events(sbf_fast_path *fast, char *why, size_t why_size)
{
    if (unbound(fast, "[updateDiscreteStates]", why, why_size)) return 1;
    int gil = py.PyGILState_Ensure();
    PyObject *result = py.PyObject_CallMethod(fast->slave, "apply_step_events", NULL);
    drop_clean_state(fast);
    fast->moved = 1;
    fast->fresh = 0;
    if (!result) exception_text("updateDiscreteStates", why, why_size);
    else py.Py_DecRef(result);
    py.PyGILState_Release(gil);
    return result == NULL;
}

/* ---- the derivatives ---- */

/* A tuple of the `n` numbers `value(i)`, or NULL (an exception set) */
#define NEW_TUPLE(tuple, n, value)                                                                                 \
    do {                                                                                                           \
        tuple = py.PyTuple_New((ptrdiff_t)(n));                                                                    \
        for (size_t i_ = 0; tuple && i_ < (n); ++i_) {                                                             \
            PyObject *item_ = value(i_);                                                                           \
            if (!item_ || py.PyTuple_SetItem(tuple, (ptrdiff_t)i_, item_) != 0) {                                  \
                py.Py_DecRef(tuple);                                                                               \
                tuple = NULL;                                                                                      \
            }                                                                                                      \
        }                                                                                                          \
    } while (0)

/* The slave's answer `result` to `function`'s call: for a read, `n` numbers into `values`; for a write, None or a
 * warning's text into `why`. The outcome as sbf_slave_derivatives gives it; on a refusal `why` says why and no
 * Python exception is left pending. */
static int derivatives_answer(PyObject *result, const char *function, size_t n, double *values, int writes, char *why,
                              size_t why_size)
{
    if (result && writes) {
        if (result == py_none) return 0;
        const char *text = py.PyUnicode_AsUTF8(result);
        if (text) {
            snprintf(why, why_size, "%s", text);
            return 2;
        }
    } else if (result) {
        ptrdiff_t k = py.PyTuple_Size(result);
        if (k == (ptrdiff_t)n) {
            for (size_t i = 0; i < n; ++i) values[i] = py.PyFloat_AsDouble(py.PyTuple_GetItem(result, (ptrdiff_t)i));
            if (!py.PyErr_Occurred()) return 0;
        } else if (k >= 0) {
            snprintf(why, why_size, "[%s] the slave answered %zd values for %zu asked for", function, k, n);
            return 1;
        }
    }
    exception_text(function, why, why_size); /* the exception pending */
    return 1;
}

int sbf_slave_derivatives(sbf_fast_path *fast, const char *function, const char *method, const unsigned *vr, size_t n,
                          const int *order, double *values, int writes, char *why, size_t why_size)
{
    if (unbound(fast, function, why, why_size)) return 1;
    int gil = py.PyGILState_Ensure();
    PyObject *references, *orders, *given = NULL, *result = NULL;
#define REFERENCE(i) py.PyLong_FromLong((long)vr[i])
#define ORDER(i) py.PyLong_FromLong((long)order[i])
#define VALUE(i) py.PyFloat_FromDouble(values[i])
    NEW_TUPLE(references, n, REFERENCE);
    NEW_TUPLE(orders, n, ORDER);
    if (writes) NEW_TUPLE(given, n, VALUE);
#undef REFERENCE
#undef ORDER
#undef VALUE
    if (references && orders && (given || !writes))
        result = py.PyObject_CallMethod(fast->slave, method, writes ? "(OOO)" : "(OO)", references, orders, given);
    int outcome = derivatives_answer(result, function, n, values, writes, why, why_size);
    PyObject *held[] = {references, orders, given, result};
    for (size_t i = 0; i < sizeof held / sizeof *held; ++i)
        if (held[i]) py.Py_DecRef(held[i]);
    py.PyGILState_Release(gil);
    return outcome;
}

/* ---- the inputs kept until the next step ---- */

/* The slave's rules for keeping inputs (its kept_inputs()), asked once, under the GIL: none if it gives none or a
 * malformed answer (no Python exception left pending). */
static void ask_rules(sbf_fast_path *fast)
{
    PyObject *rules = py.PyObject_CallMethod(fast->slave, "kept_inputs", NULL);
    ptrdiff_t n = rules && rules != py_none ? py.PyTuple_Size(rules) : 0;
    ptrdiff_t i = 0;
    for (; i < n && n <= SBF_MAX_KEPT; ++i) {
        PyObject *rule = py.PyTuple_GetItem(rules, i);
        if (!rule || py.PyTuple_Size(rule) != 3) break;
        long vr = py.PyLong_AsLong(py.PyTuple_GetItem(rule, 0)), order = py.PyLong_AsLong(py.PyTuple_GetItem(rule, 1));
        double bound = py.PyFloat_AsDouble(py.PyTuple_GetItem(rule, 2));
        if (py.PyErr_Occurred() || vr < 0 || (unsigned long)vr > UINT_MAX || order < 0 || order > INT_MAX) break;
        fast->rule_vr[i] = (unsigned)vr, fast->rule_order[i] = (int)order, fast->rule_bound[i] = bound;
    }
    fast->rules_asked = 1;
    fast->n_rules = i == n ? (size_t)n : 0;
    py.PyErr_Clear();
    if (rules) py.Py_DecRef(rules);
}

/* The rule that keeps `value` set for the input `vr` (its derivative of order `order`), or -1 if none surely does */
static int rule_for(const sbf_fast_path *fast, unsigned vr, int order, double value)
{
    for (size_t k = 0; k < fast->n_rules; ++k)
        if (fast->rule_vr[k] == vr && fast->rule_order[k] == order)
            return isfinite(value) && fabs(value) <= fast->rule_bound[k] ? (int)k : -1;
    return -1;
}

/* `value` kept for the input of `rule`, which becomes the last set */
static void keep_value(sbf_fast_path *fast, size_t rule, double value)
{
    size_t j = 0;
    while (j < fast->n_kept && fast->kept_order[j] != rule) ++j;
    if (j < fast->n_kept) {
        memmove(fast->kept_order + j, fast->kept_order + j + 1, (fast->n_kept - j - 1) * sizeof *fast->kept_order);
        --fast->n_kept;
    }
    fast->kept_order[fast->n_kept++] = rule;
    fast->kept[rule] = value;
}

int sbf_keep_inputs(sbf_fast_path *fast, const unsigned *vr, const int *order, size_t n, const double *values)
{
    int rules[SBF_MAX_KEPT];
    if (!fast->slave || !stepping || n == 0 || n > SBF_MAX_KEPT || !vr || !values) return 0;
    if (!fast->rules_asked) {
        int gil = py.PyGILState_Ensure();
        ask_rules(fast);
        py.PyGILState_Release(gil);
    }
    for (size_t i = 0; i < n; ++i) /* a derivative's order is 1 or more: 0 is the slave's to refuse */
        if ((order && order[i] < 1) || (rules[i] = rule_for(fast, vr[i], order ? order[i] : 0, values[i])) < 0)
            return 0;
    for (size_t i = 0; i < n; ++i) keep_value(fast, (size_t)rules[i], values[i]);
    fast->fresh = 0; /* outputs may depend on the inputs: read them from the slave, which is handed the inputs first */
    return 1;
}

/* (rule, value) as the slave takes it, or NULL (an exception set) */
static PyObject *kept_pair(size_t rule, double value)
{
    PyObject *pair = py.PyTuple_New(2), *index = py.PyLong_FromLong((long)rule), *number = py.PyFloat_FromDouble(value);
    if (!pair || !index || !number) {
        PyObject *made[] = {pair, index, number};
        for (size_t i = 0; i < sizeof made / sizeof *made; ++i)
            if (made[i]) py.Py_DecRef(made[i]);
        return NULL;
    }
    py.PyTuple_SetItem(pair, 0, index);
    py.PyTuple_SetItem(pair, 1, number);
    return pair;
}

/* The inputs kept, ((rule, value), ...) in the order they were last set (a new reference, or NULL with an exception
 * set), forgotten. Under the GIL. */
static PyObject *kept_sets(sbf_fast_path *fast)
{
    PyObject *sets;
#define KEPT_PAIR(i) kept_pair(fast->kept_order[i], fast->kept[fast->kept_order[i]])
    NEW_TUPLE(sets, fast->n_kept, KEPT_PAIR);
#undef KEPT_PAIR
    fast->n_kept = 0;
    return sets;
}

/* ---- model exchange (FMI 2) ---- */

int sbf_slave_exchange(sbf_fast_path *fast, const char *function, const double *in, size_t n_in, size_t count,
                       double *out, size_t n_out, char *why, size_t why_size)
{
    if (unbound(fast, function, why, why_size)) return 1;
    int gil = py.PyGILState_Ensure();
    PyObject *given, *result = NULL;
#define VALUE(i) py.PyFloat_FromDouble(in[i])
    NEW_TUPLE(given, n_in, VALUE);
#undef VALUE
    if (given)
        result = py.PyObject_CallMethod(fast->slave, "model_exchange", "(sOn)", function, given, (ptrdiff_t)count);
    int outcome = derivatives_answer(result, function, n_out, out, 0, why, why_size);
    PyObject *held[] = {given, result};
    for (size_t i = 0; i < sizeof held / sizeof *held; ++i)
        if (held[i]) py.Py_DecRef(held[i]);
    py.PyGILState_Release(gil);
    return outcome;
}

/* ---- FMU states ---- */

/* 1 if the bound slave answers the FMU-state calls (else they go the inner library's way) */
static int states_taken(const sbf_fast_path *fast) { return fast->restore && stepping; }

int sbf_state_get(sbf_fast_path *fast, void **state, char *why, size_t why_size)
{
    int taken = states_taken(fast) && state;
    if (!taken && !fast->n_kept) return -1;
    int gil = py.PyGILState_Ensure();
    if (fast->n_kept) hand_over(fast); /* a state holds every input set, whoever takes it */
    drop_freed(fast);
    if (!taken) {
        py.PyGILState_Release(gil);
        return -1;
    }
    PyObject *saved = py.PyObject_CallFunctionObjArgs(fast->save, NULL);
    drop_clean_state(fast);
    if (saved) {
        *state = saved; /* the reference the host holds until it frees the state */
        if (fast->rewind) {
            py.Py_IncRef(saved);
            fast->clean_state = saved;
        }
    } else {
        exception_text("GetFMUstate", why, why_size);
    }
    py.PyGILState_Release(gil);
    return saved == NULL;
}

/* 1 if the clean state `state` was set by rewinding the trajectory alone (the FMU state's first item, the block's
 * part, holds the trajectory's part at BLOCK_TRAJECTORY: fmu_src/block_interface.py, block_state); else 0, no
 * exception left pending. Under the GIL. */
enum { BLOCK_TRAJECTORY = 5 };
static int rewound(sbf_fast_path *fast, PyObject *state)
{
    if (state != fast->clean_state || !fast->rewind) return 0;
    PyObject *block = py.PyTuple_GetItem(state, 0);
    PyObject *trajectory = block ? py.PyTuple_GetItem(block, BLOCK_TRAJECTORY) : NULL;
    PyObject *done = trajectory ? py.PyObject_CallFunctionObjArgs(fast->rewind, trajectory, NULL) : NULL;
    if (!done) {
        py.PyErr_Clear();
        return 0; /* the slave's restore_state sets it instead */
    }
    py.Py_DecRef(done);
    fast->fresh = 0;
    fast->moved = 1; /* the slave hears it as after a step */
    return 1;
}

int sbf_state_set(sbf_fast_path *fast, void *state, char *why, size_t why_size)
{
    if (!states_taken(fast)) return -1;
    int gil = py.PyGILState_Ensure();
    drop_freed(fast);
    if (rewound(fast, (PyObject *)state)) {
        fast->n_kept = 0; /* the state sets every input */
        py.PyGILState_Release(gil);
        return 0;
    }
    drop_clean_state(fast); /* the instance may now differ from it in more than its trajectory */
    PyObject *kept = py.PyObject_CallFunctionObjArgs(fast->restore, (PyObject *)state, NULL);
    fast->fresh = 0;
    fast->moved = 0; /* the restore told the slave's caches */
    if (!kept || py.PyObject_IsTrue(kept) != 1) drop_step_call(fast);
    if (!kept) {
        exception_text("SetFMUstate", why, why_size); /* refused: the instance keeps its inputs kept */
    } else {
        py.Py_DecRef(kept);
        fast->n_kept = 0;       /* the state sets every input */
        fast->rules_asked = 0;  /* not rewound: its parameters may differ */
    }
    py.PyErr_Clear();
    py.PyGILState_Release(gil);
    return kept == NULL;
}

int sbf_state_free(sbf_fast_path *fast, void **state)
{
    if (!states_taken(fast) || !state || !*state) return -1;
    if (fast->n_freed == SBF_MAX_FREED) { /* no room to wait: drop them all now */
        int gil = py.PyGILState_Ensure();
        drop_freed(fast);
        py.Py_DecRef(*state);
        py.PyGILState_Release(gil);
    } else {
        fast->freed[fast->n_freed++] = *state; /* dropped by the next state call, under the GIL it takes */
    }
    *state = NULL;
    return 0;
}

/* `size` bytes of `bytes` as those of `state`, serialized last; 0 if out of memory. Under the GIL. */
static int keep_serialized(sbf_fast_path *fast, void *state, const void *bytes, size_t size)
{
    if (size > fast->serialized_room) {
        unsigned char *room = realloc(fast->serialized, size);
        if (!room) return 0;
        fast->serialized = room;
        fast->serialized_room = size;
    }
    memcpy(fast->serialized, bytes, size);
    fast->serialized_size = size;
    py.Py_IncRef(state);
    if (fast->serialized_state) py.Py_DecRef(fast->serialized_state);
    fast->serialized_state = state;
    return 1;
}

/* The bytes of `state` in fast->serialized, made for the first of the calls on the same state (the size is asked
 * for before the bytes): packed by the plan, else by the slave's _fmu_state_to_bytes (the plan then takes its parts
 * from them). 0, or 1 with `why` saying why not. Under the GIL. */
static int state_bytes(sbf_fast_path *fast, void *state, const char *function, char *why, size_t why_size)
{
    drop_freed(fast);
    if (fast->serialized_state == state) return 0;
    const unsigned char *bytes = NULL;
    long size = fast->plan ? sbf_plan_pack(fast->plan, state, &bytes) : -1;
    PyObject *data = NULL;
    if (size < 0) {
        data = py.PyObject_CallFunctionObjArgs(fast->to_bytes, (PyObject *)state, NULL);
        size = data ? (long)py.PyBytes_Size(data) : -1;
        if (size < 0) {
            exception_text(function, why, why_size);
            if (data) py.Py_DecRef(data);
            return 1;
        }
        bytes = (const unsigned char *)py.PyBytes_AsString(data);
        if (fast->plan) sbf_plan_packed(fast->plan, state, bytes, (size_t)size);
    }
    int kept = keep_serialized(fast, state, bytes, (size_t)size);
    if (data) py.Py_DecRef(data);
    if (!kept) snprintf(why, why_size, "%s: out of memory for the state's %ld bytes", function, size);
    return !kept;
}

int sbf_state_size(sbf_fast_path *fast, void *state, size_t *size, char *why, size_t why_size)
{
    if (!states_taken(fast) || !size) return -1;
    if (fast->serialized_state == state) { /* its bytes are kept: no call into Python */
        *size = fast->serialized_size;
        return 0;
    }
    int gil = py.PyGILState_Ensure();
    int outcome = state_bytes(fast, state, "SerializedFMUstateSize", why, why_size);
    if (!outcome) *size = fast->serialized_size;
    py.PyGILState_Release(gil);
    return outcome;
}

int sbf_state_serialize(sbf_fast_path *fast, void *state, void *bytes, size_t size, char *why, size_t why_size)
{
    if (!states_taken(fast) || !bytes) return -1;
    int outcome = 0;
    if (fast->serialized_state != state) { /* else its bytes are kept: no call into Python */
        int gil = py.PyGILState_Ensure();
        outcome = state_bytes(fast, state, "SerializeFMUstate", why, why_size);
        py.PyGILState_Release(gil);
    }
    if (!outcome && fast->serialized_size > size) {
        snprintf(why, why_size, "SerializeFMUstate: size = %zu bytes, but the state takes %zu (the size "
                 "SerializedFMUstateSize gives)", size, fast->serialized_size);
        outcome = 1;
    } else if (!outcome) {
        memcpy(bytes, fast->serialized, fast->serialized_size);
    }
    return outcome;
}

int sbf_state_deserialize(sbf_fast_path *fast, const void *bytes, size_t size, void **state, char *why,
                          size_t why_size)
{
    if (!states_taken(fast) || !state || (size && !bytes)) return -1;
    int gil = py.PyGILState_Ensure();
    drop_freed(fast);
    PyObject *data = NULL, *restored = fast->plan && size ? sbf_plan_unpack(fast->plan, bytes, size) : NULL;
    if (!restored) { /* the slave's unpacking, which the plan takes its parts from, or the reason for a refusal */
        data = py.PyBytes_FromStringAndSize(size ? bytes : "", (ptrdiff_t)size);
        restored = data ? py.PyObject_CallFunctionObjArgs(fast->from_bytes, data, NULL) : NULL;
        if (restored && fast->plan) sbf_plan_unpacked(fast->plan, restored, bytes, size);
    }
    if (restored)
        *state = restored;
    else
        exception_text(NULL, why, why_size); /* "the N bytes are not a serialized FMU state of this FMU: ..." */
    if (data) py.Py_DecRef(data);
    py.PyGILState_Release(gil);
    return restored == NULL;
}
