"""The names a user picks on the command line, in a module that imports nothing heavy: the masters
(:data:`stickslip.systems.masters.MASTERS` holds their classes under these names) and the ``zoh`` master's engines
(:mod:`.engines`)."""

#: ``--master``: fixed step with held inputs, FMI 3 model exchange, adaptive co-simulation, the compiled chain engine
MASTER_NAMES = ("zoh", "me", "adaptive", "native")
#: ``--engine`` of the ``zoh`` master: the SSP stepped by FMPy here, libcosim, ecos or FMPy's SSP simulator
ENGINES = ("fmpy", "libcosim", "ecos", "fmpy-ssp")
