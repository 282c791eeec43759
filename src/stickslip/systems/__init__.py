"""Systems of coupled blocks (SPEC section 5) as data, run through masters and compared with the chain's reference.

- :mod:`.system_file`: the TOML system file, loaded and validated (:func:`load_system`, :class:`System`);
- :mod:`.master`: what a master implements and returns (:class:`SystemResult`); :mod:`.masters`: the masters
  by name; :mod:`.zoh` (fixed step, held inputs, FMI 2 co-simulation) and :mod:`.me` (FMI 3 model exchange of
  every block in one solver, :mod:`.me_blocks`);
- :mod:`.compare`: a run against :func:`stickslip.reference.simulate_chain`;
- :mod:`.report` and :mod:`.plots`: the CSV, the markdown report and the figures; :mod:`.run`: all of it for
  ``stickslip system run`` (docs/systems.md);
- :mod:`.names`: the masters' and engines' names, for the command line.
"""

import importlib

#: public name: the module that defines it, imported on first use (``import stickslip.systems`` stays light, so that
#: the command line's parsers can read :mod:`.names` without loading FMPy, NumPy and SciPy)
_HOMES = {"MASTERS": ".masters", "make_master": ".masters", "SystemResult": ".master", "SystemOutcome": ".run",
          "run_system": ".run", "System": ".system_file", "SystemFileError": ".system_file",
          "load_system": ".system_file"}

__all__ = sorted(_HOMES)


def __getattr__(name):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_HOMES[name], __name__), name)
