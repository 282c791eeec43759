"""A chain for the compiled engine as flat arrays: :class:`ChainSpec` (SPEC section 5).

Block ``i`` (0-based here, ``b<i+1>`` in files and messages) has its mass ``M`` (kg), its wall spring ``kappa``
(N/m), its kinetic and static laws (codes and parameter rows, :mod:`.laws`) and its start state ``x0`` (m, from its
wall spring's relaxed position) and ``v0`` (m/s). ``coupling[i]`` (N/m) joins blocks ``i`` and ``i + 1``, relaxed
at ``x_i = x_(i+1)``; the surface moves at ``v_drive`` (m/s, constant).
"""

import math
from dataclasses import dataclass

import numpy as np

from ..core import Parameters, kinetic_law, static_law
from ..core.errors import ParameterError
from .laws import KINETIC_PARAMETERS, KINETIC_WIDTH, STATIC_PARAMETERS, STATIC_WIDTH


class ChainSpecError(ValueError):
    """A chain's values are out of range; the message names the block (``b<i>``) and the variable."""


@dataclass(frozen=True, eq=False)
class ChainSpec:
    """The chain as arrays over its ``N`` blocks: ``M``, ``kappa``, ``x0``, ``v0`` (shape ``(N,)``),
    ``kinetic_law`` and ``static_law`` (codes, ints), ``kinetic`` (``(N, 5)``) and ``static`` (``(N, 4)``) parameter
    rows in the orders of :data:`.laws.KINETIC_PARAMETERS` and :data:`.laws.STATIC_PARAMETERS`; ``coupling``
    (``(N - 1,)``, N/m) and ``v_drive`` (m/s). Checked when made: :class:`ChainSpecError` names the block and the
    variable."""

    M: np.ndarray
    kappa: np.ndarray
    kinetic_law: np.ndarray
    kinetic: np.ndarray
    static_law: np.ndarray
    static: np.ndarray
    x0: np.ndarray
    v0: np.ndarray
    coupling: np.ndarray
    v_drive: float

    def __post_init__(self):
        n = np.asarray(self.M).size
        for name, dtype, shape in (("M", float, (n,)), ("kappa", float, (n,)), ("x0", float, (n,)),
                                   ("v0", float, (n,)), ("kinetic_law", np.int64, (n,)),
                                   ("static_law", np.int64, (n,)), ("kinetic", float, (n, KINETIC_WIDTH)),
                                   ("static", float, (n, STATIC_WIDTH)), ("coupling", float, (max(n - 1, 0),))):
            value = np.array(getattr(self, name), dtype=dtype)
            if value.shape != shape:
                raise ChainSpecError(f"{name}: shape {value.shape}, allowed is {shape} for {n} blocks")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "v_drive", float(self.v_drive))
        self._check()

    @property
    def n(self):
        """The number of blocks."""
        return self.M.size

    def _check(self):
        if self.n == 0:
            raise ChainSpecError("a chain needs at least one block")
        if not math.isfinite(self.v_drive):
            raise ChainSpecError(f"v_drive = {self.v_drive!r} m/s: allowed is a finite value")
        for i, kc in enumerate(self.coupling):
            if not (math.isfinite(kc) and kc >= 0.0):
                raise ChainSpecError(f"coupling[{i}] (b{i + 1}-b{i + 2}) = {kc!r} N/m: allowed is a finite value >= 0")
        for i in range(self.n):
            for name, unit in (("x0", "m"), ("v0", "m/s")):
                value = getattr(self, name)[i]
                if not math.isfinite(value):
                    raise ChainSpecError(f"block b{i + 1}: {name} = {value!r} {unit}: allowed is a finite value")
            try:
                self.parameters(i).check()
            except ParameterError as exc:
                raise ChainSpecError(f"block b{i + 1}: {exc}") from None

    def parameters(self, i):
        """Block ``i``'s (0-based) :class:`stickslip.core.Parameters` (ParameterError for an unknown law code)."""
        laws = []
        for build, table, code, row in ((kinetic_law, KINETIC_PARAMETERS, self.kinetic_law[i], self.kinetic[i]),
                                        (static_law, STATIC_PARAMETERS, self.static_law[i], self.static[i])):
            names = table.get(int(code), ())
            laws.append(build(int(code), **dict(zip(names, map(float, row)))))
        return Parameters(self.M[i], self.kappa[i], *laws)

    @classmethod
    def from_blocks(cls, blocks, coupling, v_drive):
        """The chain of ``blocks``, each ``{FMU name: value}`` (``M``, ``kappa``, ``kinetic.law``, ``kinetic.<p>``,
        ``static.law``, ``static.<p>``, ``x_start``, ``v_start``; as a system file's blocks), joined by
        ``coupling`` (N/m) on a surface at ``v_drive`` (m/s)."""
        n = len(blocks)
        kinetic, static = np.zeros((n, KINETIC_WIDTH)), np.zeros((n, STATIC_WIDTH))
        for i, block in enumerate(blocks):
            for kind, table, rows in (("kinetic", KINETIC_PARAMETERS, kinetic), ("static", STATIC_PARAMETERS, static)):
                code = block.get(f"{kind}.law")
                if code not in table:
                    raise ChainSpecError(f"block b{i + 1}: {kind}.law = {code!r}: allowed are {sorted(table)}")
                for j, name in enumerate(table[code]):
                    key = f"{kind}.{name}"
                    if key not in block:
                        raise ChainSpecError(f"block b{i + 1}: {key} is missing")
                    rows[i, j] = block[key]
        column = [[b.get(k, math.nan) for b in blocks] for k in ("M", "kappa", "x_start", "v_start")]
        return cls(M=column[0], kappa=column[1], kinetic_law=[b["kinetic.law"] for b in blocks], kinetic=kinetic,
                   static_law=[b["static.law"] for b in blocks], static=static, x0=column[2], v0=column[3],
                   coupling=list(coupling), v_drive=v_drive)

    @classmethod
    def from_system(cls, system):
        """The chain of a :class:`stickslip.systems.system_file.System`."""
        return cls.from_blocks(system.blocks, system.coupling, system.v_drive)

    def length_scale(self):
        """The largest ``F_S(0) / kappa`` (m) of the blocks: the stretch of a wall spring at breakaway."""
        return float(np.max(self.static[:, 0] / self.kappa))

    def shortest_period(self):
        """A lower bound (s) of the chain's free periods, ``2 pi / omega_max`` (Gershgorin on ``M^-1 K``)."""
        side = np.concatenate([[0.0], self.coupling, [0.0]])
        return float(2.0 * math.pi / math.sqrt(np.max((self.kappa + 2.0 * (side[:-1] + side[1:])) / self.M)))
