"""The scenario suite, the main job: scenario files (:mod:`~stickslip.suite.scenario`), their input signals
(:mod:`~stickslip.suite.inputs`), the FMU-vs-reference comparison (:mod:`~stickslip.suite.compare`), the runner
(:mod:`~stickslip.suite.runner`), the report (:mod:`~stickslip.suite.report`) and plots
(:mod:`~stickslip.suite.scenario_plots`)."""
