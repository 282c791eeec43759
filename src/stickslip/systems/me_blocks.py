"""The blocks of the ``me`` master: N FMI 3 model-exchange instances seen as one system of ``2N`` states.

:class:`ExchangeBlocks` loads a time and a state vector ``y = [x_1..x_N, v_1..v_N]`` (m, m/s) into every
instance (``fmi3SetTime``, ``F_ext_i`` from the positions by SPEC section 5, ``fmi3SetContinuousStates``) and
reads the derivatives and the event indicators there; it runs the event update of every block. A load is
skipped when the same ``(t, y)`` is already loaded, and a block's ``F_ext`` is not set again where its bits did not
change (an input keeps its value: about half the loads on the Burridge-Knopoff chain, stuck blocks between stuck
neighbours). The calls of a derivative evaluation go to the FMU's C functions on arrays made once (each block's views
into one NumPy array per quantity), one status check each.
"""

from ctypes import c_double, c_uint

import numpy as np

from ..hosts.fmpy_host import WARNING, FMUError, log_mark
from ..hosts.interrupts import check as check_interrupts
from .master import references

MAX_UPDATES = 100  # updateDiscreteStates calls of one block at one event


class _Block:
    """One instance's C functions and its views (ctypes arrays) of the blocks' arrays: its ``(x, v)``, ``F_ext``,
    derivatives and event indicators."""

    FUNCTIONS = ("fmi3SetTime", "fmi3SetFloat64", "fmi3SetContinuousStates", "fmi3GetContinuousStateDerivatives",
                 "fmi3GetEventIndicators")

    def __init__(self, instance, state, force, derivatives, indicators):
        self.instance, self.component = instance, instance.fmu.component
        (self.set_time, self.set_float64, self.set_states, self.get_derivatives,
         self.get_indicators) = (instance.function(name) for name in self.FUNCTIONS)
        self.state, self.force, self.derivatives, self.indicators = (
            np.ctypeslib.as_ctypes(a) for a in (state, force, derivatives, indicators))
        self.force_bits = None  # the bits of the F_ext last set (None: none set here)


class ExchangeBlocks:
    """The instances ``instances`` (initialized, of the ExtractedFMU ``fmu``) of ``system``'s blocks."""

    def __init__(self, system, fmu, instances):
        self.system, self.instances, self.n = system, instances, len(instances)
        self.F_ext = references(fmu, ("F_ext",))
        self.counters = references(fmu, ("mode", "n_events"))
        self.nz = instances[0].fmu.getNumberOfEventIndicators()
        self._buffer, self._force_ref = (c_double * 2)(), (c_uint * 1)(*self.F_ext)
        # per block (rows): its (x, v), F_ext, derivatives and indicators, which the calls read and write
        self._y, self._f = np.zeros((self.n, 2)), np.zeros(self.n)
        self._dy, self._z = np.zeros((self.n, 2)), np.zeros((self.n, self.nz))
        self._f_bits = [None] * self.n  # the bits of each F_ext in _f (an int64 each)
        self._blocks = [_Block(instance, self._y[i], self._f[i:i + 1], self._dy[i], self._z[i])
                        for i, instance in enumerate(instances)]
        self._loaded = None  # the (t, y) loaded in every instance, None if unknown
        self._indicators_at = None  # the (t, y) where _z holds every block's indicators
        self.evaluations = 0

    def _load_block(self, block, t, force_bits, first):
        """Time ``t`` (s), the block's ``F_ext`` (whose bits are ``force_bits``: not set again if it holds them, as an
        input keeps its value) and ``(x, v)`` from its arrays into its instance (log mark ``first``)."""
        c = block.component
        status = block.set_time(c, t)
        if status > WARNING:
            raise block.instance.failure("fmi3SetTime", status, first)
        if force_bits != block.force_bits:
            status = block.set_float64(c, self._force_ref, 1, block.force, 1)
            if status > WARNING:
                raise block.instance.failure("fmi3SetFloat64", status, first)
            block.force_bits = force_bits
        status = block.set_states(c, block.state, 2)
        if status > WARNING:
            raise block.instance.failure("fmi3SetContinuousStates", status, first)

    def _stage(self, t, y):
        """``(float t, log mark)`` with ``y``'s positions, velocities and forces in the arrays the calls read."""
        n = self.n
        self._y[:, 0], self._y[:, 1] = y[:n], y[n:]
        self._f[:] = self.system.force_array(self._y[:, 0])
        self._f_bits = self._f.view(np.int64).tolist()
        check_interrupts()
        return float(t), log_mark()

    def load(self, t, y):
        """Set time ``t`` (s), the coupling forces and the states ``y`` in every instance."""
        self._pass(t, y, read_derivatives=False)

    def _pass(self, t, y, read_derivatives):
        """One pass over the blocks: each loaded with ``(t, y)`` unless that is loaded, its derivatives read into
        their array if ``read_derivatives``."""
        key = (t, y.tobytes())
        load = key != self._loaded
        t, first = self._stage(t, y) if load else (float(t), log_mark())
        for block, force_bits in zip(self._blocks, self._f_bits):
            if load:
                self._load_block(block, t, force_bits, first)
            if read_derivatives:
                status = block.get_derivatives(block.component, block.derivatives, 2)
                if status > WARNING:
                    raise block.instance.failure("fmi3GetContinuousStateDerivatives", status, first)
        self._loaded = key
        check_interrupts()

    def derivatives(self, t, y):
        """``[x_1'..x_N', v_1'..v_N']`` (m/s, m/s^2) at ``(t, y)``: the right-hand side for the solver."""
        self._pass(t, y, read_derivatives=True)
        self.evaluations += 1
        out = np.concatenate((self._dy[:, 0], self._dy[:, 1]))
        if not np.all(np.isfinite(out)):
            raise FMUError(f"me: non-finite derivatives {out.tolist()} at t = {t!r} s")
        return out

    def _read_indicators(self, block, first):
        status = block.get_indicators(block.component, block.indicators, self.nz)
        if status > WARNING:
            raise block.instance.failure("fmi3GetEventIndicators", status, first)

    def indicators(self, t, y):
        """Every block's event indicators at ``(t, y)``: shape ``(N, nz)`` (read again only where the load moved)."""
        self.load(t, y)
        if self._indicators_at != self._loaded:
            first = log_mark()
            for block in self._blocks:
                self._read_indicators(block, first)
            self._indicators_at = self._loaded
        return self._z.copy()

    def block_indicators(self, t, y, i):
        """Block ``i``'s event indicators at ``(t, y)``, only it loaded (its ``F_ext`` from the positions in ``y``):
        what locating one block's event needs, at the cost of one block, not ``N``."""
        block = self._blocks[i]
        t, first = self._stage(t, y)
        self._load_block(block, t, self._f_bits[i], first)
        self._loaded = self._indicators_at = None  # the others are where they were
        self._read_indicators(block, first)
        check_interrupts()
        return self._z[i].copy()

    def _pairs(self, getter):
        """``[a_1..a_N, b_1..b_N]`` from each instance's two-value FMI 3 getter named ``getter``."""
        out = np.empty(2 * self.n)
        for i, instance in enumerate(self.instances):
            instance.call(getattr(instance.fmu, getter), self._buffer, 2)
            out[i], out[self.n + i] = self._buffer[0], self._buffer[1]
        return out

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
        self._loaded = self._indicators_at = None  # the update may have moved the states and indicators

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
