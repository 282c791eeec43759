"""The benchmark's peers are correct, and ``stickslip bench --quick`` writes its outputs (no timing asserted)."""

import argparse
import importlib.util
import json
import math

import numpy as np
import pytest

from stickslip.bench import fmus
from stickslip.cli.bench import add_bench_parser
from stickslip.bench.peers import hybrid_solve_ivp, regularized_solve_ivp, tuned_solve_ivp
from stickslip.core import Constant, Coulomb, Logarithmic, Parameters

import machine_needs

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


def test_tuned_peer_event_times_match_the_closed_form_and_it_refuses_aging(coulomb):
    grid = np.linspace(0.0, 60.0, 601)
    run = tuned_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, 1e-10, 1e-12)
    expected = coulomb_events(60.0)
    assert [e.kind for e in run.events] == [kind for kind, _ in expected]
    assert max(abs(e.t_lo - t) for e, (_, t) in zip(run.events, expected)) < 1e-7  # over 8 events, 60 s
    stuck = grid <= F_S / V_DRIVE  # the first stick, in closed form: x = v_drive t
    assert np.array_equal(run.x[stuck], V_DRIVE * grid[stuck]) and np.all(run.v[stuck] == V_DRIVE)
    slip = (grid > expected[0][1]) & (grid < expected[1][1])  # the first slip: a half-turn about F_K / kappa
    tau = grid[slip] - expected[0][1]
    R = math.hypot(F_S - F_K, V_DRIVE)
    phi = math.atan2(F_S - F_K, V_DRIVE)
    assert np.abs(run.x[slip] - (F_K + R * np.sin(tau + phi))).max() < 1e-8
    aging = Parameters(1.0, 1.0, Coulomb(F0=F_K), Logarithmic(F0=F_S, A=0.1, tau=1.0))
    with pytest.raises(ValueError, match="static.law must be constant"):
        tuned_solve_ivp(aging, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, 1e-10, 1e-12)


def test_regularized_error_grows_with_v_eps(coulomb):
    grid = np.linspace(0.0, 40.0, 401)
    exact = hybrid_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, "DOP853", 1e-12, 1e-12).x
    errors = [np.abs(regularized_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, grid, v_eps, "LSODA", 1e-10, 1e-10).x
                     - exact).max() for v_eps in (1e-5, 1e-4, 1e-3, 1e-2)]
    assert all(a < b for a, b in zip(errors, errors[1:])), errors


def test_quick_bench_writes_json_markdown_and_plots(tmp_path, fmu_path, fmu3_path, monkeypatch):
    machine_needs.c_compiler("the bench's C-host families")
    machine_needs.libpython("the bench's C-host families")
    monkeypatch.setattr(fmus, "BUILD_DIR", tmp_path / "build")
    parser = argparse.ArgumentParser()
    add_bench_parser(parser.add_subparsers())
    out = tmp_path / "out"
    args = parser.parse_args(["bench", "--quick", "--out", str(out), "--scenes", "coulomb", "--fmu", str(fmu_path),
                              "--fmu3", str(fmu3_path)])
    assert args.handler(args) == 0

    records = json.loads((out / "bench.json").read_text())["scenes"]["coulomb"]["records"]
    assert {r["family"] for r in records} == {"fmu", "stepper", "stepper-integrating", "solve_ivp", "regularized",
                                              "floor", "c-host", "c-host-floor", "fmi3-me", "cvode-bare", "fmu-pure",
                                              "stepper-pure", "stepper-integrating-pure"}
    assert all(r["error"] is None and len(r["times_s"]) >= 1 for r in records)
    assert all(r["cpu_s"] > 0 for r in records if r["family"].startswith("c-host"))
    exact = [r for r in records if r["family"].startswith(("fmu", "stepper"))]
    assert max(r["rel_dx"] for r in exact) < 1e-12  # Coulomb slips are closed forms in the stepper
    for family in ("fmu", "stepper", "stepper-integrating"):  # the two implementations: the same numbers
        compiled = {str(r["settings"]): r["max_abs_dx"] for r in records if r["family"] == family}
        pure = {str(r["settings"]): r["max_abs_dx"] for r in records if r["family"] == f"{family}-pure"}
        assert pure and all(compiled[key] == value for key, value in pure.items())
    report = (out / "bench.md").read_text()
    assert "## Matched accuracy" in report and "C host: FMU CPU µs/step" in report
    assert "## Compiled and pure Python (same sources)" in report
    assert "## FMI 3 model exchange (FMPy CVode) beside our co-simulation" in report
    me = next(r for r in records if r["family"] == "fmi3-me")
    assert me["events_unmatched"] == 0 and me["rel_dx"] < 1e-3  # CVode at rtol 1e-6 over 20 s
    bare = next(r for r in records if r["family"] == "cvode-bare")
    assert bare["events_unmatched"] == 0 and 0.5 <= me["rel_dx"] / bare["rel_dx"] <= 2.0  # the same CVode, no FMU
    assert "| error FMU / bare |" in report
    assert (out / "coulomb.png").stat().st_size > 0


# ---------------------------------------------------------------------------
# the report's estimates and columns, on made-up records (no timing)
# ---------------------------------------------------------------------------

META = {"date": "today", "machine": "m", "python": "3", "versions": "v", "repeats": [1], "load": [0.0]}


def _record(family, label, seconds, rel_dx=1e-9, error=None, **settings):
    record = {"family": family, "label": label, "settings": settings, "error": error}
    if "comm_step" in settings:
        record["n_comm_steps"] = round(100.0 / settings["comm_step"])
    if error is None:
        record.update(median_s=seconds, rel_dx=rel_dx, max_abs_dx=rel_dx, final_abs_dx=0.0)
    return record


@pytest.fixture
def scene():
    from stickslip.bench.scenes import select_scenes

    return select_scenes(["coulomb"])[0]  # 100 s, grid 0.05 s, communication steps 1e-3 .. 10 s


def _sweep(family, scene, cost, start, wobble=()):
    """Records of the communication-step sweep: ``start + cost * steps`` s, plus a wobble per point."""
    hs = scene.comm_steps()
    wobble = list(wobble) + [0.0] * len(hs)
    return [_record(family, f"{family} h={h:g}", start + cost * round(100.0 / h) + w, comm_step=h, rtol=1e-10)
            for h, w in zip(hs, wobble)]


def test_per_step_cost_recovers_a_linear_cost(scene):
    from stickslip.bench.results import per_step_cost

    cost, per_call, note = per_step_cost(_sweep("fmu", scene, 12e-6, 3e-3), "fmu", scene)
    assert cost == pytest.approx(12e-6, rel=1e-9) and per_call == pytest.approx(3e-3, rel=1e-9)
    assert "5 communication steps" in note


def test_per_step_cost_is_never_negative(scene):
    """Times that fall as the step count grows (noise on a quick run) give 0, never a negative cost."""
    from stickslip.bench.results import per_step_cost

    records = _sweep("fmu", scene, 0.0, 5e-3, wobble=[-2e-3, -1e-3, 0.0, 1e-3, 2e-3])  # fewest steps slowest
    cost, _, _ = per_step_cost(records, "fmu", scene)
    assert cost == 0.0
    assert np.polyfit([100000, 10000, 1000, 100, 10], [3e-3, 4e-3, 5e-3, 6e-3, 7e-3], 1)[0] < 0  # what lstsq gave


def test_per_step_cost_from_two_points_is_not_estimated(scene):
    from stickslip.bench.results import per_step_cost

    cost, per_call, note = per_step_cost(_sweep("fmu", scene, 12e-6, 3e-3)[:2], "fmu", scene)
    assert cost is None and per_call is None and "cannot be estimated from 2 communication steps" in note


def test_report_stamps_quick_runs_names_failures_and_compares_coarse_like_with_like(scene):
    from stickslip.bench.results import markdown

    records = [
        *_sweep("fmu", scene, 12e-6, 3e-3), *_sweep("floor", scene, 9e-6, 2e-3),
        _record("fmu", "FMU rtol=1e-10 h=0.05", 0.030, comm_step=0.05, rtol=1e-10),
        _record("solve_ivp", "DOP853 rtol=1e-10", 0.020, method="DOP853", rtol=1e-10),
        _record("solve_ivp", "DOP853 rtol=1e-06", None, error="Traceback\nOverflowError: math range error",
                method="DOP853", rtol=1e-6),
        _record("solve_ivp", "DOP853 rtol=1e-10 on the 10 s grid", 0.002, method="DOP853", rtol=1e-10, out_step=10.0),
    ]
    text = markdown(dict(META, quick=True), [scene], {scene.name: records})
    assert "smoke run, not a measurement" in text.splitlines()[0]
    row = next(line for line in text.splitlines() if line.startswith("| coulomb | 1e-08 |"))
    cells = [c.strip() for c in row.strip("|").split(" | ")]
    assert cells[4] == "20 ms (DOP853 rtol=1e-10); failed: DOP853 rtol=1e-06 (OverflowError: math range error)"
    assert cells[6] == "10"  # the coarse step H
    assert cells[7].startswith("3.") and "h=10" in cells[7]  # FMU at 10 s steps: 3 ms + 10 x 12 µs
    assert cells[8] == "2 ms (DOP853 rtol=1e-10 on the 10 s grid)"
    assert cells[10] == "1.6"  # 3.12 ms / 2 ms, both on the 10 s grid (not 3.12 / 20 = 0.16)
    assert "| coulomb | 12 | 9 | 1.3 | 3 | 2 | 1.5 | – | – | – | fit over 5 communication steps |" in text
    assert "smoke run" not in markdown(dict(META, quick=False), [scene], {scene.name: records}).splitlines()[0]


def test_model_exchange_table_sets_bare_cvode_beside_the_fmu_at_each_rtol(scene):
    from stickslip.bench.results import model_exchange_section

    records = [_record("fmi3-me", "FMI 3 ME, CVode rtol=1e-08", 0.100, rel_dx=3.5e-5, rtol=1e-8),
               _record("fmi3-me", "FMI 3 ME, CVode rtol=1e-06", 0.080, rel_dx=1e-4, rtol=1e-6),
               _record("cvode-bare", "bare CVode rtol=1e-08", 0.020, rel_dx=3.5e-5, rtol=1e-8),
               _record("cvode-bare", "bare CVode rtol=1e-06", 0.016, rel_dx=2.5e-5, rtol=1e-6),
               _record("cvode-bare", "bare CVode rtol=1e-10", 0.030, rel_dx=1e-7, rtol=1e-10)]
    text = "\n".join(model_exchange_section([scene], {scene.name: records}))
    assert "| coulomb | 1e-08 | 3.5e-05 | – | None | 100 ms | 3.5e-05 | 1 | 20 ms | 5 |" in text
    assert "| coulomb | 1e-06 | 0.0001 | – | None | 80 ms | 2.5e-05 | 4 | 16 ms | 5 |" in text
    assert "| coulomb | 1e-10 |" not in text  # bare CVode alone: nothing to set it beside


def test_solve_ivp_peer_on_a_coarse_grid_is_the_fine_run_thinned(coulomb):
    """Phases with no output time in them (the whole stick-slip cycle between two 10 s points) are fine."""
    fine = np.linspace(0.0, 100.0, 2001)
    coarse = fine[::200]
    a = hybrid_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, fine, "DOP853", 1e-12, 1e-12)
    b = hybrid_solve_ivp(coulomb, 0.0, V_DRIVE, V_DRIVE, 0.0, coarse, "DOP853", 1e-12, 1e-12)
    assert b.x.shape == coarse.shape
    assert np.abs(b.x - a.x[::200]).max() < 1e-9
    assert [e.kind for e in b.events] == [e.kind for e in a.events]


def test_bench_versus_times_fmus_in_turn_and_gives_their_ratios(fmu_path, capsys):
    """The same FMU twice: both rows end in the same state; the first row's ratios are 1."""
    from stickslip.cli import main

    code = main(["bench-versus", str(fmu_path), str(fmu_path), "--scene", "msl-pendulum", "--comm-step", "0.1",
                 "--rounds", "2", "--repeats", "1"])
    out = capsys.readouterr()
    assert code == 0, out.err
    rows = [line.split(" | ") for line in out.out.splitlines() if line.startswith(f"| {fmu_path}")]
    assert len(rows) == 2 and rows[0][3:5] == ["1", "1"] and rows[0][5] == rows[1][5]
    assert all(len(row[1].split(", ")) == 2 for row in rows)  # one median per round
    assert out.err.count("round 2/2") == 2


def test_bench_versus_refuses_an_unknown_scene(fmu_path, capsys):
    from stickslip.cli import main

    assert main(["bench-versus", str(fmu_path), "--scene", "no-such-scene"]) == 2
    assert "no-such-scene" in capsys.readouterr().err


def test_the_floor_fmu_has_every_output_of_ours_with_its_kind_and_the_bench_records_only_outputs():
    """The floor slave (built into its own FMU, so it cannot import the table) declares the outputs of the
    variable table with the same kind and variability; the benchmark records outputs both FMUs have."""
    from stickslip.bench.harness import FMU_OUTPUTS
    from stickslip.fmu_src.block_interface import VARIABLES

    spec = importlib.util.spec_from_file_location("floor_slave_under_test", fmus.FLOOR_SOURCE)
    floor = importlib.util.module_from_spec(spec)  # not in sys.modules: building the floor FMU is unaffected
    spec.loader.exec_module(floor)
    declared = {(name, "real", "continuous") for name in floor.REALS} | \
        {(name, "real", "discrete") for name in floor.DISCRETE_REALS} | \
        {(name, "integer", "discrete") for name in floor.INTEGERS}
    assert declared == {(v.name, v.kind, v.variability) for v in VARIABLES if v.causality == "output"}
    assert set(FMU_OUTPUTS) <= {name for name, _, _ in declared}
