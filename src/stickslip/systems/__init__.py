"""Systems of coupled blocks (SPEC section 5) as data, run through masters and compared with the chain's reference.

- :mod:`.system_file`: the TOML system file, loaded and validated (:func:`load_system`, :class:`System`);
- :mod:`.master`: what a master implements and returns (:class:`SystemResult`); :mod:`.masters`: the masters
  by name; :mod:`.zoh` (fixed step, held inputs, FMI 2 co-simulation) and :mod:`.me` (FMI 3 model exchange of
  every block in one solver, :mod:`.me_blocks`);
- :mod:`.compare`: a run against :func:`stickslip.reference.simulate_chain`;
- :mod:`.report` and :mod:`.plots`: the CSV, the markdown report and the figures; :mod:`.run`: all of it for
  ``stickslip system run`` (docs/systems.md).
"""

from .master import SystemResult
from .masters import MASTERS, make_master
from .run import SystemOutcome, run_system
from .system_file import System, SystemFileError, load_system

__all__ = ["MASTERS", "System", "SystemFileError", "SystemOutcome", "SystemResult", "load_system", "make_master",
           "run_system"]
