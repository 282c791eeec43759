"""The chain benchmark's numba peer against the independent reference (``simulate_chain`` at a tight tolerance):
short chains on every kinetic and static law, bk10 over 300 s block event by block event; and the chain part of
``stickslip bench-systems`` end to end on a tiny configuration."""

import csv
import json
import math

import numpy as np
import pytest

from stickslip.bench.numba_chain_peer import KINDS, chain_arrays, run_peer
from stickslip.cli import main
from stickslip.reference import ChainBlock, parameters_from_values, simulate_chain
from stickslip.systems import load_system

BK10 = "systems/bk10-velocity-weakening.toml"


def _block(x_start, v_start, kinetic, static, M=1.0, kappa=1.0):
    values = {"M": M, "kappa": kappa, "x_start": x_start, "v_start": v_start}
    values |= {f"kinetic.{k}": v for k, v in kinetic.items()} | {f"static.{k}": v for k, v in static.items()}
    return values


def _compare(blocks, coupling, v_drive, stop_time, step, rtol):
    """``(max |dx| / amplitude, peer run, reference)`` of the peer at ``rtol`` against the reference at 1e-13."""
    t = np.arange(round(stop_time / step) + 1) * step
    reference = simulate_chain([ChainBlock(parameters_from_values(b), b["x_start"], b["v_start"]) for b in blocks],
                               coupling, v_drive, t, rtol=1e-13)
    run = run_peer(chain_arrays(blocks, coupling, v_drive), t, rtol)
    return float(np.abs(run.x - reference.x).max()) / reference.amplitude(), run, reference


def _events_pair(run, reference, within):
    """Every block event of the peer is the reference's, in order, same block and kind, within ``within`` s."""
    assert [(e.block, e.kind) for e in reference.events] == [(int(b), KINDS[k]) for b, k in
                                                             zip(run.event_block, run.event_kind)]
    assert np.abs(run.event_t - np.array([e.t for e in reference.events])).max() <= within


COULOMB = {"law": 1, "F0": 0.6}
STRIBECK = {"law": 3, "F0": 0.5, "F_stribeck": 0.4, "v_stribeck": 0.05, "delta": 1.0, "gamma": 0.0}
CONSTANT = {"law": 1, "F0": 1.0}

LAW_CASES = {
    "coulomb": (COULOMB, CONSTANT),
    "viscous": ({"law": 2, "F0": 0.5, "gamma": 0.02}, CONSTANT),
    "stribeck-delta2": ({"law": 3, "F0": 0.5, "F_stribeck": 0.3, "v_stribeck": 0.1, "delta": 2.0, "gamma": 0.05},
                        CONSTANT),
    "lubricated": ({"law": 4, "gamma1": 3.0, "gamma2": 0.1, "v_tilde": 0.2, "dv": 0.05}, CONSTANT),
    "carlson-langer": ({"law": 5, "F0": 1.0, "sigma": 0.1, "alpha": 2.0}, CONSTANT),
    "logarithmic-aging": (STRIBECK, {"law": 2, "F0": 1.0, "A": 0.1, "tau": 0.5}),
    "saturating-aging": (COULOMB, {"law": 3, "F0": 1.0, "F_inf": 1.3, "tau": 2.0}),
    "sigmoid-aging": (COULOMB, {"law": 4, "F0": 1.0, "F_inf": 1.3, "tau": 2.0, "n": 3.0}),
}


@pytest.mark.parametrize("case", sorted(LAW_CASES))
def test_a_three_block_chain_follows_the_reference_on_every_law(case):
    kinetic, static = LAW_CASES[case]
    v_drive = 0.3
    blocks = [_block(0.0, v_drive, kinetic, static), _block(0.2, 0.0, kinetic, static, M=2.0),
              _block(-0.1, v_drive, kinetic, static, kappa=1.5)]
    error, run, reference = _compare(blocks, [0.8, 1.2], v_drive, 40.0, 0.05, 1e-12)
    assert len(reference.events) >= 6, "the case must stick and slip"
    assert error <= 1e-8, f"{case}: max |dx| = {error:.3g} of the amplitude"
    _events_pair(run, reference, 1e-8)


def test_two_blocks_stick_and_slip_with_the_reference_and_grazes_nothing_over():
    blocks = [_block(0.3, 0.1, COULOMB, CONSTANT), _block(-0.4, 0.1, STRIBECK, CONSTANT, M=0.5)]
    error, run, reference = _compare(blocks, [2.0], 0.1, 60.0, 0.1, 1e-12)
    assert len(reference.events) >= 20
    assert error <= 1e-8
    _events_pair(run, reference, 1e-8)


def test_bk10_over_300_s_pairs_every_block_event_with_the_reference():
    system = load_system(BK10)
    error, run, reference = _compare(list(system.blocks), system.coupling, system.v_drive, 300.0, 0.1, 1e-12)
    assert len(reference.events) == 210
    # the slow loading (0.01 m/s) turns a breakaway's position error into 100 times that in time
    assert error <= 5e-7, f"max |dx| = {error:.3g} of the amplitude"
    _events_pair(run, reference, 1e-6)


def test_the_error_falls_with_the_tolerance():
    system = load_system(BK10)
    errors = [_compare(list(system.blocks), system.coupling, system.v_drive, 120.0, 0.1, rtol)[0]
              for rtol in (1e-6, 1e-9)]
    assert errors[1] < errors[0] / 100.0


def test_bad_input_is_refused_by_name():
    system = load_system(BK10)
    chain = chain_arrays(list(system.blocks), system.coupling, system.v_drive)
    with pytest.raises(ValueError, match="rtol"):
        run_peer(chain, [0.0, 1.0], 0.0)
    with pytest.raises(ValueError, match="coupling"):
        run_peer(chain_arrays(list(system.blocks), system.coupling[1:], system.v_drive), [0.0, 1.0], 1e-8)
    with pytest.raises(ValueError, match="b1: kinetic.law"):
        chain_arrays([dict(system.blocks[0], **{"kinetic.law": 9})], [], 0.01)
    assert math.isfinite(run_peer(chain, [0.0, 1.0], 1e-8).x.sum())


def test_the_chain_bench_runs_end_to_end_and_its_report_agrees_with_its_runs(tmp_path):
    """A 3-block template chain over 150 s (its first slips), the reference timed beside at one rtol, and a 4-block
    chain as the large one (truth: the engine at a tighter rtol); the table, the CSV and the plot are written and
    hold the runs' own numbers."""
    out = tmp_path / "bench"
    code = main(["bench-systems", "--chain", "--chain-files", "--chain-sizes", "3", "--chain-stop-time", "150",
                 "--chain-rtols", "1e-6", "1e-9", "--chain-reference-rtols", "1e-8", "--repeats", "1",
                 "--large-n", "4", "--large-stop-time", "150", "--large-rtols", "1e-6", "--out", str(out)])
    assert code == 0
    data = json.loads((out / "chain.json").read_text())
    small, large = data["chains"]
    assert (small["n"], large["n"]) == (3, 4)
    assert sorted(small["runs"]) == ["engine", "peer", "reference"]
    assert small["truth_events"] > 0 and "rtol 1e-13" in small["truth"] and "engine at rtol 1e-10" in large["truth"]
    for subject, runs in small["runs"].items():
        for r in runs:
            assert r["error"] < (1e-3 if r["setting"] < 1e-7 else 0.5), (subject, r)
            assert r["events"] == small["truth_events"]
    for m in small["matched"]:
        peer = next(r for r in small["runs"]["peer"] if r["setting"] == m["rtol"])
        assert m["peer_wall"] == peer["wall"]
        if m["engine_wall"] is not None:
            assert m["ratio"] == pytest.approx(m["engine_wall"] / m["peer_wall"])
            assert m["engine_error"] <= m["peer_error"]
    rows = list(csv.DictReader(open(out / "chain.csv")))
    assert len(rows) == sum(len(runs) for r in data["chains"] for runs in r["runs"].values())
    table = (out / "chain.md").read_text()
    assert "## Growth with N" in table and f"| {small['runs']['peer'][0]['setting']:g} |" in table
    assert (out / "chain.png").stat().st_size > 10_000


def test_the_chain_bench_refuses_bad_options_by_name(capsys):
    assert main(["bench-systems", "--chain", "--chain-rtols", "0.5"]) == 2
    assert "--chain-rtols" in capsys.readouterr().err
    assert main(["bench-systems"]) == 2
    assert "--chain" in capsys.readouterr().err
