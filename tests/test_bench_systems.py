"""``stickslip bench-systems`` (:mod:`stickslip.bench.systems_bench`): the report's numbers agree with each other
and with the runs they come from (no timing is asserted)."""

import json
import math
from pathlib import Path

import pytest

from stickslip.bench.systems_bench import order, wall_at_error
from stickslip.cli import main

CHAIN2 = Path(__file__).resolve().parents[1] / "systems" / "chain2-coulomb.toml"


def run(error, wall, setting=1.0):
    return {"setting": setting, "error": error, "wall": wall}


def test_wall_at_error_interpolates_between_measured_runs_and_never_extrapolates():
    runs = [run(1e-4, 1.0), run(1e-8, 10.0), run(1e-12, 100.0)]
    assert wall_at_error(runs, 1e-6) == (1e-6, pytest.approx(10.0 ** 0.5))  # log-log halfway from 1 s to 10 s
    assert wall_at_error(runs, 1e-8) == (1e-8, 10.0)
    assert wall_at_error(runs, 1e-2) == (1e-4, 1.0)  # beyond the loosest run: that run
    assert wall_at_error(runs, 1e-13) is None  # no run that accurate
    assert wall_at_error([run(1e-8, 1.0), run(1e-6, 5.0)], 1e-7) == (1e-8, 1.0)  # a cheaper, more accurate run


def test_order_is_the_slope_of_the_log_error():
    runs = [run(0.4, 0.0, 0.1), run(0.04, 0.0, 0.01), run(0.002, 0.0, 0.001)]
    found = order(runs)
    assert found["steps"] == pytest.approx([1.0, math.log10(20.0)])
    assert order(runs[:1]) == {"fit": None, "steps": []}


def test_the_command_reports_consistent_numbers(tmp_path):
    """chain2 over 12 s (two slips of each block): zoh at 0.1 and 0.01 s, adaptive and me at two rtol values,
    adaptive on the FMI 3 FMU (early return) at one of them, side by side with the FMI 2 run; the scipy peer at two
    rtol values, exact on this chain (its events paired), and every master's run beside it at matched error."""
    out = tmp_path / "bench"
    code = main(["bench-systems", str(CHAIN2), "--stop-time", "12", "--zoh-steps", "0.1", "0.01",
                 "--adaptive-rtols", "1e-5", "1e-9", "--adaptive-fmi3-rtols", "1e-9", "--me-rtols", "1e-6", "1e-10",
                 "--peer-rtols", "1e-8", "1e-12", "--out", str(out)])
    assert code == 0
    assert all((out / name).is_file() for name in ("systems.json", "systems.md", "systems.png"))
    record = json.loads((out / "systems.json").read_text())["scenes"][0]
    assert (record["scene"], record["stop_time"]) == ("chain2-coulomb", 12.0)
    zoh, adaptive = record["runs"]["zoh"], record["runs"]["adaptive"]
    assert [r["setting"] for r in zoh] == [0.1, 0.01]
    assert 0.01 < zoh[0]["error"] < 0.1 and 0.8 < record["orders"]["zoh"]["fit"] < 1.6  # first order
    assert record["orders"]["zoh"]["fit"] == pytest.approx(math.log10(zoh[0]["error"] / zoh[1]["error"]))
    assert all(r["error"] < 1e-8 and r["events_paired"] for r in adaptive + record["runs"]["me"])
    for row, z in zip(record["matched"], zoh):
        assert (row["h"], row["zoh_error"], row["zoh_wall"]) == (z["setting"], z["error"], z["wall"])
        assert row["adaptive_error"] <= row["zoh_error"]
        assert min(r["wall"] for r in adaptive) <= row["adaptive_wall"] <= max(r["wall"] for r in adaptive)
        assert row["ratio"] == pytest.approx(row["zoh_wall"] / row["adaptive_wall"])
    early = record["runs"]["adaptive-fmi3"]
    assert [r["setting"] for r in early] == [1e-9] and early[0]["error"] < 1e-8 and early[0]["events_paired"]
    (side,) = record["early_return"]
    assert (side["fmi2_wall"], side["fmi3_wall"]) == (adaptive[1]["wall"], early[0]["wall"])
    assert side["ratio"] == pytest.approx(early[0]["wall"] / adaptive[1]["wall"])
    peer = record["runs"]["scipy-peer"]
    assert [r["setting"] for r in peer] == [1e-8, 1e-12]
    assert all(r["error"] < 1e-8 and r["events_paired"] for r in peer)
    masters = [(m, r) for m in ("adaptive", "adaptive-fmi3", "me") for r in record["runs"][m]]
    assert [(row["master"], row["setting"]) for row in record["peer"]] == [(m, r["setting"]) for m, r in masters]
    for row in record["peer"]:
        assert row["peer_error"] <= row["error"] and row["ratio"] == pytest.approx(row["wall"] / row["peer_wall"])
    text = (out / "systems.md").read_text()
    assert "## chain2-coulomb (12 s" in text and "| zoh | h = 0.01 |" in text and "| adaptive | rtol = 1e-09 |" in text
    assert "| adaptive-fmi3 | rtol = 1e-09 |" in text and "| FMI 3 wall / FMI 2 wall |" in text
    assert "| scipy-peer | rtol = 1e-12 |" in text and "| wall / peer wall |" in text


def test_the_command_refuses_a_stop_time_off_the_grid(capsys):
    assert main(["bench-systems", str(CHAIN2), "--stop-time", "12.05", "--out", "unused"]) == 2
    assert "--stop-time 12.05 is not a positive multiple of the output interval" in capsys.readouterr().err
