"""Model exchange's state machine (FMI 2.0 section 3.2.3, FMI 3.0 section 3.2): a call made in a state where the
standard does not allow it is refused with an error status and a message naming the call and the state the instance
is in, in both FMUs (FMPy's FMU2Model and FMU3Model, the calls one by one); the instance goes on as before after it.
The right sequences are those of FMPy's and fmusim's model exchange (tests/test_fmi2_model_exchange.py,
tests/test_cvode_model_exchange.py, tests/test_model_exchange_suite.py).
"""

import pytest

from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

#: FMI version: the name of the discrete-state update
UPDATE = {2: "fmi2NewDiscreteStates", 3: "fmi3UpdateDiscreteStates"}


@pytest.fixture(params=[2, 3], ids=["fmi2", "fmi3"])
def exchange(request, fmu_path, fmu3_path):
    """``(FMI version, a new model-exchange instance, instantiated only)``, freed after the test."""
    with ExtractedFMU(fmu_path if request.param == 2 else fmu3_path) as extracted:
        instance = extracted.new_instance(interface="me")
        try:
            yield request.param, instance
        finally:
            instance.free(terminate=False)


def initialize(version, instance, **values):
    """Through Initialization Mode with the Float64 ``values`` set; the status of exitInitializationMode raised as
    FmuCallError."""
    fmu = instance.fmu
    if version == 2:
        instance.call(fmu.setupExperiment, startTime=0.0)
        instance.call(fmu.enterInitializationMode)
    else:
        instance.call(fmu.enterInitializationMode, startTime=0.0)
    references = [instance.extracted.variables[name].valueReference for name in values]
    instance.call(fmu.setReal if version == 2 else fmu.setFloat64, references, list(values.values()))
    instance.call(fmu.exitInitializationMode)


def update(version, instance):
    fmu = instance.fmu
    return instance.call(fmu.newDiscreteStates if version == 2 else fmu.updateDiscreteStates)


def refused(version, instance, function, state, call, *args):
    """``call(*args)`` fails with an error status and one message naming ``function`` (FMI version prefix added)
    and the instance's ``state``."""
    name = f"fmi{version}{function}"
    with pytest.raises(FmuCallError) as failure:
        instance.call(call, *args)
    assert failure.value.status == 3  # error, not fatal: the instance stays usable
    assert [m for m in failure.value.messages if name in m and f"in {state}" in m], failure.value.messages


def test_the_discrete_state_update_is_refused_in_continuous_time_mode(exchange):
    version, instance = exchange
    initialize(version, instance)
    update(version, instance)  # Event Mode after initialization: allowed
    instance.call(instance.fmu.enterContinuousTimeMode)
    refused(version, instance, UPDATE[version][4:], "Continuous-Time Mode",
            instance.fmu.newDiscreteStates if version == 2 else instance.fmu.updateDiscreteStates)
    instance.call(instance.fmu.setTime, 1.0)  # and the instance goes on in Continuous-Time Mode
    instance.call(instance.fmu.completedIntegratorStep)
    instance.call(instance.fmu.enterEventMode)
    update(version, instance)


def test_completed_integrator_step_is_refused_in_event_mode(exchange):
    version, instance = exchange
    initialize(version, instance)
    refused(version, instance, "CompletedIntegratorStep", "Event Mode", instance.fmu.completedIntegratorStep)
    update(version, instance)
    instance.call(instance.fmu.enterContinuousTimeMode)
    instance.call(instance.fmu.completedIntegratorStep)


def test_set_time_is_refused_after_terminate(exchange):
    version, instance = exchange
    initialize(version, instance)
    instance.call(instance.fmu.terminate)
    refused(version, instance, "SetTime", "Terminated", instance.fmu.setTime, 1.0)
    refused(version, instance, UPDATE[version][4:], "Terminated",
            instance.fmu.newDiscreteStates if version == 2 else instance.fmu.updateDiscreteStates)


@pytest.mark.parametrize("function", ["EnterContinuousTimeMode", "EnterEventMode"])
def test_mode_changes_are_refused_after_initialization_failed(exchange, function):
    """A block of negative mass fails exitInitializationMode; entering Continuous-Time or Event Mode is then refused
    (the instance is still in Initialization Mode), and so is every later one, until a good mass succeeds."""
    version, instance = exchange
    with pytest.raises(FmuCallError, match="M"):
        initialize(version, instance, M=-1.0)
    method = getattr(instance.fmu, function[0].lower() + function[1:])
    refused(version, instance, function, "Initialization Mode", method)
    refused(version, instance, function, "Initialization Mode", method)
    instance.call(instance.fmu.setReal if version == 2 else instance.fmu.setFloat64,
                  [instance.extracted.variables["M"].valueReference], [1.0])
    instance.call(instance.fmu.exitInitializationMode)
    update(version, instance)
    instance.call(instance.fmu.enterContinuousTimeMode)
