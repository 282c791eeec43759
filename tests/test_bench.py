"""The benchmark's peers are correct, and ``stickslip bench --quick`` writes its outputs (no timing asserted)."""

import argparse
import json
import math

import numpy as np
import pytest

from stickslip.bench import fmus
from stickslip.bench.cli import add_bench_parser
from stickslip.bench.peers import hybrid_solve_ivp, regularized_solve_ivp
from stickslip.core import Constant, Coulomb, Parameters

F_K, F_S, V_DRIVE = 0.5, 1.0, 0.1  # N, N, m/s; M = kappa = 1


def coulomb_events(t_end):
    """Closed form (SPEC section 3) from rest at x = 0, stuck: slip at kappa x = F_S, stick after the
    half-turn about x = F_K/kappa that returns to v = v_drive; then the stick lasts 2 (F_S - F_K)/(kappa v_drive)."""
    stick = 2.0 * (F_S - F_K) / V_DRIVE
    phi = math.atan2(F_S - F_K, V_DRIVE)  # v - v_drive over the slip: R cos(tau + phi) - v_drive
    slip = 2.0 * math.pi - 2.0 * phi
    events, t = [], F_S / V_DRIVE
    while t < t_end:
        events += [("slip", t), ("stick", t + slip)]
        t += slip + stick
    return [e for e in events if e[1] < t_end]


@pytest.fixture
def coulomb():
    return Parameters(1.0, 1.0, Coulomb(F0=F_K), Constant(F0=F_S))


@pytest.mark.parametrize("method", ["RK45", "DOP853", "LSODA", "Radau"])
def test_solve_ivp_peer_event_times_match_the_closed_form(coulomb, method):
    grid = np.linspace(0.0, 60.0, 601)
    rtol = 1e-10
    run = hybrid_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, method, rtol, rtol)
    expected = coulomb_events(60.0)
    assert [e.kind for e in run.events] == [kind for kind, _ in expected]
    assert max(abs(e.t_lo - t) for e, (_, t) in zip(run.events, expected)) < 1e3 * rtol  # over 8 events, 60 s
    assert run.x.shape == grid.shape and np.all(np.isfinite(run.x))


def test_regularized_error_grows_with_v_eps(coulomb):
    grid = np.linspace(0.0, 40.0, 401)
    exact = hybrid_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, "DOP853", 1e-12, 1e-12).x
    errors = [np.abs(regularized_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, v_eps, "LSODA", 1e-10, 1e-10).x
                     - exact).max() for v_eps in (1e-5, 1e-4, 1e-3, 1e-2)]
    assert all(a < b for a, b in zip(errors, errors[1:])), errors


def test_quick_bench_writes_json_markdown_and_plots(tmp_path, fmu_path, monkeypatch):
    monkeypatch.setattr(fmus, "BUILD_DIR", tmp_path / "build")
    parser = argparse.ArgumentParser()
    add_bench_parser(parser.add_subparsers())
    out = tmp_path / "out"
    args = parser.parse_args(["bench", "--quick", "--out", str(out), "--scenes", "coulomb", "--fmu", str(fmu_path)])
    assert args.handler(args) == 0

    records = json.loads((out / "bench.json").read_text())["scenes"]["coulomb"]["records"]
    assert {r["family"] for r in records} == {"fmu", "stepper", "stepper-integrating", "solve_ivp", "regularized",
                                              "floor", "fmu-pure", "stepper-pure", "stepper-integrating-pure"}
    assert all(r["error"] is None and len(r["times_s"]) >= 1 for r in records)
    exact = [r for r in records if r["family"].startswith(("fmu", "stepper"))]
    assert max(r["rel_dx"] for r in exact) < 1e-12  # Coulomb slips are closed forms in the stepper
    for family in ("fmu", "stepper", "stepper-integrating"):  # the two implementations: the same numbers
        compiled = {str(r["settings"]): r["max_abs_dx"] for r in records if r["family"] == family}
        pure = {str(r["settings"]): r["max_abs_dx"] for r in records if r["family"] == f"{family}-pure"}
        assert pure and all(compiled[key] == value for key, value in pure.items())
    report = (out / "bench.md").read_text()
    assert "## Matched accuracy" in report and "## Compiled and pure Python (same sources)" in report
    assert (out / "coulomb.png").stat().st_size > 0
