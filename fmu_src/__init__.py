"""The FMU slaves' sources, shipped inside the package as ``stickslip.fmu_src`` (mapped from the project's
top-level ``fmu_src/``) so that an installed ``stickslip`` can build its FMUs.

- ``SpringBlockFriction.py``: the FMI 2.0 co-simulation slave (PythonFMU);
- ``SpringBlockFriction_fmi3.py``: the FMI 3.0 co-simulation and model-exchange slave (pythonfmu3);
- ``block_interface.py``: the variable table and the bookkeeping both slaves share;
- ``ChainCoupling.py``: the coupling FMU's slave (PythonFMU);
- ``loader_binding.py``: what every slave does for the FMUs' binaries (the C loader in front of the library's).

The slaves are not imported from here: :mod:`stickslip.fmu.staging` copies them into an FMU under names only
that FMU uses. Hosts read the variable table (:data:`block_interface.VARIABLES`) from here.
"""
