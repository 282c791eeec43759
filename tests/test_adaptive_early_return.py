"""The ``adaptive`` master on the FMI 3 FMU (``fmi=3``, ``--fmi 3``): early return from ``fmi3DoStep`` at each
block's event, blocks whose forces did not change not stepped again, the output derivatives' cubic predictor,
against the chain's reference; the choice of the FMU and its errors. The FMI 2 scheme is held by ``tests/test_systems.py``."""

import dataclasses

import numpy as np
import pytest

from stickslip.cli import main
from stickslip.hosts.fmpy_host import FMUError
from stickslip.reference import simulate_chain
from stickslip.systems import adaptive, load_system, make_master
from stickslip.systems.compare import compare
from test_systems import CHAIN2, scene


@pytest.mark.parametrize("name", ["chain2-coulomb", "chain3-coulomb", "chain3-stribeck-aging"])
def test_early_return_keeps_the_chains_exact(name, fmu3_path):
    """Every chain of systems/ over its whole stop time at the default rtol: within 1e-8 of the amplitude, the
    reference's events and no others, paired within 1e-8 s, with early returns that stopped steps and blocks not
    stepped again. chain2-coulomb holds the first sweep's convergence: at 95.25 s a landing redo of 6e-4 s had
    b1's hold break away at the redo's end, and the cubic predictor made the first sweep converge before b1 was
    swept with its cells' forces: the breakaway landed 4.5e-4 s late (1.8e-4 of the amplitude)."""
    system, reference = scene(name)
    result = make_master("adaptive", fmi=3).run(system, fmu3_path)
    comparison = compare(result, reference, system.tolerances["adaptive"])
    assert comparison.ok and comparison.max_rel_dx < 1e-8, comparison
    assert list(comparison.master_events) == list(comparison.reference_events)
    assert np.all(comparison.max_event_dt < 1e-8), comparison.max_event_dt
    assert not any(e.kind == "overshoot" for e in result.events)
    assert result.stats["early returns"] > 0 and result.stats["sweeps of a block skipped"] > 0
    assert result.stats["events not landed"] == 0


def test_the_fmu_is_chosen_by_fmi(fmu_path, fmu3_path):
    """``fmi`` picks the FMU (default 2, the scheme without early return); a wrong value or the other FMU's file
    is refused, naming it."""
    assert make_master("adaptive").FMI_VERSION == 2 and make_master("adaptive", fmi=3).FMI_VERSION == 3
    with pytest.raises(FMUError, match=r"adaptive: fmi = 4: allowed are 2 and 3"):
        make_master("adaptive", fmi=4)
    with pytest.raises(FMUError, match=r"master 'zoh' takes no option 'fmi' \(the masters \['adaptive'\] do\)"):
        make_master("zoh", fmi=3)
    with pytest.raises(FMUError, match=r"adaptive: .* is an FMI 2 FMU; the master runs the FMI 3 FMU"):
        make_master("adaptive", fmi=3).run(load_system(CHAIN2), fmu_path)


def test_the_command_runs_the_fmi3_scheme(tmp_path, capsys):
    """``stickslip system run --master adaptive --fmi 3``: its own files beside the FMI 2 run's, within the
    file's tolerance (exit 0)."""
    text = CHAIN2.read_text().replace("stop_time = 100.0", "stop_time = 20.0")
    assert "stop_time = 20.0" in text
    path = tmp_path / "chain2-coulomb.toml"
    path.write_text(text)
    assert main(["system", "run", str(path), "--master", "adaptive", "--fmi", "3", "--out", str(tmp_path),
                 "--quiet"]) == 0
    assert ": PASS" in capsys.readouterr().out
    report = (tmp_path / "chain2-coulomb-adaptive-fmi3.md").read_text()
    assert "early returns" in report
    assert not (tmp_path / "chain2-coulomb-adaptive.md").exists()


def test_the_command_takes_the_fmi_version_from_the_fmu(tmp_path, fmu3_path, capsys):
    """``--fmu`` naming the FMI 3 FMU without ``--fmi`` runs the early-return scheme (its model description says the
    version); ``--fmi 2`` given beside it wins and is refused, naming the file's version."""
    text = CHAIN2.read_text().replace("stop_time = 100.0", "stop_time = 5.0")
    path = tmp_path / "chain2-coulomb.toml"
    path.write_text(text)
    arguments = ["system", "run", str(path), "--master", "adaptive", "--fmu", str(fmu3_path), "--out", str(tmp_path),
                 "--quiet"]
    assert main(arguments) == 0
    assert ": PASS" in capsys.readouterr().out
    assert "early returns" in (tmp_path / "chain2-coulomb-adaptive-fmi3.md").read_text()
    assert not (tmp_path / "chain2-coulomb-adaptive.md").exists()
    assert main(arguments + ["--fmi", "2"]) == 1
    assert "is an FMI 3 FMU; the master runs the FMI 2 FMU" in capsys.readouterr().err


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_slipping_block_steps_each_cell_in_one_do_step(fmi, fmu_path, fmu3_path, monkeypatch):
    """The force over a cell is a line (F_ext and its rate: FMI 2's input derivative, FMI 3's input der(F_ext)), so
    every doStep that sets a block's force spans one cell of its attempt, or the whole attempt (a hold), or holds a
    stuck block's force from an attempt's start or to it (a step ahead or back): none is a half cell. The 2-block
    chain over 12 s (two slips of each block), against the reference."""
    cells, steps = set(), []
    attempt_init, block_step = adaptive._Attempt.__init__, adaptive._Blocks.step

    def recorded_attempt(self, times, *args):
        cells.update(zip(times[:-1], times[1:]))
        cells.add((times[0], times[-1]))
        attempt_init(self, times, *args)

    def recorded_step(self, i, t, h, force=None, rate=0.0, last=True):
        if force is not None:
            steps.append(((t, t + h), rate))
        return block_step(self, i, t, h, force, rate, last)

    monkeypatch.setattr(adaptive._Attempt, "__init__", recorded_attempt)
    monkeypatch.setattr(adaptive._Blocks, "step", recorded_step)
    system = dataclasses.replace(load_system(CHAIN2), stop_time=12.0)
    reference = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, system.times())
    result = make_master("adaptive", fmi=fmi).run(system, fmu3_path if fmi == 3 else fmu_path)
    assert compare(result, reference, system.tolerances["adaptive"]).max_rel_dx < 1e-8
    starts = {start for start, _ in cells}
    assert len(steps) > 100 and all(step in cells or (rate == 0.0 and (step[0] in starts or step[1] in starts))
                                    for step, rate in steps)
