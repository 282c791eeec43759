"""Every FMI function the FMUs' Linux binaries export, called with its documented result (FMI 2.0.4, FMI 3.0),
and the debug-logging filter at every category of the model description.

The calls run in child processes (``fmi_call_runner.py``, ctypes with the standard's signatures on the extracted
binary), one per FMU; a crash fails the case that was running and the other cases run in a new process. A call
the FMU supports gives the standard's value, checked against the model description and the SPEC's stuck block
(SPEC section 2: stuck, ``v = v_drive``, ``x = x_start + v_drive t``, until ``|kappa x - F_ext| > F_S``); a call
the FMU does not support, or that is not allowed where it is made, is refused with the error status and a log
message naming it, never answered with OK and no effect.
"""

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from fmi_call_runner import FMI2_EXCHANGE_ONLY, FMI3_EXCHANGE_ONLY, FMI3_OTHER_TYPES, FMI3_REFUSED

RUNNER = Path(__file__).with_name("fmi_call_runner.py")
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
TIMEOUT = 300  # s for one child process (all cases of one FMU take about 2 s)
#: the <LogCategories> of both model descriptions (PythonFMU's and pythonfmu3's standard set)
LISTED = ("logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logAll")
#: the start values of the runner's stuck block (fmi_call_runner.STUCK) and the defaults it relies on
X_START, V_DRIVE, KAPPA, F_S = 0.0, 0.1, 1.0, 1.0
H = 0.5  # s, the runner's step
#: m, N: the stuck block's x, v and indicators come out exactly as computed here (error 0); 100 ulps of 0.05
EXACT = 100 * math.ulp(X_START + V_DRIVE * H)

# ---- what each call must give ---------------------------------------------------------------------------------
#
# An outcome: "ok" (fmi*OK, no message of warning or worse), "value" (a function without a status: no message of
# warning or worse; the value is checked below), "refused" (fmi*Error and an error message naming the
# call), "discarded" (fmi2Discard and a discard message naming it: FMI 2.0.4 section 4.2.3, a status the slave
# cannot retrieve), "null" (instantiation refused: NULL and an error message naming the call).

FMI2_EXPECTED = {
    "fmi2GetVersion": "value", "fmi2GetTypesPlatform": "value",
    **dict.fromkeys([
        "fmi2Instantiate", "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2SetReal", "fmi2SetInteger",
        "fmi2ExitInitializationMode", "fmi2GetReal at t=0", "fmi2GetInteger", "fmi2DoStep", "fmi2GetReal at t=0.5",
        "fmi2GetInteger mode", "fmi2GetRealStatus", "fmi2Terminate", "fmi2FreeInstance", "fmi2Reset",
        "fmi2SetupExperiment after reset", "fmi2EnterInitializationMode after reset",
        "fmi2ExitInitializationMode after reset", "fmi2GetReal after reset", "fmi2DoStep after reset",
        "fmi2GetFMUstate", "fmi2GetReal stepped", "fmi2SetFMUstate", "fmi2GetReal restored",
        "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate", "fmi2DoStep again",
        "fmi2SetFMUstate deserialized", "fmi2GetReal deserialized", "fmi2FreeFMUstate",
        "fmi2FreeFMUstate deserialized", "fmi2FreeFMUstate of a NULL state", "fmi2FreeFMUstate of a null pointer",
        # the model has no Boolean or String variable: reading or writing none of them is fine
        "fmi2GetBoolean of none", "fmi2SetBoolean of none", "fmi2GetString of none", "fmi2SetString of none",
        "fmi2DoStep after the refusals", "fmi2GetReal after the refusals",
        "fmi2GetBooleanStatus",  # fmi2Terminated: the slave never asks to terminate (fmi2False)
        "fmi2SetRealInputDerivatives",  # canInterpolateInputs = true: der(F_ext)
        "fmi2GetRealOutputDerivatives",  # maxOutputDerivativeOrder = 2: der(x)
        "fmi2DoStep after the refusal", "fmi2GetReal after the refusal",
        # model exchange (fmuType fmi2ModelExchange)
        "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode", "fmi2GetContinuousStates",
        "fmi2GetNominalsOfContinuousStates", "fmi2GetDerivatives", "fmi2SetTime", "fmi2SetContinuousStates",
        "fmi2GetEventIndicators", "fmi2CompletedIntegratorStep", "fmi2EnterEventMode", "fmi2NewDiscreteStates at t=0.5",
        "fmi2GetReal at t=0.5", "fmi2GetReal of der(x), der(v)", "fmi2Terminate in model exchange",
        *(f"fmi2{name} of model exchange" for name in ("Instantiate", "SetupExperiment", "EnterInitializationMode",
                                                       "FreeInstance")),
        "fmi2SetReal of M = -1 kg", "fmi2GetContinuousStates after the refusals",
    ], "ok"),
    **dict.fromkeys([
        "fmi2GetBoolean of a Real", "fmi2SetBoolean of a Real", "fmi2GetString of a Real", "fmi2SetString of a Real",
        "fmi2GetDirectionalDerivative",  # providesDirectionalDerivative is not set
        "fmi2CancelStep",  # only for an fmi2DoStep that returned fmi2Pending, which this FMU never does
        *(f"{name} in co-simulation" for name in FMI2_EXCHANGE_ONLY),  # model-exchange functions
        # the co-simulation functions on a model-exchange instance
        *(f"fmi2{name} in model exchange" for name in ("DoStep", "SetRealInputDerivatives",
                                                       "GetRealOutputDerivatives")),
        # a mass out of range (during initialization), arrays of the wrong length, a non-finite time or state, NULL
        "fmi2GetDerivatives with M = -1 kg", "fmi2ExitInitializationMode with M = -1 kg",
        "fmi2GetDerivatives of nx = 5", "fmi2GetEventIndicators of ni = 2", "fmi2SetContinuousStates of nx = 1",
        "fmi2SetTime of NaN", "fmi2GetContinuousStates into NULL", "fmi2SetContinuousStates of inf",
    ], "refused"),
    **dict.fromkeys([
        "fmi2GetStatus", "fmi2GetStringStatus",  # fmi2DoStepStatus, fmi2PendingStatus: no step is pending
        "fmi2GetIntegerStatus",  # no status kind has an Integer value
        "fmi2GetRealStatus of fmi2DoStepStatus",  # not a Real status kind
    ], "discarded"),
}

FMI3_EXPECTED = {
    "fmi3GetVersion": "value",
    **dict.fromkeys([
        "fmi3InstantiateCoSimulation", "fmi3InstantiateModelExchange", "fmi3EnterInitializationMode",
        "fmi3SetFloat64", "fmi3SetInt32", "fmi3ExitInitializationMode", "fmi3GetFloat64 at t=0", "fmi3GetInt32",
        "fmi3DoStep", "fmi3GetFloat64 at t=0.5", "fmi3GetInt32 mode", "fmi3Terminate", "fmi3FreeInstance",
        "fmi3Reset", "fmi3EnterInitializationMode after reset", "fmi3ExitInitializationMode after reset",
        "fmi3GetFloat64 after reset", "fmi3DoStep after reset",
        "fmi3GetFMUState", "fmi3GetFloat64 stepped", "fmi3SetFMUState", "fmi3GetFloat64 restored",
        "fmi3SerializedFMUStateSize", "fmi3SerializeFMUState", "fmi3DeserializeFMUState", "fmi3DoStep again",
        "fmi3SetFMUState deserialized", "fmi3GetFloat64 deserialized", "fmi3FreeFMUState",
        "fmi3FreeFMUState deserialized", "fmi3FreeFMUState of a NULL state", "fmi3FreeFMUState of a null pointer",
        *(f"fmi3{way}{kind} of none" for kind in FMI3_OTHER_TYPES for way in ("Get", "Set")),
        "fmi3DoStep after the refusals", "fmi3GetFloat64 after the refusals",
        "fmi3DoStep after the refusal", "fmi3GetFloat64 after the refusal",
        # model exchange
        "fmi3UpdateDiscreteStates", "fmi3EnterContinuousTimeMode", "fmi3GetNumberOfContinuousStates",
        "fmi3GetNumberOfEventIndicators", "fmi3GetContinuousStates", "fmi3GetNominalsOfContinuousStates",
        "fmi3GetContinuousStateDerivatives", "fmi3SetTime", "fmi3SetContinuousStates", "fmi3GetEventIndicators",
        "fmi3CompletedIntegratorStep", "fmi3EnterEventMode", "fmi3UpdateDiscreteStates at t=0.5",
        "fmi3GetOutputDerivatives",  # maxOutputDerivativeOrder = 2: x and v, orders 1 and 2
        # co-simulation with event mode and early return
        "fmi3InstantiateCoSimulation with event mode", "fmi3EnterInitializationMode with event mode",
        "fmi3ExitInitializationMode with event mode", "fmi3UpdateDiscreteStates after initialization",
        "fmi3EnterStepMode after initialization", "fmi3DoStep to the first event", "fmi3GetFloat64 before the event",
        "fmi3GetInt32 before the event", "fmi3EnterEventMode at the event", "fmi3UpdateDiscreteStates at the event",
        "fmi3GetInt32 after the event", "fmi3EnterStepMode after the event", "fmi3DoStep after the event",
    ], "ok"),
    **dict.fromkeys([
        *FMI3_REFUSED,
        *(f"fmi3{way}{kind} of a Float64" for kind in FMI3_OTHER_TYPES for way in ("Get", "Set")),
        "fmi3GetDirectionalDerivative",  # providesDirectionalDerivatives is not set
        "fmi3GetOutputDerivatives of order 3", "fmi3GetOutputDerivatives of mode",  # only x and v, orders 1 and 2
        "fmi3GetOutputDerivatives with nValues short",  # scalars: nValues = nValueReferences
        "fmi3EnterConfigurationMode", "fmi3ExitConfigurationMode",  # the model has no structural parameter
        "fmi3EnterStepMode",  # a co-simulation instance made with eventModeUsed = false never is in event mode
        "fmi3EnterEventMode in co-simulation", "fmi3UpdateDiscreteStates in co-simulation",  # likewise
        # with eventModeUsed: each call in the mode it belongs to (FMI 3.0 section 4.2)
        "fmi3UpdateDiscreteStates in Step Mode", "fmi3EnterStepMode in Step Mode", "fmi3DoStep in Event Mode",
        "fmi3EnterEventMode in Event Mode",
        *(f"{name} in co-simulation" for name in FMI3_EXCHANGE_ONLY),  # FMI 3.0 section 2.3
    ], "refused"),
    **dict.fromkeys(["fmi3InstantiateScheduledExecution"], "null"),
}

#: calls against the standard, left to the loader's state tracking (issue 20's misuse list)
# ---- logging settings: (loggingOn at instantiation, [[on, categories] of each fmi*SetDebugLogging call]) --------

LOG_SETTINGS = {
    "off": (False, []),
    "on": (True, []),
    **{f"only {name}": (False, [[True, [name]]]) for name in LISTED},
    "all listed": (False, [[True, list(LISTED)]]),
    "all, none named": (False, [[True, []]]),
    "off, none named": (True, [[False, []]]),
    "on, then off for logStatusWarning": (True, [[False, ["logStatusWarning"]]]),
    "FMI 3's example: all off, then logStatusFatal": (True, [[False, []], [True, ["logStatusFatal"]]]),
    "logAll, then logStatusWarning": (False, [[True, ["logAll"]], [True, ["logStatusWarning"]]]),
    "unknown: logEvents": (False, [[True, ["logEvents"]]]),
    "unknown: NULL": (False, [[True, [None]]]),
}


def information_wanted(fmi_version, logging_on, debug_logging_calls):
    """Whether an fmi*OK message of category logAll (the slave's information messages) must reach the logger.

    FMI 2.0.4 section 2.1.5: fmi2SetDebugLogging enables the categories given (all if none) when loggingOn, else
    disables debug logging. FMI 3.0 section 2.3.1: each category given is switched to loggingOn (all if none),
    the others keep their state. A call with a category the model description does not list is refused and
    changes nothing."""
    enabled = dict.fromkeys(LISTED, logging_on)
    for on, categories in debug_logging_calls:
        if not set(categories) <= set(LISTED):
            continue
        if fmi_version == 2:
            enabled = {name: on and (not categories or name in categories) for name in LISTED}
        else:
            enabled.update(dict.fromkeys(categories or LISTED, on))
    return enabled["logAll"]


# ---- running the cases -----------------------------------------------------------------------------------------


def _run_child(fmi_version, folder, names):
    """(stdout, None) of the runner on the cases ``names``, or (stdout so far, why) if it failed or hung."""
    command = [sys.executable, str(RUNNER), str(fmi_version), str(folder), *names]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired as expired:
        return (expired.stdout or b"").decode(), f"no answer within {TIMEOUT} s"
    return done.stdout, None if done.returncode == 0 else f"exit status {done.returncode}: {done.stderr[-3000:]}"


def run_cases(fmi_version, folder, names):
    """``{case: record}`` of the runner's cases ``names`` on the extracted FMU ``folder``. A case during which
    the child process died or hung is ``{"crash": why}`` and the cases after it run in a new process; a process
    that fails after its last case marks that case."""
    results, remaining = {}, list(names)
    while remaining:
        output, why = _run_child(fmi_version, folder, remaining)
        running = None
        for line in output.splitlines():
            record = json.loads(line)
            running = record.get("start")
            if running is None:
                results[record["case"]] = record
        if why is None:
            break
        running = running or next((name for name in remaining if name not in results), remaining[-1])
        results[running] = {"crash": why}
        remaining = remaining[remaining.index(running) + 1:]
    return results


def _log_case(setting):
    return "log" + json.dumps(LOG_SETTINGS[setting])


def _plain_cases(fmi_version):
    names = {2: ("version", "stuck_step", "reset", "fmu_state", "boolean_string", "derivatives", "status",
                 "cs_exchange_calls", "model_exchange", "exchange_refusals"),
             3: ("version", "cs_stuck_step", "reset", "fmu_state", "other_types", "refused", "modes",
                 "cs_exchange_calls", "model_exchange", "event_mode")}
    return names[fmi_version]


@pytest.fixture(scope="module")
def results(unzipped, unzipped3):
    """``{FMI version: {case: record}}``: every case of the runner, the logging settings included."""
    out = {}
    for fmi_version, (folder, _, _) in ((2, unzipped), (3, unzipped3)):
        names = [*_plain_cases(fmi_version), *map(_log_case, LOG_SETTINGS)]
        out[fmi_version] = run_cases(fmi_version, folder, names)
    return out


def case(results, fmi_version, name):
    """The record of one case; fails with the child's exit if the case crashed it."""
    record = results[fmi_version][name]
    assert "crash" not in record, f"FMI {fmi_version} case {name!r} crashed the process: {record['crash']}"
    return record


def calls(record, label):
    """The calls of ``record`` made under ``label``."""
    return [call for call in record["calls"] if call["label"] == label]


def calls_of_the_cases(results, fmi_version):
    """Every call of the plain cases (not the logging settings) that ran to their end."""
    records = (results[fmi_version][name] for name in _plain_cases(fmi_version))
    return [call for record in records if "crash" not in record for call in record["calls"]]


def names_the_call(message, function):
    """Whether a log message names ``function`` (with or without its fmi2/fmi3 prefix, any case)."""
    return function[4:].lower() in message.lower()


def check_outcome(call, outcome):
    """Assert that one recorded call had ``outcome`` (see the expectation tables)."""
    status, messages = call["result"], call["messages"]
    if outcome in ("ok", "value"):
        assert outcome == "value" or status in (OK, None, "instance"), call
        assert not [m for m in messages if m[0] >= WARNING], call
        return
    wanted = {"refused": ERROR, "discarded": DISCARD, "null": ERROR}[outcome]
    assert status == ("NULL" if outcome == "null" else wanted), call
    assert any(m[0] == wanted and names_the_call(m[2], call["function"]) for m in messages), call


def _expected_params(fmi_version, table):
    return [pytest.param(fmi_version, label, outcome, id=f"{label}: {outcome}") for label, outcome in table.items()]


def binary_path(unzipped, fmi_version):
    """The Linux binary of the extracted FMU ``unzipped``."""
    folder, description, _ = unzipped
    platform = "linux64" if fmi_version == 2 else "x86_64-linux"
    identifier = (description.coSimulation or description.modelExchange).modelIdentifier
    return Path(folder, "binaries", platform, f"{identifier}.so")


def exported_functions(binary):
    """The names of the FMI functions ``binary`` exports (nm's defined dynamic text symbols)."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (GNU binutils) is needed to list the functions the FMU's binary exports")
    listing = subprocess.run([nm, "-D", "--defined-only", str(binary)], capture_output=True, text=True, check=True)
    fields = (line.split() for line in listing.stdout.splitlines())
    return {f[2] for f in fields if len(f) == 3 and f[1] == "T" and f[2].startswith("fmi")}


# ---- every function, its documented result ------------------------------------------------------------------


def _all_cases():
    return [pytest.param(fmi_version, name, id=f"FMI {fmi_version}, {name}")
            for fmi_version in (2, 3) for name in [*_plain_cases(fmi_version), *map(_log_case, LOG_SETTINGS)]]


@pytest.mark.parametrize("fmi_version, name", _all_cases())
def test_no_case_crashes_or_hangs_the_process(results, fmi_version, name):
    case(results, fmi_version, name)


@pytest.mark.parametrize("fmi_version, count", [(2, 44), (3, 75)])
def test_the_cases_call_every_exported_function_and_no_other(results, unzipped, unzipped3, fmi_version, count):
    """A function the binary exports that no case calls, or a case calling one it does not export, fails."""
    binary = binary_path(unzipped if fmi_version == 2 else unzipped3, fmi_version)
    called = {call["function"] for record in results[fmi_version].values() for call in record.get("calls", [])}
    exported = exported_functions(binary)
    assert called == exported, (sorted(exported - called), sorted(called - exported))
    assert len(exported) == count  # FMI 2 co-simulation and model exchange: all 44; FMI 3: all 75 of fmi3Functions.h


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_every_call_the_cases_make_has_an_expected_result(results, fmi_version):
    table = FMI2_EXPECTED if fmi_version == 2 else FMI3_EXPECTED
    made = {call["label"] for call in calls_of_the_cases(results, fmi_version)}
    assert made <= set(table), sorted(made - set(table))


@pytest.mark.parametrize("fmi_version, label, outcome",
                         [*_expected_params(2, FMI2_EXPECTED), *_expected_params(3, FMI3_EXPECTED)])
def test_the_call_gives_its_documented_result(results, fmi_version, label, outcome):
    made = [call for call in calls_of_the_cases(results, fmi_version) if call["label"] == label]
    crashed = {name: record["crash"] for name, record in results[fmi_version].items() if "crash" in record}
    assert made, f"no case that ran to its end calls {label!r}; crashed: {crashed}"
    for call in made:
        check_outcome(call, outcome)


# ---- the values the supported calls give ----------------------------------------------------------------------


def test_fmi2_version_and_types_platform(results):
    assert case(results, 2, "version")["values"] == {"version": "2.0", "platform": "default"}


def test_fmi3_version(results):
    assert case(results, 3, "version")["values"] == {"version": "3.0"}


@pytest.mark.parametrize("fmi_version, name", [(2, "stuck_step"), (3, "cs_stuck_step")])
def test_a_step_of_the_stuck_block_moves_it_with_the_drive(results, fmi_version, name):
    """Stuck from t = 0 (v_start = v_drive, |kappa x| = 0.05 N < F_S = 1 N): x = x_start + v_drive t,
    v = v_drive, t_stick = t, mode 0; the Integer parameter set reads back; the step completes in full."""
    values = case(results, fmi_version, name)["values"]
    assert values["at_start"] == [X_START, V_DRIVE]
    assert values["law"] == [2] and values["mode"] == [0]
    assert values["after"] == pytest.approx([X_START + V_DRIVE * H, V_DRIVE, H], rel=0, abs=EXACT)
    if fmi_version == 3:  # fmi3DoStep: no event handling needed, no termination, no early return, lastSuccessfulTime
        assert values["step"] == [False, False, False, H]


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_reset_brings_back_the_start_values(results, unzipped, unzipped3, fmi_version):
    """After fmi*Reset and a new initialization without values set, M and x are the model description's start
    values (M = 40 kg before the reset)."""
    variables = (unzipped if fmi_version == 2 else unzipped3)[2]
    expected = [float(variables["M"].start), float(variables["x_start"].start)]
    assert case(results, fmi_version, "reset")["values"]["M_x"] == expected


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_a_saved_and_a_deserialized_state_bring_back_t_0(results, fmi_version):
    values = case(results, fmi_version, "fmu_state")["values"]
    assert values["stepped"] == pytest.approx([X_START + V_DRIVE * H], rel=0, abs=EXACT)
    assert values["restored"] == [X_START] and values["deserialized"] == [X_START]
    assert values["size"] > 0
    assert values["freed_states"] == [None, None]  # fmi*FreeFMUstate returns NULL in its argument


@pytest.mark.parametrize("fmi_version, name", [(2, "boolean_string"), (3, "other_types"), (3, "refused"),
                                               (3, "modes")])
def test_after_refused_calls_the_instance_steps_as_before(results, fmi_version, name):
    """The refused calls changed nothing: v_drive keeps its value (a refused set of it), the block moves with it."""
    values = case(results, fmi_version, name)["values"]
    if "x_v_drive" in values:
        assert values["x_v_drive"] == pytest.approx([X_START + V_DRIVE * H, V_DRIVE], rel=0, abs=EXACT)
    if "x" in values:
        assert values["x"] == pytest.approx([X_START + V_DRIVE * H], rel=0, abs=EXACT)
    if fmi_version == 3:
        assert values["step"] == [False, False, False, H]


#: FMI version: (its model-exchange functions, why each is refused on a co-simulation instance)
EXCHANGE_REFUSALS = {
    2: (FMI2_EXCHANGE_ONLY, "(the instance was made by fmi2Instantiate with fmuType = fmi2CoSimulation)"),
    3: (FMI3_EXCHANGE_ONLY, "(FMI 3.0: not allowed in co-simulation; the instance was made by "
                            "fmi3InstantiateCoSimulation)"),
}


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_co_simulation_refuses_the_model_exchange_calls_and_its_outputs_survive_them(results, fmi_version):
    """FMI 3.0 section 2.3, and FMI 2 alike: the model-exchange functions are "not allowed in Co-Simulation": each
    is refused with a message naming it and why; fmi<N>SetTime(0.5) and fmi<N>SetContinuousStates(x = 0.05 m)
    change nothing, so one step of H from t = 0 gives the stuck block's x = x_start + v_drive H."""
    record = case(results, fmi_version, "cs_exchange_calls")
    names, why = EXCHANGE_REFUSALS[fmi_version]
    for name in names:
        [call] = calls(record, f"{name} in co-simulation")
        assert call["result"] == ERROR and [message[2] for message in call["messages"]] == [
            f"{name} is not allowed for a co-simulation instance: it is a model-exchange function {why}"], call
    assert record["values"]["x"] == pytest.approx([X_START + V_DRIVE * H], rel=0, abs=EXACT)


def test_fmi2_model_exchange_of_the_stuck_block_answers_as_fmi3(results):
    """The FMI 2 FMU's model exchange gives the FMI 3 FMU's states, nominals, derivatives, indicators, integrator
    step and event updates, bit for bit; der(x) and der(v) read as variables are the derivatives."""
    fmi2, fmi3 = case(results, 2, "model_exchange")["values"], case(results, 3, "model_exchange")["values"]
    for name in ("states", "nominals", "derivatives", "indicators", "outputs"):
        assert fmi2[name] == fmi3[name], name
    for name in ("completed", "first_update", "second_update"):  # fmi2Boolean ints, fmi3Boolean bools; the flags
        assert [bool(a) for a in fmi2[name][:5]] == fmi3[name][:5], name  # (nextEventTime: not defined)
    assert fmi2["der"] == [V_DRIVE, 0.0]


def test_fmi2_model_exchange_refusals_name_the_value_and_its_range(results):
    """A mass out of range is refused in model exchange as in co-simulation, naming M and its range; arrays of the
    wrong length name the array and the FMU's count; the instance keeps its states through the refusals."""
    record = case(results, 2, "exchange_refusals")
    wanted = {"fmi2GetDerivatives with M = -1 kg": "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)",
              "fmi2ExitInitializationMode with M = -1 kg": "M = -1.0 kg is out of range",
              "fmi2GetDerivatives of nx = 5": "nx = 5, but this FMU has 2 continuous states",
              "fmi2GetEventIndicators of ni = 2": "ni = 2, but this FMU has 3 event indicators",
              "fmi2SetTime of NaN": "time = nan s is out of range: allowed is a finite value",
              "fmi2SetContinuousStates of inf": "x = inf m is out of range"}
    for label, text in wanted.items():
        [call] = calls(record, label)
        assert call["result"] == ERROR and any(text in message[2] for message in call["messages"]), call
    assert record["values"]["states"] == [X_START, V_DRIVE]


def test_fmi2_status_inquiries_after_a_completed_step(results):
    values = case(results, 2, "status")["values"]
    assert values["last_successful_time"] == H
    assert values["terminated"] == 0  # fmi2Terminated: fmi2False, the slave does not ask to stop


def test_fmi3_model_exchange_of_the_stuck_block(results, unzipped3):
    """Counts and nominals as the model description gives them; while stuck der(x) = v = v_drive, der(v) = 0;
    at x = 0.05 m the indicators are stick 1, breakaway F_S - |kappa x - F_ext| = 0.95 N, graze 1 (stuck); no
    event, no termination; the outputs follow the states set."""
    _, description, variables = unzipped3
    values = case(results, 3, "model_exchange")["values"]
    assert values["counts"] == [len(description.derivatives), len(description.eventIndicators)] == [2, 3]
    assert values["nominals"] == [float(variables[name].nominal or 1.0) for name in ("x", "v")]
    assert values["states"] == [X_START, V_DRIVE]
    assert values["derivatives"] == [V_DRIVE, 0.0]
    x = X_START + V_DRIVE * H
    assert values["indicators"] == pytest.approx([1.0, F_S - KAPPA * x, 1.0], rel=0, abs=EXACT)
    assert values["completed"] == [False, False]  # enterEventMode, terminateSimulation
    for update in (values["first_update"], values["second_update"]):  # discreteStatesNeedUpdate, terminate,
        assert update[:3] == [False, False, False] and update[4] is False  # nominals changed, next event time
    assert values["outputs"] == pytest.approx([x, V_DRIVE, H], rel=0, abs=EXACT)


# ---- the debug-logging filter ---------------------------------------------------------------------------------


def test_the_model_descriptions_list_the_categories_the_tests_use(unzipped, unzipped3):
    for _, description, _ in (unzipped, unzipped3):
        assert tuple(category.name for category in description.logCategories) == LISTED


def _log_params():
    return [pytest.param(fmi_version, setting, id=f"FMI {fmi_version}, {setting}")
            for fmi_version in (2, 3) for setting in LOG_SETTINGS]


def _messages(record):
    return [message for call in record["calls"] for message in call["messages"]]


@pytest.mark.parametrize("fmi_version, setting", _log_params())
def test_debug_logging_takes_the_listed_categories_and_refuses_others(results, fmi_version, setting):
    record = case(results, fmi_version, _log_case(setting))
    for index, (_, categories) in enumerate(LOG_SETTINGS[setting][1]):
        [call] = calls(record, f"fmi{fmi_version}SetDebugLogging #{index}")
        unknown = [name for name in categories if name not in LISTED]
        check_outcome(call, "refused" if unknown else "ok")
        assert all((f'"{name}"' if name else "NULL") in call["messages"][0][2] for name in unknown), call


@pytest.mark.parametrize("fmi_version, setting", _log_params())
def test_warnings_and_errors_reach_the_logger_at_every_setting(results, fmi_version, setting):
    """The slave's messages of status warning, discard, error and fatal (fatal is reported as error during a call
    whose failure the binary reports as fmi*Error), an unsupported call's error and a bad parameter's error reach
    the logger whatever the setting (docs/hosts.md, "Errors at every logging setting")."""
    record = case(results, fmi_version, _log_case(setting))
    received = {message: (status, category) for status, category, message in _messages(record)}
    for message, status in record["values"]["queued"].items():
        if status >= WARNING:
            name = ("warning", "discard", "error", "fatal")[status - WARNING]
            assert received.get(message) in [(status, f"logStatus{name.capitalize()}"),
                                             (ERROR, "logStatusFatal")][:1 + (status == FATAL)], message
    check_outcome(calls(record, f"fmi{fmi_version}GetDirectionalDerivative")[0], "refused")
    bad_mass = "M = -1.0 kg is out of range"
    failing = [f"fmi{fmi_version}ExitInitializationMode with M = -1 kg"]
    if fmi_version == 3:
        check_outcome(calls(record, "fmi3GetFloat32")[0], "refused")
        failing.append("fmi3GetContinuousStateDerivatives with M = -1 kg")
    for label in failing:
        [call] = calls(record, label)
        assert call["result"] == ERROR and any(m[0] == ERROR and bad_mass in m[2] for m in call["messages"]), call


@pytest.mark.parametrize("fmi_version, setting", _log_params())
def test_information_messages_reach_the_logger_as_the_setting_asks(results, fmi_version, setting):
    record = case(results, fmi_version, _log_case(setting))
    [information] = [message for message, status in record["values"]["queued"].items() if status == OK]
    received = {message: (status, category) for status, category, message in _messages(record)}
    wanted = information_wanted(fmi_version, *LOG_SETTINGS[setting])
    assert received.get(information) == ((OK, "logAll") if wanted else None)


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_every_message_has_a_category_the_model_description_lists(results, fmi_version):
    records = (case(results, fmi_version, name) for name in results[fmi_version])
    categories = {message[1] for record in records for message in _messages(record)}
    assert categories <= set(LISTED), categories


#: s: the first stick of the runner's SLIDING block (the reference integrator's, tests/test_fmi3_early_return.py
#: checks every event of the scene against it); the stepper locates it to its event precision
FIRST_STICK = 29.26831861812952


def test_fmi3_output_derivatives_of_the_stuck_block(results):
    """fmi3GetOutputDerivatives of x and v, orders 1 and 2, of the stuck block (SPEC section 2: x moves with the
    drive, v is held): v_drive, 0, 0, 0 for der(x), der(x, 2), der(v), der(v, 2) asked for as (x, 1), (v, 2)."""
    assert case(results, 3, "refused")["values"]["derivatives"] == [V_DRIVE, 0.0]


def test_fmi3_event_mode_and_early_return_follow_the_state_machine(results):
    """With eventModeUsed and earlyReturnAllowed: Event Mode after initialization needs no update; a step of 40 s
    returns early at the first stick with eventHandlingNeeded, lastSuccessfulTime there and the state before it
    (slipping, v = v_drive); fmi3UpdateDiscreteStates in Event Mode applies it (stuck) and asks for nothing more;
    the rest of the step completes."""
    values = case(results, 3, "event_mode")["values"]
    assert values["first_update"] == [False, False, False, False, False, 0.0]
    handling, terminate, early, last = values["early"]
    assert (handling, terminate, early) == (True, False, True)
    assert last == pytest.approx(FIRST_STICK, rel=1e-12)
    assert values["v_before"] == pytest.approx([V_DRIVE], rel=1e-9)
    assert values["modes"] == [[1], [0]]
    assert values["update"] == [False, False, False, False, False, 0.0]
    assert values["rest"][:3] == [False, False, False] and values["rest"][3] == pytest.approx(40.0, rel=1e-15)
