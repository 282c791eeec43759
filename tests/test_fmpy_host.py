"""The one FMPy host (:mod:`stickslip.hosts.fmpy_host`): the variable lists read from the table agree with the
built FMUs, an :class:`ExtractedFMU` serves the suite, the stress tests and the benchmark alike, a failed call
carries its function, status and log, and an instance that reported Fatal is never freed."""

import pytest
from fmpy.fmi1 import FMICallException

from stickslip.fmu import variables
from stickslip.hosts.fmpy_host import FATAL, ExtractedFMU, FmuCallError, Instance, run_fmu

STICK_SLIP = {"kinetic.F0": 0.5, "static.F0": 1.0, "v_start": 0.1}
#: FMPy's type names of the table's kinds, FMI 2 and FMI 3
TYPES = {"real": ("Real", "Float64"), "integer": ("Integer", "Int32")}


@pytest.mark.parametrize("fmu", ["fmu_path", "fmu3_path"])
def test_the_tables_names_kinds_and_start_values_are_the_fmus(request, fmu):
    with ExtractedFMU(request.getfixturevalue(fmu)) as extracted:
        declared = extracted.variables
        assert tuple(n for n, v in declared.items() if v.causality == "output") == variables.OUTPUTS
        rate = (variables.RATE_INPUT,) if fmu == "fmu3_path" else ()  # FMI 3 only: FMI 2 has input derivatives
        assert tuple(n for n, v in declared.items() if v.causality == "input") == variables.INPUTS + rate
        for kind, names in (("real", variables.REAL_OUTPUTS), ("integer", variables.INTEGER_OUTPUTS)):
            assert all(declared[n].type in TYPES[kind] for n in names), kind
        assert extracted.defaults == {**variables.START_VALUES, **{name: 0.0 for name in rate}}


def test_run_fmu_and_extracted_simulate_give_the_same_numbers(fmu_path):
    """The suite's host (an instance of its own, logging) and the benchmark's call (FMPy's instance)."""
    outputs = ["x", "v", "n_events", "t_last_event"]
    hosted = run_fmu(fmu_path, STICK_SLIP, 30.0, 0.5, outputs=outputs)
    with ExtractedFMU(fmu_path) as extracted:
        plain = extracted.simulate(STICK_SLIP, 30.0, 0.5, outputs)
    assert hosted.tobytes() == plain.tobytes() and hosted["n_events"][-1] >= 2


def test_a_failed_run_names_the_function_the_status_and_the_fmus_message(fmu_path):
    with pytest.raises(FmuCallError) as error:
        run_fmu(fmu_path, {"kappa": -2.0}, 1.0, 0.5)
    assert error.value.function == "fmi2ExitInitializationMode" and error.value.status == 3
    assert any("kappa = -2.0 N/m is out of range" in m for m in error.value.messages)
    assert str(error.value).startswith("fmi2ExitInitializationMode failed with status 3 (error)\n")


class _Slave:
    """An FMPy object whose every call reports ``status``; it records what was called."""

    def __init__(self, status):
        self.status, self.calls = status, []

    def doStep(self):  # noqa: N802 -- FMPy's name
        self.calls.append("doStep")
        raise FMICallException("fmi2DoStep", self.status)

    def terminate(self):
        self.calls.append("terminate")

    def freeInstance(self):  # noqa: N802 -- FMPy's name
        self.calls.append("freeInstance")


class _FMI2:
    fmi_version = 2


@pytest.mark.parametrize("status, freed", [(3, ["terminate", "freeInstance"]), (FATAL[2], [])],
                         ids=["error", "fatal"])
def test_an_instance_is_never_freed_after_fatal(status, freed):
    slave = _Slave(status)
    with Instance(_FMI2(), slave, "fake") as instance:
        with pytest.raises(FmuCallError) as error:
            instance.call(slave.doStep)
        assert (error.value.function, error.value.status, instance.fatal) == ("fmi2DoStep", status, status == 4)
    instance.free()  # once only
    assert slave.calls == ["doStep", *freed]


def test_libcosims_error_text_comes_through_its_public_c_function():
    pytest.importorskip("libcosimpy.CosimExecution")
    from libcosimpy.CosimExecution import CosimExecution

    from stickslip.stress.cosim import libcosim_last_error

    execution = CosimExecution.from_step_size(10**8)
    assert execution.connect_real_variables(5, 0, 6, 0) != 0  # no such instances
    assert libcosim_last_error().strip()  # the C++ exception's text
