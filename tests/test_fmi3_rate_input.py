"""The FMI 3 FMU's input ``der(F_ext)`` (N/s), in place of FMI 2's fmi2SetRealInputDerivatives (FMI 3 co-simulation
has none): a ramp of F_ext set through it is followed to the closed form through the FMU, setting F_ext keeps the
rate (an input of its own), a saved state keeps it, and a rate that is not finite is refused by name, the rate kept."""

import math

import pytest
from fmu_instances import instantiate3
from test_fmi3 import reals
from test_input_rate import RATE, ramp_motion

COULOMB_AT_REST = {"M": 1.0, "kappa": 1.0, "kinetic.law": 1, "kinetic.F0": 0.5, "static.law": 1, "static.F0": 1.0,
                   "x_start": 0.0, "v_start": 0.0, "v_drive": 0.0, "F_ext": 0.0, "der(F_ext)": RATE}


def steps(fmu, unzipped3, t0, t1, h=0.25):
    """``[(t, x, v)]`` after each doStep of ``h`` s from ``t0`` to ``t1``."""
    out, t = [], t0
    while t < t1 - 1e-12:
        fmu.doStep(t, h)
        t += h
        out.append((t, *reals(fmu, unzipped3, ["x", "v"])))
    return out


def test_a_ramp_set_through_der_F_ext_is_followed_to_the_closed_form(unzipped3, capfd):
    """A Coulomb block at rest on a still surface loaded by F_ext = RATE t: stuck until RATE t = F_S (4 s), then the
    forced oscillator of the closed form; F_ext set to its ramp value at 5 s keeps the rate; a state saved at 5 s
    goes on the same; der(F_ext) = NaN is refused, the log naming it."""
    fmu = instantiate3(unzipped3, "ramp", COULOMB_AT_REST)
    refs = unzipped3[2]
    try:
        for t, x, v in steps(fmu, unzipped3, 0.0, 5.0):
            expected = (0.0, 0.0) if t < 4.0 else ramp_motion(t)
            assert abs(x - expected[0]) < 1e-12 and abs(v - expected[1]) < 1e-12, t
        fmu.setFloat64([refs["F_ext"].valueReference], [RATE * 5.0])
        assert reals(fmu, unzipped3, ["der(F_ext)"]) == [RATE]
        state = fmu.getFMUState()
        after = steps(fmu, unzipped3, 5.0, 6.5)
        for t, x, v in after:
            expected = ramp_motion(t)
            assert abs(x - expected[0]) < 1e-12 and abs(v - expected[1]) < 1e-12, t
        fmu.setFMUState(state)
        assert steps(fmu, unzipped3, 5.0, 6.5) == after
        fmu.freeFMUState(state)
        capfd.readouterr()
        with pytest.raises(Exception, match="fmi3SetFloat64"):
            fmu.setFloat64([refs["der(F_ext)"].valueReference], [math.nan])
        assert "der(F_ext, 1) = nan" in capfd.readouterr().out  # the log names it
        assert reals(fmu, unzipped3, ["der(F_ext)"]) == [RATE]
    finally:
        fmu.terminate()
        fmu.freeInstance()
