"""The blocks of the ``me`` master: N FMI 3 model-exchange instances seen as one system of ``2N`` states.

:class:`ExchangeBlocks` loads a time and a state vector ``y = [x_1..x_N, v_1..v_N]`` (m, m/s) into every
instance (``fmi3SetTime``, ``F_ext_i`` from the positions by SPEC section 5, ``fmi3SetContinuousStates``) and
reads the derivatives and the event indicators there; it runs the event update of every block. A load is
skipped when the same ``(t, y)`` is already loaded.
"""

from ctypes import c_double

import numpy as np

from ..hosts.fmpy_host import FMUError
from .master import references

MAX_UPDATES = 100  # updateDiscreteStates calls of one block at one event


class ExchangeBlocks:
    """The instances ``instances`` (initialized, of the ExtractedFMU ``fmu``) of ``system``'s blocks."""

    def __init__(self, system, fmu, instances):
        self.system, self.instances, self.n = system, instances, len(instances)
        self.F_ext = references(fmu, ("F_ext",))
        self.counters = references(fmu, ("mode", "n_events"))
        self.nz = instances[0].fmu.getNumberOfEventIndicators()
        self._buffer, self._z = (c_double * 2)(), (c_double * self.nz)()
        self._loaded = None
        self.evaluations = 0

    def _load_one(self, instance, t, x, v, F):
        fmu = instance.fmu
        fmu.setTime(t)
        fmu.setFloat64(self.F_ext, [F])
        self._buffer[0], self._buffer[1] = x, v
        fmu.setContinuousStates(self._buffer, 2)

    def load(self, t, y):
        """Set time ``t`` (s), the coupling forces and the states ``y`` in every instance."""
        key = (t, y.tobytes())
        if key == self._loaded:
            return
        n = self.n
        forces = self.system.forces(y[:n])
        for i, instance in enumerate(self.instances):
            instance.call(self._load_one, instance, float(t), float(y[i]), float(y[n + i]), forces[i])
        self._loaded = key

    def _pairs(self, getter):
        """``[a_1..a_N, b_1..b_N]`` from each instance's two-value FMI 3 getter named ``getter``."""
        out = np.empty(2 * self.n)
        for i, instance in enumerate(self.instances):
            instance.call(getattr(instance.fmu, getter), self._buffer, 2)
            out[i], out[self.n + i] = self._buffer[0], self._buffer[1]
        return out

    def derivatives(self, t, y):
        """``[x_1'..x_N', v_1'..v_N']`` (m/s, m/s^2) at ``(t, y)``: the right-hand side for the solver."""
        self.load(t, y)
        self.evaluations += 1
        out = self._pairs("getContinuousStateDerivatives")
        if not np.all(np.isfinite(out)):
            raise FMUError(f"me: non-finite derivatives {out.tolist()} at t = {t!r} s")
        return out

    def indicators(self, t, y):
        """Every block's event indicators at ``(t, y)``: shape ``(N, nz)``."""
        self.load(t, y)
        out = np.empty((self.n, self.nz))
        for i, instance in enumerate(self.instances):
            instance.call(instance.fmu.getEventIndicators, self._z, self.nz)
            out[i] = self._z[:]
        return out

    def block_indicators(self, t, y, i):
        """Block ``i``'s event indicators at ``(t, y)``, only it loaded (its ``F_ext`` from the positions in ``y``):
        what locating one block's event needs, at the cost of one block, not ``N``."""
        instance = self.instances[i]
        instance.call(self._load_one, instance, float(t), float(y[i]), float(y[self.n + i]),
                      self.system.forces(y[:self.n])[i])
        self._loaded = None  # the others are where they were
        instance.call(instance.fmu.getEventIndicators, self._z, self.nz)
        return self._z[:]

    def states(self):
        """The instances' states ``y`` (after an event update a block's ``v`` may have changed)."""
        return self._pairs("getContinuousStates")

    def nominals(self):
        """The instances' nominals of ``y`` (``F_S(0)/kappa`` m, ``F_S(0)/sqrt(kappa M)`` m/s), the solver's scales."""
        return self._pairs("getNominalsOfContinuousStates")

    def counts(self):
        """``(modes, n_events)``: each block's ``mode`` and ``n_events`` outputs."""
        values = [instance.call(instance.fmu.getInt32, self.counters) for instance in self.instances]
        return [v[0] for v in values], [v[1] for v in values]

    def initial_update(self):
        """The event update that ends initialization (the instances are in event mode), then continuous-time mode."""
        self._update(0.0, enter=False)

    def update(self, t, y):
        """The event update of every block at ``(t, y)``: event mode, ``updateDiscreteStates`` until the block needs
        no more, continuous-time mode."""
        self.load(t, y)
        self._update(t, enter=True)
        self._loaded = None  # the update may have moved the states

    def _update(self, t, enter):
        for number, instance in enumerate(self.instances, 1):
            if enter:
                instance.call(instance.fmu.enterEventMode)
            for _ in range(MAX_UPDATES):
                needed, terminate, *_ = instance.call(instance.fmu.updateDiscreteStates)
                if terminate:
                    raise FMUError(f"me: block b{number} asked to terminate at t = {t!r} s")
                if not needed:
                    break
            else:
                raise FMUError(f"me: block b{number} still needs a discrete update after {MAX_UPDATES} at t = {t!r} s")
            instance.call(instance.fmu.enterContinuousTimeMode)
