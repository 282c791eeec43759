"""The scenario files shipped with stickslip (installed as stickslip.scenario_files; docs/scenarios.md)."""
