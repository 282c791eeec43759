"""A chain of ``N`` like blocks from a few numbers: :func:`chain_system`.

The defaults are the Burridge-Knopoff chain of ``systems/bk10-velocity-weakening.toml``: ``M = 1`` kg,
``kappa = 1`` N/m, coupling springs ``kc = 4`` N/m, velocity-weakening kinetic friction (Stribeck, ``F0 = 0.5`` N,
``F_stribeck = 0.4`` N, ``v_stribeck = 0.05`` m/s, ``delta = 1``, ``gamma = 0``), constant static friction
``F0 = 1`` N, a surface at ``v_drive = 0.01`` m/s; every block starts stuck (``v_start = v_drive``) at
``x_start`` plus a random offset uniform in ``[-offset_spread, offset_spread]`` m drawn with ``seed``. The system
is what a system file's ``[template]`` table with the same values loads into (:mod:`stickslip.systems.template_table`).
"""

from pathlib import Path

from ..systems.system_file import system_from_data

#: the kinetic law of the Burridge-Knopoff chain (``law``: the code of SPEC section 2; the rest its parameters)
BK_KINETIC = {"law": 3, "F0": 0.5, "F_stribeck": 0.4, "v_stribeck": 0.05, "delta": 1.0, "gamma": 0.0}
#: its static law
BK_STATIC = {"law": 1, "F0": 1.0}


def template_table(n, *, seed, M=1.0, kappa=1.0, kc=4.0, v_drive=0.01, kinetic=None, static=None,
                   x_start=0.0, offset_spread=0.01, stop_time=300.0, output_interval=0.1):
    """The content of a system file with a ``[template]`` table (as TOML reads it) for the arguments of
    :func:`chain_system`."""
    block = {"M": M, "kappa": kappa, "x_start": x_start, "v_start": v_drive}
    for kind, law in (("kinetic", BK_KINETIC if kinetic is None else kinetic),
                      ("static", BK_STATIC if static is None else static)):
        block |= {f"{kind}.{name}": value for name, value in law.items()}
    return {"system": {"stop_time": stop_time, "output_interval": output_interval, "v_drive": v_drive,
                       "coupling": kc},
            "template": {"n": n, "seed": seed, "block": block, "spread": {"x_start": offset_spread}}}


def chain_system(n, *, seed, name=None, **values):
    """A validated :class:`stickslip.systems.system_file.System` of ``n`` like blocks; ``values``: the keyword
    arguments of :func:`template_table` (``M`` kg, ``kappa`` and ``kc`` N/m, ``v_drive`` m/s, ``kinetic`` and
    ``static`` ``{"law": code, parameter: value}``, ``x_start`` and ``offset_spread`` m, ``stop_time`` and
    ``output_interval`` s). ``name`` (default ``chain<n>-seed<seed>``) names it in messages and output files. Bad
    values raise :class:`stickslip.systems.SystemFileError` naming the key; no run length is refused (the chain
    engine runs long chains)."""
    data = template_table(n, seed=seed, **values)
    return system_from_data(data, Path(name or f"chain{n}-seed{seed}"), check_run_length=False)
