"""Work-precision benchmark: our FMU and stepper against scipy peers and a do-nothing FMU.

``stickslip bench [--quick] [--out DIR] [--scenes NAME ...]``; see ``benchmarks/README.md``.
Modules: :mod:`.scenes` (what is run), :mod:`.peers` (solve_ivp hybrid and
regularized models), :mod:`.fmus` (FMUs under FMPy, the floor FMU),
:mod:`.harness` (timing and errors), :mod:`.results` (JSON, Markdown, plots),
:mod:`.cli` (the command).
"""
