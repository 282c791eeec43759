"""Chains of blocks at compiled speed, and what works on their output: the engine, the catalogue of slip events,
their statistics and a chain's set-up from a template (docs/chains.md)."""

from .engine import ChainRunError, ChainRunSummary, run_chain
from .output import EVENT_KINDS, CsvSink, MemorySink
from .spec import ChainSpec, ChainSpecError

__all__ = ["ChainRunError", "ChainRunSummary", "ChainSpec", "ChainSpecError", "CsvSink", "EVENT_KINDS", "MemorySink",
           "run_chain"]
