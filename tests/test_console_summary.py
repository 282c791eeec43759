"""What ``stickslip run`` prints: at most 100 columns, and the numbers of the outcomes it summarises."""

from pathlib import Path
from types import SimpleNamespace

import pytest

from stickslip.suite.report import CONSOLE_COLUMNS, CONSOLE_WIDTH, Outcome, console_summary
from stickslip.suite.runner import run_suite

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"


def _check_rows(lines, outcomes):
    """The table's rows (after the header and the rule) state each outcome's result, errors and times to the
    three significant digits (errors) or hundredths of a second (times) printed."""
    assert lines[0].split() == [word for column in CONSOLE_COLUMNS for word in column.split()]
    assert set(lines[1]) == {"-"}
    for line, o in zip(lines[2:], outcomes):
        cells = line.split()
        name, result, figures = cells[0], cells[1:-5], cells[-5:]
        assert o.name.startswith(name.removesuffix(".."))
        assert " ".join(result) == o.result
        c = o.comparison
        if c is None:
            assert figures[:3] == ["-", "-", "-"]
        else:
            expected = (c.max_abs_dx, c.max_abs_dv, c.events.max_time_error)
            assert [float(f) for f in figures[:3]] == [pytest.approx(e, rel=5e-3, abs=1e-300) for e in expected]
        assert [float(f) for f in figures[3:]] == [pytest.approx(t, abs=5e-3, nan_ok=True)
                                                   for t in (o.fmu_seconds, o.ref_seconds)]


def test_the_suite_prints_its_outcomes_within_100_columns(tmp_path, fmu_path, capsys):
    paths = [SCENARIO_DIR / f"{name}.toml" for name in ("coulomb-stick-slip", "viscous-above-critical")]
    result = run_suite(paths, tmp_path / "out", jobs=1, fmu_path=fmu_path)
    printed = capsys.readouterr().out.splitlines()
    assert max(len(line) for line in printed) <= CONSOLE_WIDTH
    assert printed[-2:] == [f"2/2 passed in {result.seconds:.1f} s", f"report: {tmp_path / 'out' / 'report.md'}"]
    _check_rows(printed[:-2], result.outcomes)


def test_long_names_failures_and_known_misses_stay_within_the_width():
    events = SimpleNamespace(max_time_error=3.14159e-9, n_matched=12, n_unmatched=0)
    missed = SimpleNamespace(max_abs_dx=1.23456e-3, max_abs_dv=9.87654e-4, final_abs_dx=1e-5, events=events,
                             attractor_fmu="stick-slip", attractor_ref="stick-slip", passed=False,
                             failures=("max |dx| 1.23e-03 > 1e-08 m " * 8,))
    long_name = "a-scenario-name-longer-than-the-console-table-has-room-for"
    outcomes = [Outcome(long_name, "stick-slip", missed, 123.456, 7.0),
                Outcome("known", "stick-slip", missed, 0.5, 0.25, known_miss="a limit of the host's solver"),
                Outcome("broken", "rest", None, error="the FMU did not load: " + "no such file " * 12)]
    lines = console_summary(outcomes).splitlines()
    assert max(len(line) for line in lines) <= CONSOLE_WIDTH
    assert [o.result for o in outcomes] == ["FAIL", "KNOWN MISS", "FAIL"]
    _check_rows(lines[:2 + len(outcomes)], outcomes)
    failures = lines[2 + len(outcomes):]
    assert failures[0].startswith(f"- {outcomes[0].name}: max |dx|") and failures[1].startswith("  ")
    joined = " ".join(line.strip() for line in failures)
    assert joined.count("max |dx| 1.23e-03") == 8 and "- broken: the FMU did not load: no such file" in joined


def _outcome(name, met, known_miss=""):
    """An outcome whose comparison met (``met``) or missed its checks."""
    comparison = SimpleNamespace(passed=met, failures=() if met else ("max |dx| above its tolerance",))
    return Outcome(name, "stick-slip", comparison, known_miss=known_miss)


def test_a_known_miss_is_counted_as_such_not_as_passed():
    from stickslip.suite.report import tally
    outcomes = [_outcome("a", True), _outcome("b", True), _outcome("c", False, known_miss="host solver")]
    assert tally(outcomes) == "2/3 passed, 1 known miss"
    assert tally(outcomes[:2]) == "2/2 passed"
    assert tally(outcomes + [_outcome("d", False)]) == "2/4 passed, 1 known miss"
    # a known miss that met its checks fails: neither passed nor a known miss
    assert tally([_outcome("e", True, known_miss="host solver")]) == "0/1 passed"
