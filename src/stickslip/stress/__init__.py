"""Stress matrix and robustness checks of the SpringBlockFriction FMU.

- :mod:`.cases`: the grid of stress cases as data;
- :mod:`.checks`: invariants, reference comparison, energy balance;
- :mod:`.session`: direct FMI access through FMPy (statuses, log text, FMU states);
- :mod:`.case_runs`: runs the cases with a progress bar and tabulates the outcomes;
- :mod:`.cosim`: the FMU under libcosim (OSP), run in a child process;
- :mod:`.cli`: ``stickslip stress``.
"""
