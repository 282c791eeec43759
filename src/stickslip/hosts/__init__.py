"""Hosts of the FMUs: :mod:`~stickslip.hosts.fmpy_host` (FMPy, FMI 2 and 3, one error type and one log) and
:mod:`~stickslip.hosts.c_host` (plain C importers that run an FMU outside any Python process)."""
