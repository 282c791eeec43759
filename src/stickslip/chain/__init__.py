"""Chains of blocks at compiled speed, and what works on their output: the engine, the catalogue of slip events,
their statistics and a chain's set-up from a template (docs/chains.md)."""
