"""The ``adaptive`` master's blocks stuck under a steady force, stepped ahead in one ``doStep`` and read off their
line until their force moves or an event comes: the chain stays exact against its reference, and such a block is
stepped far less often than the master takes steps."""

import collections

import numpy as np
import pytest

from stickslip.reference import simulate_chain
from stickslip.systems import adaptive, load_system, make_master
from stickslip.systems.compare import compare

# b1 breaks away at 11 s and slips once; b2 (its neighbour, aging) and b3 (aging) stay stuck throughout; b4 breaks
# away at 20 s under a force that has been steady since the start (b3 and b4 move together with the surface)
CHAIN4 = """
[system]
stop_time = 30.0
output_interval = 0.1
v_drive = 0.05
coupling = [0.5, 0.5, 0.5]
""" + "".join(f"""
[[blocks]]
M = 1.0
kappa = 1.0
"kinetic.law" = 1
"kinetic.F0" = 0.5
{law}
x_start = {x_start}
v_start = 0.05
""" for law, x_start in [('"static.law" = 1\n"static.F0" = 1.0', 0.3),
                          ('"static.law" = 2\n"static.F0" = 3.0\n"static.A" = 0.1\n"static.tau" = 1.0', 0.0),
                          ('"static.law" = 2\n"static.F0" = 3.0\n"static.A" = 0.1\n"static.tau" = 1.0', 0.0),
                          ('"static.law" = 1\n"static.F0" = 1.0', 0.0)])


@pytest.fixture(scope="module")
def chain4(tmp_path_factory):
    path = tmp_path_factory.mktemp("ahead") / "chain4-ahead.toml"
    path.write_text(CHAIN4)
    system = load_system(path)
    return system, simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, system.times())


@pytest.mark.parametrize("fmi", [2, 3])
def test_blocks_stuck_under_a_steady_force_are_stepped_ahead_exactly(fmi, chain4, fmu_path, fmu3_path, monkeypatch):
    """Within 1e-8 of the amplitude, the reference's events paired within 1e-8 s (b4's breakaway among them, found
    while it was stepped ahead: FMI 2 by its step passing the event, FMI 3 by its early return). Before b4 breaks
    away (the master takes at least one step per output point, 190 by 19 s, more while b1 slips), b3, stuck under a
    steady force while b1 slips, is stepped in fewer than one step in ten. b4's steps ahead do not go on past its
    breakaway at every attempt until it: FMI 2's step ahead that passed it is redone to just before it and kept, as
    FMI 3's early return leaves it (before, 20 of b4's steps ahead passed it, each integrating the slip after it)."""
    system, reference = chain4
    assert {e.block for e in reference.events} == {0, 3}  # b2 and b3 never slip
    calls = collections.Counter()  # per block, its doStep calls that start before 19 s
    step = adaptive._Blocks.step

    def counted(self, i, t, *args, **kwargs):
        calls[i] += t < 19.0
        return step(self, i, t, *args, **kwargs)

    passed = collections.Counter()  # per block, its steps ahead that passed an event and were not kept
    extend = adaptive._Run._extend_line

    def extended(self, i, *args):
        kept = extend(self, i, *args)
        passed[i] += not kept
        return kept

    monkeypatch.setattr(adaptive._Blocks, "step", counted)
    monkeypatch.setattr(adaptive._Run, "_extend_line", extended)
    result = make_master("adaptive", fmi=fmi).run(system, fmu_path if fmi == 2 else fmu3_path)
    comparison = compare(result, reference, system.tolerances["adaptive"])
    assert comparison.ok and comparison.max_rel_dx < 1e-8, comparison
    assert list(comparison.master_events) == list(comparison.reference_events)
    assert np.all(comparison.max_event_dt < 1e-8), comparison.max_event_dt
    assert result.stats["events not landed"] == 0
    assert result.stats["holds of a block stepped ahead"] > result.stats["communication steps"]
    assert calls[2] < 19, calls
    assert passed[3] <= 1, passed
