"""Scenario and system files by name (stickslip.cli.named_files): the shipped files are the checkout's, a name finds
its file from any folder, an existing path wins over a name, an unknown name is refused with the list of names."""

from pathlib import Path

import pytest

from stickslip.cli import main
from stickslip.cli.named_files import SCENARIOS, SYSTEMS, UnknownNameError, local_paths, resolve, shipped
from stickslip.suite import runner
from stickslip.systems import run as system_run

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("package, folder", [(SCENARIOS, "scenarios"), (SYSTEMS, "systems")])
def test_the_shipped_files_are_the_checkouts(package, folder):
    files = shipped(package)
    checkout = sorted((ROOT / folder).glob("*.toml"))
    assert list(files) == [path.stem for path in checkout]
    assert [file.read_bytes() for file in files.values()] == [path.read_bytes() for path in checkout]


def test_a_name_finds_its_file_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with local_paths([resolve("elmer-fig3-v0.1", SCENARIOS), resolve("chain2-coulomb", SYSTEMS)]) as paths:
        assert [path.read_bytes() for path in paths] == [(ROOT / "scenarios" / "elmer-fig3-v0.1.toml").read_bytes(),
                                                         (ROOT / "systems" / "chain2-coulomb.toml").read_bytes()]


def test_an_existing_path_wins_over_a_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("chain2-coulomb").write_text("a local file")
    assert resolve("chain2-coulomb", SYSTEMS) == Path("chain2-coulomb")
    assert resolve(str(ROOT / "scenarios"), SCENARIOS) == ROOT / "scenarios"


def test_an_unknown_name_lists_the_known_ones(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UnknownNameError, match=r"^chain9: no such file, nor the name of a system .*\(names: "
                                               r"bk10-velocity-weakening, bk100-velocity-weakening, chain2-coulomb, "):
        resolve("chain9", SYSTEMS)


@pytest.mark.parametrize("argv, package", [(["run", "elmer-fig3"], SCENARIOS),
                                           (["system", "run", "chain9", "--master", "me"], SYSTEMS),
                                           (["system", "ssp", "chain9"], SYSTEMS)])
def test_the_command_line_refuses_an_unknown_name_in_one_line(argv, package, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 1
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"stickslip {argv[0]}: {argv[-1] if argv[0] == 'run' else 'chain9'}: no such file")
    assert line.endswith(f"(names: {', '.join(shipped(package))})")
    assert list(tmp_path.iterdir()) == []


def test_run_takes_names_and_without_a_path_every_shipped_scenario(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    given = []

    class Passed:
        ok = True

    monkeypatch.setattr(runner, "run_suite", lambda paths, *args, **kwargs: given.append(
        [Path(path).read_bytes() for path in paths]) or Passed())
    assert main(["run", "coulomb-stick-slip", str(ROOT / "scenarios" / "msl-pendulum.toml")]) == 0
    assert main(["run"]) == 0
    scenarios = sorted((ROOT / "scenarios").glob("*.toml"))
    assert given == [[(ROOT / "scenarios" / name).read_bytes() for name in ("coulomb-stick-slip.toml",
                                                                            "msl-pendulum.toml")],
                     [path.read_bytes() for path in scenarios]]


def test_system_run_takes_a_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    given = []

    class Outcome:
        ok, summary, files = True, "chain2-coulomb me: PASS", ("csv", "md")

    monkeypatch.setattr(system_run, "run_system", lambda path, *args, **kwargs: given.append(
        Path(path).read_bytes()) or Outcome())
    assert main(["system", "run", "chain2-coulomb", "--master", "me"]) == 0
    assert given == [(ROOT / "systems" / "chain2-coulomb.toml").read_bytes()]
