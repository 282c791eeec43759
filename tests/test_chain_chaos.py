"""Chaotic chains judged by statistics: the largest Lyapunov exponent against the closed form of a damped sliding
chain, about 0 on the two-block Coulomb chain (which keeps the amplitude check), positive on a chaotic chain, whose
``system run`` is then judged by two-sample tests of its slip events: a correct run passes, a planted wrong one
(another friction drop) fails."""

import dataclasses
import math

import numpy as np
import pytest

import stickslip.reference as reference_package
from stickslip.chain.lyapunov import largest_lyapunov
from stickslip.chain.spec import ChainSpec
from stickslip.systems.chaos import Divergence, efoldings, judge_by_statistics, report_lines, rounded, two_sample_tests
from stickslip.systems.native import NativeMaster
from stickslip.systems.run import run_system

#: ten Burridge-Knopoff blocks with start offsets in [-0.1, 0.1] m: chaotic, cheap with the engine
CHAOTIC = """
[system]
stop_time = 2000.0
output_interval = 1.0
v_drive = 0.01
coupling = 4.0

[template]
n = 10
seed = 1

[template.block]
M = 1.0
kappa = 1.0
"kinetic.law" = 3
"kinetic.F0" = 0.5
"kinetic.F_stribeck" = {F_stribeck}
"kinetic.v_stribeck" = 0.05
"kinetic.delta" = 1.0
"kinetic.gamma" = 0.0
"static.law" = 1
"static.F0" = 1.0
x_start = 0.0
v_start = 0.01

[template.spread]
x_start = 0.1
"""
_references = {}


@pytest.fixture
def reference_once(monkeypatch):
    """The chain reference of ``system run``, each tolerance run once for this module's chaotic chain."""
    simulate = reference_package.simulate_chain

    def cached(blocks, coupling, v_drive, t_eval, rtol=1e-12, progress=None):
        key = (len(blocks), float(t_eval[-1]), rtol)
        if key not in _references:
            _references[key] = simulate(blocks, coupling, v_drive, t_eval, rtol=rtol, progress=progress)
        return _references[key]

    monkeypatch.setattr(reference_package, "simulate_chain", cached)  # system run takes it from there


def chaotic_file(tmp_path, F_stribeck=0.4):
    path = tmp_path / "chaotic10.toml"
    path.write_text(CHAOTIC.format(F_stribeck=F_stribeck))
    return path


def test_a_damped_sliding_chain_has_the_exponent_of_its_damping():
    # viscous friction F0 + gamma u damps every mode of the sliding chain at gamma / (2 M): lambda = -gamma / (2 M)
    gamma = 0.2
    spec = ChainSpec(M=[1.0, 1.0], kappa=[1.0, 1.0], kinetic_law=[2, 2], kinetic=[[0.5, gamma, 0, 0, 0]] * 2,
                     static_law=[1, 1], static=[[1.0, 0, 0, 0]] * 2, x0=[0.72, 0.69], v0=[0.0, 0.0],
                     coupling=[0.5], v_drive=1.0)
    estimate = largest_lyapunov(spec, 300.0)
    assert estimate.exponent == pytest.approx(-gamma / 2.0, rel=1e-3)
    assert estimate.growth() == pytest.approx(-0.1 * 300.0, rel=1e-3)


def test_the_two_block_coulomb_chain_is_not_chaotic_and_keeps_the_amplitude_check(tmp_path):
    outcome = run_system("systems/chain2-coulomb.toml", "native", tmp_path, show_progress=False)
    divergence = outcome.comparison.divergence
    estimate = divergence.estimate
    assert not divergence.diverges and outcome.comparison.statistics is None
    assert abs(estimate.exponent) < 3.0 * estimate.uncertainty and abs(estimate.exponent) < 0.03
    assert outcome.ok and outcome.comparison.max_rel_dx <= 1e-6
    report = (tmp_path / "chain2-coulomb-native.md").read_text()
    assert "**Check: the amplitude.** The largest Lyapunov exponent over the run is" in report
    assert "not past the tolerance 1e-06: the trajectory does not diverge" in report
    assert "![the largest Lyapunov exponent over the run](chain2-coulomb-native-lyapunov.png)" in report
    assert (tmp_path / "chain2-coulomb-native-lyapunov.png").stat().st_size > 10_000


def test_a_chaotic_chain_is_judged_by_statistics_and_a_correct_run_passes(tmp_path, reference_once):
    outcome = run_system(chaotic_file(tmp_path), "native", tmp_path, show_progress=False)
    comparison = outcome.comparison
    estimate = comparison.divergence.estimate
    assert comparison.divergence.diverges
    assert estimate.exponent > 5.0 * estimate.uncertainty and estimate.growth() > 3.0 * efoldings(1e-6)
    # the amplitude cannot judge it: the reference at its two tolerances is apart by a fraction of the amplitude
    check = comparison.statistics
    assert check.reference_spread > 0.1 and comparison.max_rel_dx > 0.1
    assert min(check.counts.values()) > 100
    assert check.quantities == ("size", "duration", "moment") and len(check.p_values) == 6
    assert check.ok and outcome.ok and min(check.p_values.values()) > check.threshold
    report = (tmp_path / "chaotic10-native.md").read_text()
    assert "**PASS**" in report and "**Check: statistics, not the amplitude (PASS).**" in report
    assert "the reference itself moves" in report and "between its tolerances 1e-12 and 1e-10" in report
    assert "statistics at significance 0.01): PASS" in outcome.summary


def test_a_planted_wrong_run_fails_the_statistical_check(tmp_path, reference_once, monkeypatch):
    # the master runs a chain whose kinetic friction drops to 0.8 N at the onset of slip instead of 0.9 N
    run = NativeMaster.run

    def wrong_run(self, system, fmu_path=None, progress=lambda t: None):
        blocks = tuple({**b, "kinetic.F_stribeck": 0.3} for b in system.blocks)
        return run(self, dataclasses.replace(system, blocks=blocks), fmu_path, progress)

    monkeypatch.setattr(NativeMaster, "run", wrong_run)
    outcome = run_system(chaotic_file(tmp_path), "native", tmp_path, show_progress=False)
    check = outcome.comparison.statistics
    assert check is not None and not check.ok and not outcome.ok
    assert min(check.p_values.values()) < check.threshold
    assert min(check.between_references.values()) > check.threshold  # the references agree with each other
    report = (tmp_path / "chaotic10-native.md").read_text()
    assert "**FAIL**" in report and "**Check: statistics, not the amplitude (FAIL).**" in report


def test_values_are_compared_to_six_digits():
    # a chain's repeated small slips: equal to six digits, their last digits sorted apart in the two runs
    a = {"size": np.ones(50), "duration": 1.1420774 + 1e-12 * np.arange(50), "moment": np.full(50, 0.5)}
    b = {"size": np.ones(50), "duration": 1.1420774 - 1e-12 * np.arange(1, 51), "moment": np.full(50, 0.5)}
    assert rounded([1.23456789, -0.000123456789]).tolist() == [1.23457, -0.000123457]
    p = two_sample_tests(a, {"b": b})
    assert p[("b", "duration")] == pytest.approx(1.0) and not math.isnan(p[("b", "moment")])


def test_a_master_that_misses_event_times_cannot_be_judged_by_statistics():
    result = dataclasses.make_dataclass("Result", ["events_complete"])(False)
    check = judge_by_statistics(None, result, None, {})
    assert not check.ok and check.cannot
    (line, _) = report_lines(Divergence(None, True, "it diverges"), check)
    assert line == ("**Check: statistics, not the amplitude (FAIL).** It diverges. The master's run cannot be judged "
                    "by its statistics: it knows some block events only by count, not their times.")
