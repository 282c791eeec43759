"""``stickslip chain`` end to end in a child process: the files, the exit status, the catalogue against the block
events, the reference on the shipped Burridge-Knopoff chain, Ctrl-C, and the refusals."""

import csv
import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from cli_child import STICKSLIP
from test_chain_catalogue import union_of_intervals

from stickslip.chain.catalogue import read_slip_events

ROOT = Path(__file__).resolve().parents[1]
FILES = ["block_events.csv", "positions.csv", "slip_events.csv", "slips.png", "statistics.json", "statistics.md",
         "statistics.png"]


def stickslip(*args, timeout=600):
    return subprocess.run([*STICKSLIP, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def slip_intervals(path):
    """Each block's slip intervals ``(t_slip, block, x_slip, t_stick, x_stick)`` paired from ``block_events.csv``
    (every block starts stuck)."""
    slipping, out = {}, []
    with path.open() as f:
        for row in csv.DictReader(f):
            t, block, x = float(row["time"]), int(row["block"]), float(row["x"])
            if row["kind"] == "slip":
                slipping[block] = (t, x)
            elif row["kind"] == "stick":
                t0, x0 = slipping.pop(block)
                out.append((t0, block, x0, t, x))
    return out, slipping


def test_a_small_chain_writes_its_catalogue_statistics_and_figures(tmp_path):
    out = tmp_path / "out"
    done = stickslip("chain", "--n", 5, "--stop-time", 600, "--output-interval", 0.5, "--seed", 3, "--out", out,
                     "--quiet")
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir()) == FILES
    assert done.stdout.startswith("chain5-seed3: 5 blocks over 600 s in ")
    positions = np.loadtxt(out / "positions.csv", delimiter=",", skiprows=1)
    assert (out / "positions.csv").read_text().startswith("time,x_b1,x_b2,x_b3,x_b4,x_b5\n")
    assert np.allclose(positions[:, 0], np.arange(1201) * 0.5)
    # the catalogue is the union of the blocks' slip intervals (an independent grouping of the block events)
    intervals, still = slip_intervals(out / "block_events.csv")
    expected = [e for e in union_of_intervals(intervals) if not any(t0 <= e["end"] for t0, _ in still.values())]
    table = read_slip_events(out / "slip_events.csv")
    assert len(expected) == table["start"].size > 5
    assert table["start"].tolist() == [e["start"] for e in expected]
    assert table["end"].tolist() == [e["end"] for e in expected]
    assert table["size"].tolist() == [len(e["blocks"]) for e in expected]
    np.testing.assert_allclose(table["moment"], [e["moment"] for e in expected], rtol=1e-12, atol=1e-15)
    statistics = json.loads((out / "statistics.json").read_text())
    assert statistics["events"] == table["start"].size and statistics["blocks"] == 5
    assert statistics["block_events"] == sum(1 for _ in (out / "block_events.csv").open()) - 1
    assert statistics["stop_time"] == 600 and statistics["output_interval"] == 0.5



def test_the_shipped_chain_against_the_reference(tmp_path):
    """bk10 over 300 s: the engine's 210 block events pair with the reference's, the same 16 slip events."""
    done = stickslip("chain", "--system", "bk10-velocity-weakening", "--rtol", 1e-12, "--reference", "--quiet",
                     "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "210 block events, 16 slip events" in done.stdout
    reference = json.loads((tmp_path / "reference.json").read_text())
    assert reference["events"] == {"slip": [105, 105], "stick": [105, 105], "overshoot": [0, 0]}
    assert reference["max_event_dt"] < 1e-6 and reference["max_rel_dx"] < 1e-6
    assert reference["slip_events"]["engine"] == reference["slip_events"]["reference"] == 16
    assert reference["slip_events"]["same_sizes"]
    assert "reference.json" in done.stdout


def test_ctrl_c_keeps_what_was_written_and_exits_130(tmp_path):
    proc = subprocess.Popen([*STICKSLIP, "chain", "--n", "100", "--stop-time", "1e7", "--out", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    events = tmp_path / "slip_events.csv"
    deadline = time.monotonic() + 300
    while not (events.exists() and len(events.read_text().splitlines()) > 3):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if line.startswith("stickslip chain")]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    assert lines[0].startswith("stickslip chain: interrupted (at t = ")
    assert f"kept what was written in {tmp_path}: slip_events.csv, block_events.csv)" in lines[0]
    assert read_slip_events(events)["start"].size >= 3
    assert (tmp_path / "block_events.csv").read_text().startswith("time,block,kind,x\n")


@pytest.mark.parametrize("args, message", [
    (["--n", "0"], "argument --n: allowed is a whole number >= 1, got '0'"),
    (["--kc", "-1"], "key 'system.coupling[0]': allowed is a finite number in [0, inf), got -1.0"),
    (["--kinetic", "stribek"], "--kinetic 'stribek': allowed is a kinetic law by name or code: 1 coulomb"),
    (["--kinetic", "coulomb:F1=0.5"], "--kinetic coulomb: 'F1' is not one of its parameters: allowed are F0"),
    (["--kinetic", "coulomb:F0"], "argument --kinetic: allowed is LAW[:NAME=VALUE,...] with finite values"),
    (["--system", "bk10-velocity-weakening", "--n", "3"], "--n: a template option, allowed only without --system"),
    (["--stop-time", "-1"], "argument --stop-time: allowed is a finite time > 0 s, got '-1'"),
    (["--rtol", "1"], "argument --rtol: allowed is a tolerance in [1e-14, 0.01], got '1'"),
])
def test_bad_options_are_refused_naming_the_option(tmp_path, args, message):
    done = stickslip("chain", *args, "--out", tmp_path, "--quiet", timeout=120)
    assert done.returncode in (1, 2) and message in done.stderr, done.stderr
    assert not (tmp_path / "block_events.csv").exists()
