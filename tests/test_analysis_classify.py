"""Attractor classification of long runs against the scenario suite's expected attractors."""

import pytest

from stickslip.analysis import classify
from stickslip.scenario import load_scenario

from test_analysis_cli import SCENARIOS

CONSTANT_DRIVE = [p for p in sorted(SCENARIOS.glob("*.toml"))
                  if "points" not in p.read_text() and "F_ext" not in p.read_text()]


@pytest.mark.parametrize("path", CONSTANT_DRIVE, ids=lambda p: p.stem)
def test_expected_attractor(path):
    s = load_scenario(path)
    v_drive = float(s.signals["v_drive"].right(0.0))
    a = classify.classify_run(s.params, v_drive, t_end=s.stop_time, x0=s.x0, v0=s.v0, tail=s.tail,
                              rtol=s.rtol)
    assert a.kind == s.expected_attractor


def test_oscillatory_sliding_measures():
    s = load_scenario(SCENARIOS / "elmer-fig3-v1.0.toml")
    a = classify.classify_run(s.params, 1.0, t_end=1000.0, x0=s.x0, v0=s.v0, tail=300.0)
    assert a.kind == "oscillatory-sliding" and not a.overshoots
    assert a.period == pytest.approx(39.75, abs=0.05)
    assert a.x_min == pytest.approx(-5.9, abs=0.05) and a.x_max == pytest.approx(6.2, abs=0.05)
    assert a.v_max < 1.0
