"""A fuzzer of FMI call sequences and values (issue 20): hypothesis draws sequences of FMI calls, in legal and
illegal orders, with values from the variables' ranges and edge values (0, +-tiny, subnormals, +-huge, nan,
inf), for the FMI 2 FMU's co-simulation (with its input and output derivatives) and model exchange, the FMI 3 FMU's
co-simulation and model exchange, and the coupling FMU (``ChainCoupling.fmu``).

The sequences run in a child process (``fuzz_runner.py``, ctypes with the standard's signatures), one child per
interface kept for many sequences; a sequence that crashes or hangs it is run again alone in a new child (with
every call traced), so each failure is the failing sequence's own. Every sequence must hold:

- no crash (a signal or an abnormal exit) and no hang (:data:`TIMEOUT` s for a sequence);
- no non-finite value written to the host's buffers by a call that returned OK or Warning, and no value written
  past the count the host gave;
- every Error or Fatal status (and a NULL instance) comes with a logged message of that status or worse that
  names a cause: a variable of the model, an FMI function, a value reference or a range;
- the instance, whatever its calls returned, is freed by fmi<N>FreeInstance without a crash (every sequence
  ends so), and the child ends with exit status 0 when its input ends.

Hypothesis also draws cycles of load / instantiate / step on threads / free / unload / reload (:func:`cycles`), each
case in a child process of its own, which must end with exit status 0 after every call returned OK with the
outputs of an independent reference.

The CI run is derandomized (:data:`EXAMPLES` sequences per interface); ``STICKSLIP_FUZZ_EXAMPLES=5000`` runs
that many per interface with a random seed.
"""

import json
import math
import os
import queue
import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from fmpy import read_model_description
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

RUNNER = Path(__file__).with_name("fuzz_runner.py")
TIMEOUT = 20.0  # s for one sequence in a loaded machine: a sequence of the strategies below takes under 1 s
BY_HAND = os.environ.get("STICKSLIP_FUZZ_EXAMPLES")
EXAMPLES = int(BY_HAND or 100)
OK, WARNING, DISCARD, ERROR, FATAL = range(5)

# ---- the child process ---------------------------------------------------------------------------------------


class Worker:
    """One ``fuzz_runner.py`` child for an FMU, kept for many sequences; restarted after a crash or a hang."""

    def __init__(self, version, folder, trace=False, timeout=TIMEOUT):
        self.timeout = timeout
        self.command = [sys.executable, str(RUNNER), str(version), str(folder)] + (["trace"] if trace else [])
        self.proc, self.lines, self.count = None, None, 0

    def __repr__(self):
        return f"Worker({self.command[2:]})"

    def _start(self):
        self.proc = subprocess.Popen(self.command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, cwd=RUNNER.parent)
        self.lines = queue.Queue()
        threading.Thread(target=self._read, args=(self.proc.stdout, self.lines), daemon=True).start()

    @staticmethod
    def _read(stream, lines):
        for line in stream:
            lines.put(line)
        lines.put(None)

    def run(self, calls):
        """``{"calls": [...]}`` of the sequence ``calls``, or ``{"failure": why, "traced": [...]}``."""
        if self.proc is None:
            self._start()
        self.count += 1
        self.proc.stdin.write(json.dumps({"id": self.count, "calls": calls}) + "\n")
        self.proc.stdin.flush()
        traced = []
        while True:
            try:
                line = self.lines.get(timeout=self.timeout)
            except queue.Empty:
                return self._failed(f"hung: no result after {self.timeout} s", traced)
            if line is None:
                return self._failed("crashed", traced)
            said = json.loads(line)
            if said.get("id") == self.count:
                return said
            traced.append(said)

    def _failed(self, what, traced):
        """The failure of the child, which is ended (the next sequence starts a new one)."""
        code = self.close(kill=True)
        how = f"signal {-code}" if code < 0 else f"exit {code}"
        return {"failure": f"the host {what} ({how}); stderr: {self.stderr[-3000:]}", "traced": traced}

    def close(self, kill=False):
        """End the child: its input ends, and it must end within the time limit (else, or if ``kill``, it is
        killed); its exit code (None if none was started), its stderr in ``stderr``."""
        proc, self.proc = self.proc, None
        if proc is None:
            return None
        if kill and proc.poll() is None:
            proc.kill()
        proc.stdin.close()
        try:
            proc.wait(timeout=self.timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
        self.stderr = proc.stderr.read()
        return proc.wait()


# ---- what a sequence must hold -------------------------------------------------------------------------------

RANGE = re.compile(r"allowed|range|[\[(]\s*[-+\w.]+\s*,\s*[-+\w.]+\s*[\])]|valueReference|value reference")
FUNCTION = re.compile(r"\bfmi[23][A-Z]\w+")
ARGUMENT = re.compile(r"FMU state|resource location|instance name|GUID|instantiation token|log categor")
# the loader's "[setReal] " prefix of a slave exception names no cause (the library's method); "[fmi2SetTime] " does (the
# FMI function the loader answered through the slave)
PYTHON_CALL = re.compile(r"^\[(?!fmi[23])\w+\]\s*")


def names_a_cause(text, variables):
    """Whether the message ``text`` names a variable of ``variables``, an FMI function, a value reference, a range
    or an argument of the call (the name of the library's method it came through does not count)."""
    text = PYTHON_CALL.sub("", text)
    if FUNCTION.search(text) or RANGE.search(text) or ARGUMENT.search(text):
        return True
    return any(re.search(rf"(?<![\w.]){re.escape(name)}(?![\w(])", text) for name in variables)


def _computed(values, echoed):
    """The numbers of ``values`` (a call's, by name) that the FMU computed: not the parameters and inputs ``echoed``
    (they read back what the host set, checked when they are used)."""
    for name, value in values.items():
        if name not in echoed:
            yield from (value if isinstance(value, list) else [value])


def violations(records, model):
    """What the calls ``records`` (as ``fuzz_runner`` prints them) break of the properties above, for the FMU
    ``model`` (a :class:`Model`)."""
    found = []
    for index, record in enumerate(records):
        where = f"call {index} {record['label']} -> {record['result']}"
        values = record.get("values", {})
        if values.get("past the end"):
            found.append(f"{where} wrote past the count it was given: {values['past the end']}")
        status = ERROR if record["result"] == "NULL" else record["result"]
        finite = all(isinstance(v, int) or math.isfinite(v) for v in _computed(values, model.settable))
        if status in (OK, WARNING) and not finite:
            found.append(f"{where} wrote a non-finite value: {values}")
        if status in (ERROR, FATAL) and not any(
                s >= ERROR and names_a_cause(text, model.names) for s, _, text in record["messages"]):
            found.append(f"{where} without an error message naming the cause: {record['messages']}")
    return found


INSTANCE, MODEL_EXCHANGE = ["instantiate", "plain"], ["instantiate", "me-plain"]
INITIALIZED = [["enter_initialization"], ["exit_initialization"]]


def check(worker, version, folder, calls, model):
    """Run ``calls`` in ``worker``; a failure is run again alone (and traced) in a new child."""
    said = worker.run(calls)
    if "failure" not in said and not violations(said["calls"], model):
        return
    alone = Worker(version, folder, trace=True)
    try:
        again = alone.run(calls)
    finally:
        alone.close()
    if "failure" in again:
        pytest.fail(f"{again['failure']}\nlast calls: {again['traced'][-5:]}")
    found = violations(again["calls"], model)
    assert not found, "\n".join(found)
    pytest.fail(f"fails only after earlier sequences in the same process: {said}")


# ---- the sequences -------------------------------------------------------------------------------------------

TINY, SUBNORMAL, HUGE = 1e-300, 5e-324, 1e300
EDGES = (0.0, -0.0, TINY, -TINY, SUBNORMAL, -SUBNORMAL, 2.2250738585072014e-308 / 3, HUGE, -HUGE,
         1.7976931348623157e308, -1.7976931348623157e308, math.inf, -math.inf, math.nan)
INT_EDGES = (0, -1, 2 ** 31 - 1, -2 ** 31)
CATEGORIES = ("logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logAll", "logEvents")


class Model:
    """The variables of an FMU's model description, and the strategies of values and calls drawn from them."""

    def __init__(self, folder):
        variables = read_model_description(str(folder)).modelVariables
        self.kinds = {v.name: v.type for v in variables}
        self.bounds = {v.name: (_number(v.min), _number(v.max)) for v in variables}
        self.starts = {v.name: _number(v.start) for v in variables}
        self.settable = [v.name for v in variables if v.causality in ("parameter", "input")]
        self.inputs = [v.name for v in variables if v.causality == "input"]
        self.outputs = [v.name for v in variables if v.causality == "output"]
        self.names = [v.name for v in variables]
        self.folder = folder

    def __repr__(self):
        return f"Model({self.folder})"

    def value(self, name):
        """A value for ``name``: inside its range, near its start value, or an edge value."""
        low, high = self.bounds[name]
        if self.kinds[name] in ("Integer", "Int32", "Enumeration"):
            low, high = int(low if low is not None else -3), int(high if high is not None else 3)
            return st.one_of(st.integers(low - 1, high + 1), st.sampled_from(INT_EDGES))
        start = self.starts[name] or 0.0
        valid = st.floats(min_value=max(low, -10.0) if low is not None else -10.0,
                          max_value=min(high, 10.0) if high is not None else 10.0)
        near = st.floats(0.5, 2.0).map(lambda factor: start * factor if start else factor - 1.0)
        return st.one_of(valid, near, st.sampled_from(EDGES))

    def set_call(self, names=None):
        return st.sampled_from(names or self.settable).flatmap(lambda name: self.value(name).map(
            lambda value: ["set", name, value]))

    def get_call(self):
        return st.lists(st.sampled_from(self.names), min_size=1, max_size=6, unique=True).map(lambda n: ["get", n])


def _number(text):
    return None if text is None else float(text)


def time_step(now):
    """(t, h) of a communication step when the last one ended at ``now``: mostly from ``now``, sometimes with a
    gap or an overlap, any h including 0, negative, nan and inf."""
    t = st.one_of(st.just(now), st.just(now), st.floats(-1.0, 10.0).map(lambda d: now + d),
                  st.sampled_from(EDGES))
    h = st.one_of(st.sampled_from((0.0, 1e-9, 0.01, 0.1, 0.5, 1.0)), st.floats(0.0, 20.0),
                  st.floats(-1.0, 0.0), st.sampled_from(EDGES))
    return st.tuples(t, h)


def state_call():
    slot = st.integers(0, 2)
    edit = st.one_of(st.just(["none"]), st.tuples(st.just("truncate"), st.integers(0, 400)).map(list),
                     st.tuples(st.just("flip"), st.integers(0, 4000), st.integers(1, 255)).map(list),
                     st.tuples(st.just("overwrite"), st.integers(0, 4000),
                               st.sampled_from([1e300, -1.0, math.nan, math.inf, 0.0, 5e-324])).map(list),
                     st.binary(max_size=40).map(lambda raw: ["raw", raw.decode("latin-1")]))
    return st.one_of(slot.map(lambda s: ["get_state", s]), slot.map(lambda s: ["set_state", s]),
                     slot.map(lambda s: ["free_state", s]),
                     st.tuples(st.just("serialize"), slot, slot).map(list),
                     st.tuples(st.just("deserialize"), slot, edit, slot).map(list))


def start_arguments():
    """The arguments of fmi3EnterInitializationMode / fmi2SetupExperiment: (tolerance defined, tolerance, start
    time, stop time defined, stop time)."""
    number = st.one_of(st.just(0.0), st.floats(-10.0, 10.0), st.sampled_from(EDGES))
    start = st.one_of(st.just(0.0), st.floats(-10.0, 10.0), st.sampled_from(EDGES))
    return st.tuples(st.booleans(), number, start, st.booleans(), number).map(list)


def me_call(now, version=3):
    """A model-exchange call at ``now`` (the latest time set): a time, states, the arrays read, the mode changes (and
    the counts, in FMI 3)."""
    reads = st.tuples(st.sampled_from(["read GetContinuousStates", "read GetContinuousStateDerivatives",
                                       "read GetNominalsOfContinuousStates"]), st.sampled_from((2, 2, 2, 0, 1, 3)))
    indicators = st.tuples(st.just("read GetEventIndicators"), st.sampled_from((3, 3, 3, 0, 2, 4)))
    state = st.one_of(st.floats(-2.0, 2.0), st.sampled_from(EDGES))
    return st.one_of(
        st.one_of(st.floats(0.0, 5.0).map(lambda d: now + d), st.sampled_from(EDGES)).map(
            lambda t: ["set_time", t]),
        st.lists(state, min_size=2, max_size=2).map(lambda x: ["set_states", x]),
        st.lists(state, max_size=3).map(lambda x: ["set_states", x]),
        reads.map(list), indicators.map(list), st.booleans().map(lambda b: ["completed", b]),
        st.sampled_from([["update"], ["enter_event_mode"], ["enter_continuous_time_mode"]]
                        + ([["counts"]] if version == 3 else [])))


def derivative_call(model, version=2):
    """fmi2SetRealInputDerivatives (FMI 2 only) or fmi2GetRealOutputDerivatives / fmi3GetOutputDerivatives of a few
    variables (mostly inputs or outputs), at
    orders mostly 1 or 2, with values from the edges or near 0."""
    names = st.lists(st.one_of(st.sampled_from(model.inputs or model.names), st.sampled_from(model.outputs),
                               st.sampled_from(model.names)), min_size=1, max_size=3)
    order = st.sampled_from((1, 1, 1, 2, 3, 0, -1))
    value = st.one_of(st.floats(-10.0, 10.0), st.sampled_from(EDGES))
    set_call = names.flatmap(lambda n: st.tuples(st.just(n), st.lists(order, min_size=len(n), max_size=len(n)),
                                                 st.lists(value, min_size=len(n), max_size=len(n))))
    get_call = names.flatmap(lambda n: st.tuples(st.just(n), st.lists(order, min_size=len(n), max_size=len(n))))
    if version == 3:
        return get_call.map(lambda a: ["get_output_derivatives", *a])
    return st.one_of(set_call.map(lambda a: ["set_input_derivatives", *a]),
                     get_call.map(lambda a: ["get_output_derivatives", *a]))


def any_call(model, version, now):
    """Any call of the operations of ``fuzz_runner``, legal where it is made or not."""
    plain = [["exit_initialization"], ["reset"], ["terminate"]]
    calls = [start_arguments().map(lambda a: ["enter_initialization", *a]), st.sampled_from(plain),
             st.tuples(st.booleans(), st.lists(st.sampled_from(CATEGORIES), max_size=2)).map(
                 lambda a: ["debug_logging", *a]),
             model.set_call(model.names), model.get_call(), state_call()]
    if version == 2:
        calls += [start_arguments().map(lambda a: ["setup_experiment", *a]), derivative_call(model)]
    else:
        calls += [derivative_call(model, 3), st.just(["enter_step_mode"])]
    calls.append(me_call(now, version))
    return st.one_of(calls)


def running_call(model, version, interface, now):
    """A call of a running instance: mostly steps (co-simulation) or model-exchange calls, inputs and outputs."""
    usual = [model.set_call(model.inputs), model.get_call(), state_call(), derivative_call(model, version)]
    if interface == "me":
        usual += [me_call(now, version)] * 3
    else:
        usual += [time_step(now).map(lambda th: ["step", *th])] * 3
    if version == 3 and interface == "cs":  # event mode of an instance made with eventModeUsed, or refused
        usual.append(st.sampled_from([["enter_event_mode"], ["update"], ["enter_step_mode"]]))
    return st.one_of(*usual, any_call(model, version, now))


@st.composite
def sequences(draw, model, version, interface):
    """An instantiation, then either an initialization (some parameters set) and running calls, or any calls."""
    variant = draw(st.sampled_from(["plain", "logging", *(["early", "events"] if version == 3 and interface == "cs"
                                                          else [])]))
    calls = [["instantiate", f"me-{variant}" if interface == "me" else variant]]
    now = 0.0
    if draw(st.integers(0, 3)):  # three in four: initialized first
        start = draw(st.one_of(st.just([False, 0.0, 0.0, False, 0.0]), start_arguments()))
        now = start[2]
        calls += [["enter_initialization", *start], *draw(st.lists(model.set_call(), max_size=4)),
                  ["exit_initialization"]]
        calls += [["update"], ["enter_continuous_time_mode"]] if interface == "me" else []
        calls += [["update"], ["enter_step_mode"]] if variant == "events" else []
    for _ in range(draw(st.integers(0, 12))):
        call = draw(running_call(model, version, interface, now))
        if call[0] == "step" and math.isfinite(call[1] + call[2]):
            now = call[1] + call[2]
        elif call[0] == "set_time" and math.isfinite(call[1]):
            now = call[1]
        calls.append(call)
    return calls


# ---- the test ------------------------------------------------------------------------------------------------

#: target: (FMI version, interface, the session's fixture of the FMU extracted)
TARGETS = {"fmi2-cs": (2, "cs", "unzipped"), "fmi2-me": (2, "me", "unzipped"), "fmi3-cs": (3, "cs", "unzipped3"),
           "fmi3-me": (3, "me", "unzipped3"), "coupling-cs": (2, "cs", "unzipped_coupling")}


@pytest.fixture(scope="module")
def targets(request):
    """``{target: (FMI version, interface, folder, Model, Worker)}``; the workers end with the module, each with exit
    status 0 (a child that started)."""
    made = {}
    for key, (version, interface, fixture) in TARGETS.items():
        folder = request.getfixturevalue(fixture)[0]
        made[key] = (version, interface, folder, Model(folder), Worker(version, folder))
    yield made
    ends = {key: worker.close() for key, (*_, worker) in made.items()}
    assert set(ends.values()) <= {0, None}, f"the fuzzer's children ended with {ends}"


@pytest.mark.parametrize("target", TARGETS)
@settings(max_examples=EXAMPLES, derandomize=not BY_HAND, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data())
def test_fuzzed_call_sequences_hold(targets, target, data):
    version, interface, folder, model, worker = targets[target]
    calls = data.draw(sequences(model, version, interface), label="calls")
    check(worker, version, folder, calls, model)


#: what the fuzzer found that the fronts or the slave now refuse or answer: {name: (target, calls, the label of the
#: call, its status, a text of its message)}
FOUND = {
    "fmi2SetFMUstate of a NULL state (crashed)": (
        "fmi2-cs", [INSTANCE, *INITIALIZED, ["set_state", 0]], "fmi2SetFMUstate", ERROR,
        "fmi2SetFMUstate: the FMU state is NULL (no state was got into it, or it was freed)"),
    "fmi2SerializedFMUstateSize of a NULL state (crashed)": (
        "fmi2-cs", [INSTANCE, ["serialize", 0, 0]], "fmi2SerializedFMUstateSize", ERROR, "the FMU state is NULL"),
    "fmi3SetFMUState of a NULL state (named no cause)": (
        "fmi3-cs", [INSTANCE, ["set_state", 0]], "fmi3SetFMUState", ERROR, "the FMU state is NULL"),
    "fmi3SerializedFMUStateSize of a NULL state (fatal, then a crash)": (
        "fmi3-me", [MODEL_EXCHANGE, ["serialize", 0, 0], ["get", ["x"]]], "fmi3SerializedFMUStateSize", ERROR,
        "the FMU state is NULL"),
    "fmi3GetEventIndicators of 4 (a Python exception left set)": (
        "fmi3-me", [MODEL_EXCHANGE, ["read GetEventIndicators", 4]], "fmi3GetEventIndicators", ERROR,
        "fmi3GetEventIndicators: nEventIndicators = 4, but this FMU has 3 event indicators"),
    "fmi3GetContinuousStateDerivatives on a co-simulation instance (OK, then the outputs failed)": (
        "fmi3-cs", [INSTANCE, ["read GetContinuousStateDerivatives", 2], ["get", ["F_friction"]]],
        "fmi3GetContinuousStateDerivatives", ERROR,
        "fmi3GetContinuousStateDerivatives is not allowed for a co-simulation instance: it is a model-exchange "
        "function"),
    "fmi3GetEventIndicators of 2 (OK, two of three)": (
        "fmi3-me", [MODEL_EXCHANGE, ["read GetEventIndicators", 2]], "fmi3GetEventIndicators", ERROR,
        "nEventIndicators = 2, but this FMU has 3"),
    "fmi3GetContinuousStates of 3 (a Python exception left set)": (
        "fmi3-me", [MODEL_EXCHANGE, ["read GetContinuousStates", 3]], "fmi3GetContinuousStates", ERROR,
        "nContinuousStates = 3, but this FMU has 2 continuous states"),
    "fmi3GetNominalsOfContinuousStates of 3": (
        "fmi3-me", [MODEL_EXCHANGE, ["read GetNominalsOfContinuousStates", 3]], "fmi3GetNominalsOfContinuousStates",
        ERROR, "nContinuousStates = 3"),
    "fmi3GetContinuousStateDerivatives of 3": (
        "fmi3-me", [MODEL_EXCHANGE, ["read GetContinuousStateDerivatives", 3]], "fmi3GetContinuousStateDerivatives",
        ERROR, "nContinuousStates = 3"),
    "fmi3SetContinuousStates of 1 (IndexError)": (
        "fmi3-me", [MODEL_EXCHANGE, *INITIALIZED, ["set_states", [1.0]]], "fmi3SetContinuousStates", ERROR,
        "nContinuousStates = 1, but this FMU has 2"),
    "fmi2SetupExperiment at startTime = inf (outputs inf with OK)": (
        "fmi2-cs", [INSTANCE, ["enter_initialization", False, 0.0, math.inf, False, 0.0], ["get", ["t_last_event"]]],
        "fmi2SetupExperiment", ERROR, "fmi2SetupExperiment: startTime = inf; allowed: a finite value"),
    "fmi2SetupExperiment with stopTime = nan": (
        "fmi2-cs", [INSTANCE, ["setup_experiment", False, 0.0, 0.0, True, math.nan]], "fmi2SetupExperiment", ERROR,
        "stopTime = nan; allowed: a finite value"),
    "fmi3EnterInitializationMode with tolerance = -inf": (
        "fmi3-me", [MODEL_EXCHANGE, ["enter_initialization", True, -math.inf, 0.0, False, 0.0]],
        "fmi3EnterInitializationMode", ERROR, "tolerance = -inf; allowed: a finite value"),
    "ChainCoupling: x_left = nan (F = nan with OK)": (
        "coupling-cs", [INSTANCE, *INITIALIZED, ["set", "x_left", math.nan], ["get", ["F"]]], "fmi2SetReal", ERROR,
        "x_left = nan m is out of range: allowed is a finite value in (-inf, inf)"),
    "ChainCoupling: kc_left = 1e308 with the positions 20 m apart (F = inf with OK)": (
        "coupling-cs", [INSTANCE, ["enter_initialization"], ["set", "kc_left", 1e308], ["exit_initialization"],
                        ["set", "x_left", 10.0], ["set", "x", -10.0], ["get", ["F"]]], "fmi2GetReal", ERROR,
        "F = inf N is not finite"),
    "fmi2GetReal of x after a model-exchange call during initialization (AttributeError of None)": (
        "fmi2-me", [["instantiate", "me-plain"], ["enter_initialization"], ["read GetContinuousStates", 2],
                    ["get", ["x", "der(v)"]]], "fmi2GetReal", OK, None),
    "fmi3GetFloat64 of x after a model-exchange call during initialization (AttributeError of None)": (
        "fmi3-me", [MODEL_EXCHANGE, ["enter_initialization"], ["read GetContinuousStates", 2], ["get", ["x"]]],
        "fmi3GetFloat64", OK, None),
    "fmi2GetDerivatives of 3": (
        "fmi2-me", [["instantiate", "me-plain"], *INITIALIZED, ["read GetContinuousStateDerivatives", 3]],
        "fmi2GetDerivatives", ERROR, "fmi2GetDerivatives: nx = 3, but this FMU has 2 continuous states"),
    "fmi2GetEventIndicators on a co-simulation instance": (
        "fmi2-cs", [INSTANCE, *INITIALIZED, ["read GetEventIndicators", 3]], "fmi2GetEventIndicators", ERROR,
        "fmi2GetEventIndicators is not allowed for a co-simulation instance: it is a model-exchange function"),
    "fmi3GetFloat64 of der(x) and an indicator before initialization (AttributeError of None)": (
        "fmi3-cs", [INSTANCE, ["get", ["der(x)", "der(v)", "indicator.breakaway"]]], "fmi3GetFloat64", OK, None),
}


@pytest.mark.parametrize("name", FOUND)
def test_a_found_case_is_answered(targets, name):
    """Each case alone in the target's child: the call's status and message, and every property of the fuzzer."""
    target, calls, label, status, text = FOUND[name]
    *_, model, worker = targets[target]
    said = worker.run(calls)
    assert "failure" not in said, said["failure"]
    [record] = [record for record in said["calls"] if record["label"] == label]
    assert record["result"] == status, record
    assert text is None or any(text in message for _, _, message in record["messages"]), record["messages"]
    assert violations(said["calls"], model) == []
    assert said["calls"][-1]["function"].endswith("FreeInstance")


@pytest.mark.parametrize("target", ["fmi2-cs", "fmi3-cs"])
def test_a_step_to_a_huge_time_ends_with_an_error_naming_the_time_resolution(targets, target):
    """A step to t = 1e300 s, where floats space times by 2.2e284 s (1e300 * 2**-52), ran for ever (7e298
    stick-slip cycles of the default block): it ends with an error naming the time resolution; the state saved
    before it restores, and the instance steps on from t = 0."""
    version, _, folder, model, _ = targets[target]
    alone = Worker(version, folder, timeout=10.0)
    try:
        said = alone.run([INSTANCE, *INITIALIZED, ["get_state", 0], ["step", 0.0, 1e300], ["set_state", 0],
                          ["step", 0.0, 1.0]])
    finally:
        alone.close()
    assert "failure" not in said, said["failure"]
    huge, after = [record for record in said["calls"] if record["label"].endswith("DoStep")]
    assert huge["result"] == ERROR and after["result"] == OK, said["calls"]
    spacing = f"{1e300 * 2.0 ** -52:.3g} s"
    assert any("1e+300 s: time resolution lost" in text and spacing in text for _, _, text in huge["messages"]), huge
    assert violations(said["calls"], model) == []


# ---- load / instantiate / step on threads / free / unload / reload -------------------------------------------

CYCLE_EXAMPLES = int(BY_HAND or 4)
STEP = 0.1  # s, fuzz_runner's communication step in the cycles
#: target: (start values, the output read, its value after n steps of STEP from t = 0): the block stuck to the surface
#: (x = v_drive t, v_drive = 0.1 m/s), the coupling's springs at fixed positions (F = 2 (0.5 - 0) N)
CYCLED = {"fmi2-cs": ({"v_start": 0.1}, "x", lambda n: 0.1 * STEP * n),
          "fmi3-cs": ({"v_start": 0.1}, "x", lambda n: 0.1 * STEP * n),
          "coupling-cs": ({"kc_left": 2.0, "x_left": 0.5}, "F", lambda n: 1.0)}


def cycle():
    """One cycle of ``fuzz_runner.run_cycles``: 1 to 3 instances, each stepped 0 to 4 times (on threads of their own
    at once, or one after the other), freed in any order, the binary unloaded or not."""
    return st.integers(1, 3).flatmap(lambda n: st.fixed_dictionaries({
        "instances": st.just(n), "steps": st.integers(0, 4), "threads": st.booleans(),
        "free": st.permutations(range(n)), "unload": st.booleans()}))


def run_cycles(folder, version, case):
    """The results of ``fuzz_runner.py cycles`` on ``case`` in a child process of its own, which must end with exit
    status 0 within the time limit."""
    try:
        proc = subprocess.run([sys.executable, str(RUNNER), "cycles", str(version), str(folder)],
                              input=json.dumps(case), capture_output=True, text=True, timeout=TIMEOUT,
                              cwd=RUNNER.parent)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the host hung ({TIMEOUT} s) in the cycles {case}")
    assert proc.returncode == 0, f"the host ended with {proc.returncode} in the cycles {case}: {proc.stderr[-3000:]}"
    return json.loads(proc.stdout.splitlines()[-1])["cycles"]


@pytest.mark.parametrize("target", CYCLED)
@settings(max_examples=CYCLE_EXAMPLES, derandomize=not BY_HAND, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(cycles=st.lists(cycle(), min_size=1, max_size=3))
def test_load_instantiate_step_on_threads_free_unload_reload(targets, target, cycles):
    version, _, folder, _, _ = targets[target]
    values, output, expected = CYCLED[target]
    results = run_cycles(folder, version, {"values": values, "output": output, "cycles": cycles})
    assert [result["failed"] for result in results] == [[]] * len(cycles)
    assert [result["outputs"] for result in results] == [
        [pytest.approx(expected(c["steps"]), rel=1e-12, abs=1e-15)] * c["instances"] for c in cycles]
