"""Ensembles of chains: the merged catalogue is the concatenation of the members run one by one (bit for bit, serial,
on the process pool and on a local Dask cluster), the combined statistics pool the members' events, the options'
refusals, and Ctrl-C keeps the finished members."""

import json
import os
import signal
import subprocess
import time

import numpy as np
import pytest

from cli_child import STICKSLIP

from stickslip.chain.catalogue import SLIP_EVENTS_FILE, read_slip_events
from stickslip.chain.ensemble import (EnsembleError, ensemble_members, parse_seeds, parse_sweep, run_ensemble,
                                      with_template_value)
from stickslip.chain.folder_run import run_into_folder
from stickslip.chain.statistics import catalogue_statistics
from stickslip.chain.template import chain_system

N, STOP = 8, 600.0
TEMPLATE = {"offset_spread": 0.1}


def test_seeds_and_sweeps_are_read_and_bad_ones_refused():
    assert parse_seeds("0-3,7") == [0, 1, 2, 3, 7]
    assert parse_seeds("5") == [5]
    assert parse_sweep("kc=3,4.5") == ("kc", [3.0, 4.5])
    assert parse_sweep("kinetic.F_stribeck=0.3,0.4") == ("kinetic.F_stribeck", [0.3, 0.4])
    for text, message in (("3-1", "must run from a seed >= 0 upwards"), ("a", "allowed is a list of whole numbers"),
                          ("1,1", "a seed is given twice")):
        with pytest.raises(EnsembleError, match=message):
            parse_seeds(text)
    for text, message in (("mass=1", "NAME one of M, kappa"), ("kc=", "distinct finite numbers"),
                          ("kc=1,1", "distinct finite numbers"), ("kc=nan", "distinct finite numbers")):
        with pytest.raises(EnsembleError, match=message):
            parse_sweep(text)


def test_a_sweep_sets_the_value_in_the_template_or_its_law():
    members = ensemble_members(TEMPLATE, [0, 1], ("kinetic.F_stribeck", [0.3, 0.35]))
    assert [m.label for m in members] == ["kinetic.F_stribeck=0.3-seed0", "kinetic.F_stribeck=0.3-seed1",
                                          "kinetic.F_stribeck=0.35-seed0", "kinetic.F_stribeck=0.35-seed1"]
    assert members[2].values["kinetic"]["F_stribeck"] == 0.35 and members[2].values["kinetic"]["F0"] == 0.5
    assert with_template_value(TEMPLATE, "kc", 3.0) == {"offset_spread": 0.1, "kc": 3.0}
    system = chain_system(N, seed=1, **members[3].values)
    assert all(b["kinetic.F_stribeck"] == 0.35 for b in system.blocks)


def single_runs(tmp_path, seeds):
    """The merged catalogue expected from the members run one by one as ``stickslip chain --seed k`` runs them."""
    lines = []
    for index, seed in enumerate(seeds):
        system = chain_system(N, seed=seed, name=f"seed{seed}", stop_time=STOP, output_interval=STOP, **TEMPLATE)
        folder = tmp_path / "single" / f"seed{seed}"
        run_into_folder(system, folder, stop_time=STOP)
        lines += [f"{index},{line}" for line in (folder / SLIP_EVENTS_FILE).read_text().splitlines()[1:]]
    return lines


def test_the_merged_catalogue_is_the_members_concatenation_serial_pool_and_dask(tmp_path):
    seeds = [0, 1, 2]
    expected = single_runs(tmp_path, seeds)
    merged = {}
    for name, options in (("serial", {"workers": 1}), ("pool", {"workers": 2})):
        run = run_ensemble(N, ensemble_members(TEMPLATE, seeds), STOP, tmp_path / name, progress=False, **options)
        assert run.finished == ["seed0", "seed1", "seed2"]
        merged[name] = (tmp_path / name / SLIP_EVENTS_FILE).read_text()
    run_ensemble(N, ensemble_members(TEMPLATE, seeds), STOP, tmp_path / "dask", dask="local", workers=2,
                 progress=False)
    merged["dask"] = (tmp_path / "dask" / SLIP_EVENTS_FILE).read_text()
    header, *rows = merged["serial"].splitlines()
    assert header == "member,start,duration,size,moment,first_block,end,n_slips,n_block_events"
    assert rows == expected and len(rows) > 30
    assert merged["pool"] == merged["serial"] == merged["dask"]


def test_the_combined_statistics_pool_the_members_and_give_their_spread(tmp_path):
    seeds = [0, 1, 2, 3]
    run = run_ensemble(N, ensemble_members(TEMPLATE, seeds), 1500.0, tmp_path, workers=2, progress=False)
    data = json.loads(run.files["json"].read_text())
    (group,) = data["groups"]
    tables = [read_slip_events(tmp_path / f"seed{s}" / SLIP_EVENTS_FILE) for s in seeds]
    pooled = {name: np.concatenate([t[name] for t in tables]) for name in tables[0]}
    assert group["pooled"]["events"] == sum(t["size"].size for t in tables) > 100
    expected = catalogue_statistics(pooled, N)
    assert group["pooled"]["size_fit"]["alpha"] == pytest.approx(expected["size_fit"]["alpha"], rel=1e-12)
    own = [json.loads((tmp_path / f"seed{s}" / "statistics.json").read_text())["size_fit"] for s in seeds]
    alphas = [fit["alpha"] for fit in own if "alpha" in fit]
    spread = group["spread"]["size"]
    assert spread["count"] == len(alphas) and spread["mean"] == pytest.approx(np.mean(alphas))
    assert min(alphas) <= group["pooled"]["size_fit"]["alpha"] <= max(alphas) or len(alphas) < 2
    text = run.files["md"].read_text()
    assert f"{group['pooled']['events']} slip events pooled" in text and "the members' own: mean" in text
    assert run.files["exponents"].stat().st_size > 10_000 and (tmp_path / "pooled.png").exists()


def test_a_sweep_from_the_command_line_combines_per_value(tmp_path):
    proc = subprocess.run([*STICKSLIP, "chain", "--n", str(N), "--offset-spread", "0.1", "--stop-time", "800",
                           "--sweep", "kc=3,5", "--seeds", "0-1", "--workers", "2", "--quiet", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "4 chains of 8 blocks over 800 s" in proc.stdout
    members = (tmp_path / "members.csv").read_text().splitlines()
    assert members[0] == "member,label,seed,kc,block_events,slip_events"
    assert members[3].startswith("2,kc=5.0-seed0,0,5.0,")
    groups = json.loads((tmp_path / "ensemble.json").read_text())["groups"]
    assert [g["swept"] for g in groups] == [{"kc": 3.0}, {"kc": 5.0}]
    assert [g["members"] for g in groups] == [["kc=3.0-seed0", "kc=3.0-seed1"], ["kc=5.0-seed0", "kc=5.0-seed1"]]
    for g in groups:
        counts = [read_slip_events(tmp_path / label / SLIP_EVENTS_FILE)["size"].size for label in g["members"]]
        assert g["pooled"]["events"] == sum(counts)


@pytest.mark.parametrize("args, message", [
    (["--seeds", "2-1"], "argument --seeds: the range '2-1' must run from a seed >= 0 upwards"),
    (["--sweep", "mass=1,2"], "argument --sweep: allowed is NAME=V1,V2,... with NAME one of M, kappa"),
    (["--workers", "0"], "argument --workers: allowed is a whole number >= 1, got '0'"),
    (["--seeds", "0-1", "--seed", "3"], "--seed: not with --seeds or --sweep"),
    (["--seeds", "0-1", "--system", "bk10-velocity-weakening"], "allowed only without --system"),
])
def test_bad_ensemble_options_are_refused_naming_the_option(tmp_path, args, message):
    proc = subprocess.run([*STICKSLIP, "chain", *args, "--out", str(tmp_path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode in (1, 2) and message in proc.stderr, proc.stderr


@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_keeps_the_finished_members_says_where_and_exits_130(tmp_path, workers):
    proc = subprocess.Popen([*STICKSLIP, "chain", "--n", str(N), "--offset-spread", "0.1", "--seeds", "0-5",
                             "--stop-time", "300", "--workers", str(workers), "--out", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 300
    while not any(tmp_path.glob("*/member.json")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr, stderr
    finished = [k for k in range(6) if (tmp_path / f"seed{k}" / "member.json").exists()]
    assert 1 <= len(finished) < 6
    line = next(line for line in stderr.replace("\r", "\n").splitlines() if line.startswith("stickslip chain"))
    assert line == (f"stickslip chain: interrupted ({len(finished)} of 6 chains finished, their files and the merged "
                    f"catalogue in {tmp_path}; the others hold what they wrote)")
    members = [int(row.split(",")[0]) for row in (tmp_path / SLIP_EVENTS_FILE).read_text().splitlines()[1:]]
    assert sorted(set(members)) == finished
