"""The coupling FMU's refusals through its C loader: a bad value, a force that overflows or bytes that are no state
give fmi2Error with a message naming the value and the allowed range, the previous values are kept, the instance
goes on, and freeing it and making new ones does not crash the host.

Each case runs in its own child process (``loader_probe.py``, a plain ctypes host of the extracted binary), whose
exit status is asserted. A case is repeated on several instances, each freed after its refusal: PythonFMU released
a slave whose method raised once too often, and the host died with SIGSEGV once the garbage collector freed it (the
refusals were fmi2Fatal then)."""


import pytest

from test_loader_robustness import ERROR, errors, probe

ROUNDS = 5  # instances refused and freed before a last one runs (the old slave crashed the host within 30)
#: the values before each refusal: F = 1 (1 - 0.5) + 2 (0 - 0.5) = -0.5 N
BEFORE = {"kc_left": 1.0, "kc_right": 2.0}
POSITIONS = {"x_left": 1.0, "x": 0.5, "x_right": 0.0}
F_BEFORE = -0.5
NAN, INF = "float('nan')", "float('inf')"

#: name: (the refused call, as code of the probe on the instance c after initialization; the message's text; F
#: after the refusal (N), None where it stays refused)
REFUSALS = {
    "x_left nan": (f"put(c, x_left={NAN})", "x_left = nan m is out of range: allowed is a finite value in (-inf, inf)",
                   F_BEFORE),
    "x inf": (f"put(c, x={INF})", "x = inf m is out of range: allowed is a finite value in (-inf, inf)", F_BEFORE),
    "x_right -inf": (f"put(c, x_right=-{INF})", "x_right = -inf m is out of range", F_BEFORE),
    "one bad value of two": (f"put(c, x_left=5.0, x={NAN})", "x = nan m is out of range", F_BEFORE),
    "a stiffness after initialization": ("put(c, kc_left=3.0)",
                                         "kc_left is a fixed parameter: it cannot change after initialization",
                                         F_BEFORE),
    "a force that overflows": ("put(c, x_left=1e308, x=-1e308) or get(c, 'F')[0]",
                               "F = inf N is not finite: the springs' force overflows at kc_left = 1.0 N/m", None),
    "a derivative that overflows": (
        "call('fmi2SetRealInputDerivatives', c, _vrs(['x_left', 'x']), 2, (ctypes.c_int * 2)(1, 1), "
        "(c_double * 2)(1e308, -1e308)) or call('fmi2GetRealOutputDerivatives', c, _vrs(['F']), 1, "
        "(ctypes.c_int * 1)(1), (c_double * 1)())", "der(F, 1) = inf N/s^1 is not finite", F_BEFORE),
    "bytes that are no state": ("call(STATE['deserialize'], c, b'garbage', 7, byref(c_void_p()))",
                                "the 7 bytes are not a serialized FMU state of this FMU", F_BEFORE),
    "a state with a negative stiffness": (  # kc_left, the fourth value after the 14 bytes of the header, forged
        "call(STATE['deserialize'], c, (data := serialized(c)[:38] + struct.pack('<d', -1.0) + serialized(c)[46:]), "
        "len(data), byref(saved)) or call(STATE['set'], c, saved)",
        "kc_left = -1.0 N/m is out of range: allowed is a finite value in [0, inf)", F_BEFORE),
}
#: name: (the stiffnesses set during initialization, the message's text)
PARAMETER_REFUSALS = {
    "kc_left negative": ({"kc_left": -1.0},
                         "kc_left = -1.0 N/m is out of range: allowed is a finite value in [0, inf)"),
    "kc_right nan": ({"kc_right": NAN}, "kc_right = nan N/m is out of range: allowed is a finite value in [0, inf)"),
    "kc_left inf": ({"kc_left": INF}, "kc_left = inf N/m is out of range"),
}


def _case(refused, initializing=""):
    """The probe's code: ROUNDS instances each refused (by the code ``refused``, during initialization if
    ``initializing``) and freed, then a new instance that runs."""
    return f"""
        import ctypes, gc, struct
        for round in range(ROUNDS):
            c = instantiate()
            start(c, **BEFORE)
            saved = c_void_p()
            {initializing}
            say("exit", call("fmi2ExitInitializationMode", c))
            put(c, **POSITIONS)
            say("refused", {refused})
            say("F", *get(c, "F"))
            put(c, **POSITIONS)
            say("step", step(c, 0.0, 0.1), *get(c, "F"))
            call("fmi2FreeInstance", c)
            gc.collect()
        c = instantiate()
        say("again", initialized(c, **BEFORE), put(c, **POSITIONS), *get(c, "F"), step(c, 0.0, 0.1))
        call("fmi2FreeInstance", c)
    """.replace("ROUNDS", str(ROUNDS)).replace("**BEFORE", f"**{BEFORE!r}").replace("**POSITIONS", f"**{POSITIONS!r}")


def _ran_on(run):
    """The last instance, made after the refused ones were freed, initialized, was set and stepped."""
    assert run["again"] == [0, 0, 0, F_BEFORE, 0]


@pytest.mark.parametrize("name", REFUSALS)
def test_a_refused_call_is_an_error_naming_the_value_and_the_instance_goes_on(unzipped_coupling, name):
    refused, message, f_after = REFUSALS[name]
    run = probe(unzipped_coupling[0], _case(refused))
    assert run.all("refused") == [[ERROR]] * ROUNDS
    assert all(message in text for text in errors(run)) and len(errors(run)) >= ROUNDS, run.logs
    if f_after is not None:  # the values before the refused call
        assert run.all("F") == [[0, f_after]] * ROUNDS
    assert run.all("step") == [[0, 0, F_BEFORE]] * ROUNDS
    _ran_on(run)


@pytest.mark.parametrize("name", PARAMETER_REFUSALS)
def test_a_bad_stiffness_is_refused_when_set_and_the_instance_goes_on(unzipped_coupling, name):
    values, message = PARAMETER_REFUSALS[name]
    setting = ", ".join(f"{key}={value}" for key, value in values.items())
    run = probe(unzipped_coupling[0], _case("0", f'say("set", put(c, {setting}))'))
    assert run.all("set") == [[ERROR]] * ROUNDS and run.all("exit") == [[0]] * ROUNDS
    assert len(errors(run)) == ROUNDS and all(message in text for text in errors(run)), run.logs
    assert run.all("F") == [[0, F_BEFORE]] * ROUNDS  # the stiffnesses before
    _ran_on(run)


def test_a_stiffness_of_zero_leaves_its_neighbour_unused(unzipped_coupling):
    """kc_left = 0: no force from x_left, wherever it is (0 * (1e308 - -1e308) was nan)."""
    run = probe(unzipped_coupling[0], """
        c = instantiate()
        say("exit", initialized(c, kc_left=0.0, kc_right=2.0))
        say("set", put(c, x_left=1.7e308, x=-1.7e308, x_right=-1.7e308 + 4e292))
        say("F", *get(c, "F"))
        call("fmi2FreeInstance", c)
    """)
    assert run["exit"] == [0] and run["set"] == [0]
    assert run["F"] == [0, 2.0 * ((-1.7e308 + 4e292) - -1.7e308)]


def test_a_huge_stiffness_with_neighbours_20_m_apart_is_an_error_naming_the_values(unzipped_coupling):
    """kc_left = 1e308 N/m and x_left - x = 20 m: F overflowed to inf with fmi2OK; now reading it is an error naming
    the values, and F reads again once the positions give a finite force."""
    run = probe(unzipped_coupling[0], """
        c = instantiate()
        say("exit", initialized(c, kc_left=1e308))
        say("set", put(c, x_left=10.0, x=-10.0))
        say("F", *get(c, "F"))
        say("closer", put(c, x_left=0.5, x=0.0), *get(c, "F"))
        call("fmi2FreeInstance", c)
    """)
    assert run["exit"] == [0] and run["set"] == [0]
    assert run["F"] == [ERROR, 0.0]
    [message] = errors(run)
    assert "F = inf N is not finite: the springs' force overflows at kc_left = 1e+308 N/m" in message
    assert "x_left, x, x_right = 10.0, -10.0, 0.0" in message
    assert run["closer"] == [0, 0, 0.5e308]
