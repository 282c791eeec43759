"""The system files shipped with stickslip (installed as stickslip.system_files; docs/systems.md)."""
