"""The comparison's parts on synthetic data: FMU event recovery, event matching, attractor classifier."""

import numpy as np
import pytest

from stickslip.suite.compare import Event, classify_attractor, fmu_events, match_events, transition_kind


def fmu_result(times, sticks, slips, overshoots, t_last):
    dtype = [("time", float), ("n_stick_events", int), ("n_slip_events", int), ("n_overshoots", int),
             ("t_last_event", float)]
    return np.array(list(zip(times, sticks, slips, overshoots, t_last)), dtype=dtype)


def test_transition_kinds():
    assert [transition_kind(*m) for m in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, -1), (-1, 1), (1, 1))] == [
        "stick", "stick", "slip", "slip", "overshoot", "overshoot", None]


def test_one_event_in_a_step_is_timed_several_are_not():
    nan = float("nan")
    result = fmu_result([0, 1, 2, 3], [0, 1, 1, 2], [0, 0, 0, 1], [0, 0, 0, 0], [nan, 0.4, 0.4, 2.9])
    assert fmu_events(result) == [Event("stick", 0.4, 0.4), Event("stick", 2, 3), Event("slip", 2, 3)]


def test_a_stale_t_last_event_leaves_the_event_untimed():
    result = fmu_result([0, 1, 2], [0, 1, 1], [0, 0, 1], [0, 0, 0], [float("nan"), 0.4, 0.4])
    assert fmu_events(result)[1] == Event("slip", 1, 2)


def test_matching_pairs_by_kind_and_counts_the_rest():
    fmu = [Event("stick", 1.0, 1.0), Event("slip", 2.0, 3.0), Event("stick", 5.0, 5.0)]
    ref = [Event("stick", 1.0 + 1e-9, 1.0 + 1e-9), Event("slip", 2.5, 2.5), Event("overshoot", 4.0, 4.0)]
    match = match_events(fmu, ref, window=0.1)
    assert match.max_time_error == pytest.approx(1e-9)
    assert (match.n_matched, match.n_unmatched) == (2, 2)


t = np.linspace(0.0, 100.0, 2001)
v_drive = np.full_like(t, 0.1)
no_sticks = np.zeros_like(t, dtype=int)


@pytest.mark.parametrize("v, v_drive, sticks, expected", [
    (0.05 * np.exp(-t / 10) * np.sin(t), v_drive, no_sticks, "continuous-sliding"),
    (0.05 * np.sin(t), v_drive, no_sticks, "oscillatory-sliding"),
    (0.05 * np.sin(t), v_drive, (t // 10).astype(int), "stick-slip"),
    (np.where(t > 50, 0.0, np.sin(t)), np.zeros_like(t), (t > 50).astype(int), "rest"),
    (v_drive, v_drive, no_sticks, "undetermined"),
    (0.05 * np.sin(t), v_drive, (t > 90).astype(int), "undetermined"),
])
def test_attractor_classifier(v, v_drive, sticks, expected):
    assert classify_attractor(t, v, v_drive, sticks, tail=40.0) == expected


@pytest.mark.parametrize("met, passed, verdict", [(False, True, "KNOWN MISS"),
                                                  (True, False, "FAIL (known miss met its checks)")])
def test_a_known_miss_passes_only_while_it_misses(met, passed, verdict):
    """A scenario run marked ``known_miss`` behaves like a strict xfail."""
    from types import SimpleNamespace

    from stickslip.suite.report import Outcome

    comparison = SimpleNamespace(passed=met, failures=() if met else ("attractor",))
    outcome = Outcome("s", "stick-slip", comparison, known_miss="a double root")
    assert (outcome.passed, outcome.verdict) == (passed, verdict)
    assert Outcome("s", "stick-slip", comparison).passed == met
