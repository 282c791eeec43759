/* The loader's fast path: a communication step and the reads of the outputs after it, without the inner library.
 *
 * The inner library (PythonFMU, pythonfmu3) turns every FMI call into a Python method call on the slave: its
 * arguments into Python lists, the results back, its log queue drained. Per step that costs more than the step.
 * The slave therefore offers itself to the loader while the inner library constructs it (sbf_bind_slave, called
 * from fmu_src/block_interface.py, offer_to_loader), with the value reference of its first output and the
 * outputs' kinds. The loader then
 *   - takes a communication step by one call of the slave's step call (the first of the calls fast_step_call()
 *     gives: the runtime's compiled Trajectory.communicate, which checks the step, advances and returns the
 *     first outputs, x and v), and keeps them in a buffer of its own;
 *   - answers reads of outputs from that buffer, without entering Python; a read of another output asks the
 *     second call (Trajectory.outputs: every output at the current state) once per step;
 *   - keeps the values of the inputs a host sets between steps where they surely pass the slave's checks, and
 *     hands them to the slave with the next step, in the same call into Python (sbf_keep_inputs, below);
 *   - before forwarding any other call to the inner library, hands the slave the inputs it kept, tells it that
 *     the state moved (its own caches of the outputs are stale: outputs_changed()) and, unless the call only
 *     reads, forgets the step call and the buffer: inputs, parameters, a restored state or a reset change what
 *     the next step starts from, and the slave gives a new step call for it.
 * The outputs are the very values the slave's getters answer (the same conversions as the inner library's),
 * so results do not depend on which path a call takes. Where the slave offers nothing (a pythonfmu binary
 * without this loader's symbol, a CPython without the functions below) or SBF_FAST_PATH=0 is in the environment,
 * every step and read goes the inner library's way. The input and output derivatives and FMI 2's model exchange,
 * which the inner library lacks, go to the bound slave's methods either way (sbf_slave_derivatives,
 * sbf_slave_exchange).
 */
#ifndef SBF_FAST_PATH_H
#define SBF_FAST_PATH_H
#include <stddef.h>

#define SBF_MAX_OUTPUTS 64
#define SBF_MAX_KEPT 4 /* inputs the loader may keep between steps (sbf_keep_inputs) */
#define SBF_MAX_FREED 8 /* FMU states freed by the host whose references wait for the loader's next call into Python */
/* The environment variable that turns the fast path off for the process when it is "0" (to compare the paths) */
#define SBF_FAST_PATH_VARIABLE "SBF_FAST_PATH"

typedef struct {
    void *slave;     /* the slave (a PyObject reference held), NULL while none is bound */
    void *step;      /* the slave's step call for the next steps (a reference held), NULL until asked for */
    void *outputs;   /* with it, the call that gives every output at the current state (a reference held) */
    unsigned first;  /* value reference of the first output; the others follow */
    size_t n;        /* number of outputs */
    char kinds[SBF_MAX_OUTPUTS]; /* 'r' real, 'i' integer, per output */
    double reals[SBF_MAX_OUTPUTS];
    long integers[SBF_MAX_OUTPUTS];
    size_t fresh; /* the first `fresh` outputs in reals/integers hold their values at the current state; 0 unless the
                   * state is the one the last fast step left (then the other outputs can be asked for) */
    int moved; /* a fast step moved the state since the slave last heard of it */
    const char *folder; /* the instance's resources folder (owned by the instance; kept when the slave is dropped) */
    void *rewind;    /* with them, the trajectory's restore (a reference held), NULL if the slave gave none */
    void *clean_state; /* the FMU state got last while the step call was kept (a reference held), or NULL */
    void *save, *restore;   /* the slave's save_state and restore_state (references held), NULL if it has none */
    void *to_bytes, *from_bytes; /* with them, its _fmu_state_to_bytes and state_from_bytes (references held) */
    struct sbf_state_plan *plan; /* with them, the plan of its states' bytes (state_bytes.h), NULL if it has none */
    void *serialized_state; /* the FMU state serialized last (a reference held), NULL if none */
    unsigned char *serialized; /* its bytes (malloc'd) */
    size_t serialized_size, serialized_room;
    void *freed[SBF_MAX_FREED]; /* FMU states the host freed, their references dropped at the next state call */
    int n_freed;
    /* the inputs kept in C until the next step (sbf_keep_inputs), by the slave's rules (its kept_inputs()) */
    int rules_asked;                 /* the slave was asked for them (since it bound or a state was set) */
    size_t n_rules;                  /* the inputs it lets the loader keep (0: none) */
    unsigned rule_vr[SBF_MAX_KEPT];  /* each one's value reference, */
    int rule_order[SBF_MAX_KEPT];    /* the order of its derivative set (0: the value itself), */
    double rule_bound[SBF_MAX_KEPT]; /* the magnitude up to which a finite value surely passes the slave's checks */
    double kept[SBF_MAX_KEPT];       /* the value kept of each rule's input, */
    size_t kept_order[SBF_MAX_KEPT]; /* and the rules of the inputs kept, in the order they were last set */
    size_t n_kept;
} sbf_fast_path;

/* Resolve the CPython functions the fast path calls from `libpython` (sbf_open_library's or sbf_process_python's
 * handle); without them the fast path stays off. Called once, from sbf_start. */
void sbf_fast_resolve(void *libpython);

/* The instance whose slave the inner library constructs next on this thread (NULL when done): set around the
 * inner library's instantiation and reset, when the slave calls sbf_bind_slave. */
void sbf_fast_binding(sbf_fast_path *fast);

/* Called by the slave while it binds (sbf_bind_slave): the resources folder of the instance being made on this
 * thread, byte for byte as the host named it (the inner library may have been given another path to it), or NULL. */
const char *sbf_bound_folder(void);

/* A communication step from `t` by `h` (s), with the inputs kept handed over in the same call (the slave's
 * step_kept): -1 if the fast path cannot take it (forward the call instead; the inputs kept are the slave's by
 * then), 0 if taken, 1 if the step failed, with the slave's exception as "[doStep] <repr>" in `why`. */
int sbf_fast_step(sbf_fast_path *fast, double t, double h, char *why, size_t why_size);

/* Before a call is forwarded to the inner library: the slave takes the inputs kept (take_kept; the step call is
 * then forgotten) and hears that the state moved; if `changes` (the call may change the state, parameters or
 * inputs), the step call and the buffer are forgotten. */
void sbf_fast_forward(sbf_fast_path *fast, int changes);

/* 1 with the `n` values of the outputs `vr` in `values` if the buffer holds them all (each of kind 'r', or 'i'
 * for sbf_fast_integers), after asking for every output if the step left only the first; else 0 (forward the
 * call). */
int sbf_fast_reals(sbf_fast_path *fast, const unsigned *vr, size_t n, double *values);
int sbf_fast_integers(sbf_fast_path *fast, const unsigned *vr, size_t n, int *values);

/* The FMI function `function` answered by the slave's `method` (set_real_input_derivatives or
 * get_real_output_derivatives, fmu_src/SpringBlockFriction.py) on the value references vr[0..n) and their derivatives' orders: for a write (`writes`), with values[0..n); else the
 * values into values[0..n). 0 if done, 2 if done with a warning (its text in `why`), 1 if refused (the slave's
 * exception as "[<function>] <repr>" in `why`). Needs a bound slave, whether or not the fast path steps. */
int sbf_slave_derivatives(sbf_fast_path *fast, const char *function, const char *method, const unsigned *vr, size_t n,
                          const int *order, double *values, int writes, char *why, size_t why_size);

/* The FMI 2 model-exchange call `function` (fmi2GetDerivatives...), which the inner library lacks, answered by the
 * bound slave's model_exchange(function, values, count) (fmu_src/SpringBlockFriction.py): `in[0..n_in)` the numbers
 * the host gave, `count` the length of the call's array, the `n_out` numbers the slave answers into out[0..n_out).
 * 0 if done; 1 if refused, with the slave's exception as "[<function>] <repr>" in `why` (no Python exception is
 * left pending). Needs a bound slave, whether or not the fast path steps. */
int sbf_slave_exchange(sbf_fast_path *fast, const char *function, const double *in, size_t n_in, size_t count,
                       double *out, size_t n_out, char *why, size_t why_size);

/* fmi3DoStep with early return: the bound slave's step_to_event (fmu_src/SpringBlockFriction_fmi3.py) from `t` by
 * `h` (s), with the inputs kept handed over in the same call, `event_mode`: the instance uses event mode (the step also stops at an event at t + h, and the event is left
 * for sbf_slave_apply_events). 0 with the time reached in *reached, *stopped = 1 if it stopped at an event there
 * (short of t + h, or with `event_mode` at it), and every output there in the buffer (the reads after the step are
 * answered from it, as after sbf_fast_step); -1 if no slave is bound (take the step another way); 1 if the step
 * failed, with the slave's exception as "[doStep] <repr>" in `why`. */
int sbf_slave_event_step(sbf_fast_path *fast, double t, double h, int event_mode, double *reached, int *stopped,
                         char *why, size_t why_size);

/* fmi3UpdateDiscreteStates of a co-simulation instance in Event Mode: the bound slave's apply_step_events. 0 if done,
 * 1 if it failed (the slave's exception as "[updateDiscreteStates] <repr>" in `why`, or no slave is bound). */
int sbf_slave_apply_events(sbf_fast_path *fast, char *why, size_t why_size);

/* The time the FMU is at (s), the bound slave's answer to fmu_time() (fmu_src/block_interface.py): the end of the
 * last step or of the part of a failed step it went, whichever path took it, or a restored state's time. 1 with it
 * in *t; 0 if there is no bound slave or its answer is no number (no Python exception is left pending). */
int sbf_slave_time(sbf_fast_path *fast, double *t);

/* FMU states answered by the bound slave, without the inner library (unless SBF_FAST_PATH=0): a state is the slave's
 * save_state() (fmu_src/block_interface.py), a Python object that nothing changes, the very object the inner library
 * makes a state of (its _get_fmu_state), so that states of either way mix. Each gives -1 if the slave does not answer
 * (forward the call), 0 if done, 1 if refused, with the slave's exception as "[<function>] <repr>" in `why`.
 *   get: the state into *state; set: restore_state(state), after which the step call is kept only if the slave says
 *   it still holds; free: the reference dropped, *state = NULL; size and serialize: the bytes of
 *   _fmu_state_to_bytes(state), made once for both calls; deserialize: state_from_bytes(bytes) into *state. Where
 *   the slave gives its states' plan, the loader packs and unpacks the states whose shared parts it saw last itself
 *   (state_bytes.h), to the same bytes and states.
 * A state got while the step call was kept, set again while it still is (only steps and reads in between), differs
 * from the instance in its trajectory alone: set restores that (the third call of fast_step_call(), the trajectory's
 * compiled restore, of the state's trajectory part) without the slave's restore_state; the slave hears that the
 * state moved as after a step. */
int sbf_state_get(sbf_fast_path *fast, void **state, char *why, size_t why_size);
int sbf_state_set(sbf_fast_path *fast, void *state, char *why, size_t why_size);
/* Free: the state's reference waits (at most SBF_MAX_FREED of them) for the next state call, which drops it under the
 * GIL it takes anyway (the GIL is taken once per Deserialize + Free, Get + Free); unbinding drops them too. */
int sbf_state_free(sbf_fast_path *fast, void **state);
int sbf_state_size(sbf_fast_path *fast, void *state, size_t *size, char *why, size_t why_size);
int sbf_state_serialize(sbf_fast_path *fast, void *state, void *bytes, size_t size, char *why, size_t why_size);
int sbf_state_deserialize(sbf_fast_path *fast, const void *bytes, size_t size, void **state, char *why,
                          size_t why_size);

/* The block's real inputs kept in C between steps: a master sets F_ext and its rate before every step, each set a
 * call into the slave's Python as costly as the step. The slave tells the loader once (kept_inputs(), after
 * initialization: fmu_src/block_interface.py) which inputs it may keep and the magnitude up to which a finite value
 * surely passes its checks; the loader keeps such values and hands them over in the order they were last set with
 * the next step, in the same call into Python (the slave's step_kept, or step_to_event's `sets`), or before any other
 * call that reaches the slave (sbf_fast_forward: the slave's take_kept). Any other value, and any call that is not
 * all kept inputs, goes to the slave as before (refused there with its message).
 *   sbf_keep_inputs: 1 if the n values of the inputs vr[0..n) (order[i] the order of the derivative set, or the
 *   values themselves where `order` is NULL) were kept (the outputs' buffer then stale); 0 if nothing was kept
 *   (forward the call). Only for a co-simulation instance in Step Mode (the front checks), with the fast path on.
 *   sbf_state_get hands the kept inputs over first (a state holds every input set, also one the inner library
 *   takes); a state set drops them (the state sets every input), and, unless it rewound, has the rules asked again
 *   (the state's parameters may differ). */
int sbf_keep_inputs(sbf_fast_path *fast, const unsigned *vr, const int *order, size_t n, const double *values);

/* Drop the slave and its step call (freeing the instance). */
void sbf_fast_unbind(sbf_fast_path *fast);
/* Drop them and bind the slave the inner library constructs next on this thread (around a reset, which makes a new
 * slave); sbf_fast_binding(NULL) after. */
void sbf_fast_rebinding(sbf_fast_path *fast);

#endif
