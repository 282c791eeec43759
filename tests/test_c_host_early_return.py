"""Early return and event mode of the FMI 3 FMU driven by our C host (``host3.c``, modes "early" and "events"), the
way fmusim drives them with ``--early-return-allowed`` (and ``--event-mode-used``): each step after an early return
starts at lastSuccessfulTime and ends on the next output point; in event mode the host enters Event Mode at each
early return that asks for it, updates the discrete states and returns to Step Mode.

Each run is a child process (see ``tests/test_c_host.py``); the host is conftest's ``host3``. The scene and the
reference's event times are those of ``tests/test_fmi3_early_return.py``.
"""

import pytest

from stickslip.hosts.c_host import run_host
from test_fmi3_early_return import EVENT_TIME, INTERVAL, STOP, VALUES, reference_event_times

START = {name: value for name, value in VALUES.items() if name != "v_drive"}


def completed(run):
    assert run.completed, f"host exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


@pytest.fixture(scope="module")
def runs(host3, unzipped3):
    mode_vr = str(unzipped3[2]["mode"].valueReference)
    return {mode: completed(run_host(host3, unzipped3[0], mode, STOP, INTERVAL, START, env={"HOST_MODE_VR": mode_vr}))
            for mode in ("run", "early", "events")}


def early_times(run):
    return [float(line[1]) for line in run.lines if line[0] == "early"]


@pytest.mark.parametrize("mode", ["early", "events"])
def test_the_c_host_returns_early_at_every_reference_event(runs, mode):
    reference = reference_event_times()
    times = early_times(runs[mode])
    assert len(times) == len(reference) >= 8
    assert max(abs(a - b) for a, b in zip(times, reference)) <= EVENT_TIME
    assert runs[mode].logs == []


def test_in_event_mode_the_host_sees_the_mode_before_and_after_each_event(runs):
    """Two samples at each early return: the mode before the event, then after Event Mode the mode after it
    (slipping into the first stick, stuck into the breakaway, ...); x does not jump."""
    run = runs["events"]
    times = early_times(run)
    modes = [(float(t), int(m)) for tag, t, m in (line for line in run.lines if len(line) == 3) if tag == "m"]
    xs = [(float(t), float(x)) for tag, t, x in (line for line in run.lines if len(line) == 3) if tag == "x"]
    for k, t in enumerate(times):
        at = [m for s, m in modes if s == t]
        assert at == ([1, 0] if k % 2 == 0 else [0, 1])
        assert len({x for s, x in xs if s == t}) == 1
    assert early_times(runs["early"]) == times  # the same stops with or without event mode


@pytest.mark.parametrize("mode", ["early", "events"])
def test_returning_early_changes_no_result_at_the_output_points(runs, mode):
    """x on the output points is that of the run without early return (mode "run"), to the rounding of the end of a
    step that starts at an event."""
    plain = dict(zip(*runs["run"].series("x")))
    regular = [(t, x) for t, x in zip(*runs[mode].series("x")) if abs(t - round(t)) < 1e-9]
    assert {round(t) for t, _ in regular} == {round(t) for t in plain}
    assert max(abs(x - plain[float(round(t))]) for t, x in regular) <= 1e-12
