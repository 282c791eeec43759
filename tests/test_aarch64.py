"""The FMI 3 FMU's aarch64 Linux binaries (``stickslip.fmu.bundle.aarch64_binaries``) under QEMU's user-mode
emulator: the project's FMI 3 C host, built for aarch64, runs in an aarch64 root that holds glibc alone (the cross
toolchain's, Debian 12's 2.36) and QEMU's static emulator, with the FMU extracted there, so that the only CPython,
standard library and libraries besides glibc there are the ones the FMU carries. A bad parameter is an error naming
it, then the default scene's x equals the x86_64 host's run of the same FMU to 1e-13 m; FMU states replay; two
instances on two threads run side by side; the CPython, packed in the FMU, was unpacked by the aarch64 loader; where
the host names a CPython of its own, the loader still unpacks the pack for the pythonfmu3 binary it holds, and says so
where it cannot. Five emulated processes in all, the first three as many at once as there are cores. Skipped, saying
why, where QEMU, the cross-compiler or chroot are missing, or the build could not give the FMU its aarch64 binaries.
Also: a build without the cross-compiler or Debian's packages leaves the platform out and says why."""

import os
import shutil
import subprocess
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from stickslip.fmu.bundle import aarch64_binaries, debian_packages, packing
from stickslip.fmu.bundle.aarch64_binaries import FOLDER
from stickslip.fmu.bundle.floors import DEPENDENCIES_FILE
from stickslip.hosts.c_host import aarch64_root, compile_host, host_env, run_host
from stickslip.suite.scenario import load_scenario

import machine_needs

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
SHORT = 20.0  # s: stop time of the runs that check behaviour rather than the whole scene
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"
TOLERANCE = 1e-13  # m


@pytest.fixture(scope="module")
def jail(tmp_path_factory, fmu3_path):
    """``(root, wrapper, host)``: an aarch64 root with glibc, QEMU's static emulator, the FMI 3 C host built for
    aarch64 and the FMI 3 FMU extracted (``/fmu3``), and the command prefix that runs the host there."""
    qemu = machine_needs.qemu_aarch64("the aarch64 binaries' tests")
    with zipfile.ZipFile(fmu3_path) as fmu:
        if packing.packed_name(FOLDER.split("/")[1]) not in fmu.namelist():
            pytest.skip(f"the FMU has no aarch64 binaries with their CPython (the build said why on stderr)")
        assert not any(name.startswith(f"{FOLDER}/python/") for name in fmu.namelist())  # packed, not laid out
        root = tmp_path_factory.mktemp("aarch64_root")
        fmu.extractall(root / "fmu3")
    host = compile_host(root, fmi_version=3, aarch64=True)
    wrapper = aarch64_root(root, qemu)
    probe = subprocess.run(wrapper + [f"/{host.name}"], capture_output=True, text=True, env=host_env())
    if probe.stderr.startswith("chroot:") or shutil.which("chroot") is None:
        pytest.skip(f"this process may not chroot: {probe.stderr.strip() or 'chroot is not installed'}")
    return root, wrapper, host


def completed(run):
    assert run.completed, f"host exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


@pytest.fixture(scope="module")
def runs(jail, host3, unzipped3):
    """``{mode: (the aarch64 host's run, the x86_64 host's run of the FMU's x86_64 binaries)}`` of the modes bad
    (M = -1, then the whole scene), state and unload (two instances on two threads), SHORT s for the last two."""
    root, wrapper, host = jail

    def both(mode, stop, start):
        emulated = run_host(host, root / "fmu3", mode, stop, SCENE.output_interval, start, wrapper=wrapper, root=root)
        return mode, (emulated, run_host(host3, unzipped3[0], mode, stop, SCENE.output_interval, start))

    modes = (("bad", SCENE.stop_time, [*START.items(), ("M", -1.0)]), ("state", SHORT, START), ("unload", SHORT, START))
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:  # each emulated process keeps a core busy
        runs = dict(pool.map(lambda arguments: both(*arguments), modes))
    return {mode: (completed(emulated), completed(native)) for mode, (emulated, native) in runs.items()}


def assert_close(series, reference):
    assert series[0] == reference[0] and len(series[1]) == len(reference[1]) > 0
    assert max(abs(a - b) for a, b in zip(series[1], reference[1])) <= TOLERANCE


def test_a_bad_parameter_is_an_error_naming_it_then_the_scene_equals_x86_64(runs):
    emulated, native = runs["bad"]
    assert int(emulated.value("status")[1]) == 3  # fmi3Error at fmi3ExitInitializationMode
    assert [(status, instance) for status, instance, _ in emulated.logs] == [(3, "bad")]
    assert BAD_MASS in emulated.logs[0][2]
    assert emulated.series("x")[0][-1] == SCENE.stop_time
    assert_close(emulated.series("x"), native.series("x"))


def test_fmu_states_replay_and_two_instances_run_side_by_side(runs):
    emulated, native = runs["state"]
    for tag in ("x", "r", "d"):
        assert_close(emulated.series(tag), native.series(tag))
    emulated, native = runs["unload"]
    assert len(emulated.series("x")[1]) == len(native.series("x")[1])
    # both threads' lines, interleaved
    assert max(abs(a - b) for a, b in zip(sorted(emulated.series("x")[1]), sorted(native.series("x")[1]))) <= TOLERANCE


def test_the_aarch64_loader_unpacked_the_cpython_it_started(jail, runs):
    """The emulated processes ran with no cache folder set: the loader unpacked the packed CPython beside itself."""
    root = jail[0]
    platform = FOLDER.split("/")[1]
    files = {**packing.unpack((root / "fmu3" / packing.packed_name(platform)).read_bytes(), platform),
             **packing.unpack_shared((root / "fmu3" / packing.SHARED_PACK).read_bytes(), platform)}
    unpacked = root / "fmu3" / FOLDER / "python"
    assert "python311.zip" in files  # from the archive the Linux platforms share
    assert {name: (unpacked / name).read_bytes() for name in files} == files  # its ARM64 branch filter undone
    assert not list((root / "fmu3" / FOLDER).glob("*.part"))  # no half-written folder left behind


def test_a_host_with_a_python_of_its_own_has_the_pack_unpacked_for_pythonfmu3s_binary(jail, runs, host3, unzipped3):
    """The aarch64 folder holds no pythonfmu3 binary: with ``SBF_LIBPYTHON`` naming a CPython (a copy of the carried
    one outside the FMU, standing for the host's own), the loader unpacks the pack into the empty cache folder set
    and loads that binary from there; the run equals the x86_64 host's. Where the pack cannot be unpacked (the cache
    folder below a file), the instantiation fails saying so, without pointing at ``SBF_LIBPYTHON``."""
    root, wrapper, host = jail
    assert sorted(path.name for path in (root / "fmu3" / FOLDER).glob("*.so")) == ["SpringBlockFriction.so",
                                                                                  "sbf_start_guard.so"]
    shutil.copytree(root / "fmu3" / FOLDER / "python", root / "own_python")
    env = {"SBF_LIBPYTHON": "/own_python/libpython3.11.so.1.0", "LD_LIBRARY_PATH": "/own_python/lib"}

    def emulated_run(cache):
        return run_host(host, root / "fmu3", "run", SHORT, SCENE.output_interval, START,
                        env={**env, "SBF_PYTHON_CACHE": cache}, wrapper=wrapper, root=root)

    refused = emulated_run(f"/{host.name}/cache")
    message = " ".join(text for _, _, text in refused.logs)
    assert not refused.completed and "cannot load the FMU's inner binary, and the CPython the FMU carries cannot be " \
        f"unpacked into /{host.name}/cache/cpython-" in message, (refused.lines[-3:], message)
    assert "Set SBF_PYTHON_CACHE to a folder where it can be" in message and "SBF_LIBPYTHON" not in message
    emulated = emulated_run("/cache")
    native = run_host(host3, unzipped3[0], "run", SHORT, SCENE.output_interval, START)
    assert_close(completed(emulated).series("x"), completed(native).series("x"))
    assert list((root / "cache").glob("*/lib/libpythonfmu3-export.so"))


def test_the_fmu_says_what_an_aarch64_host_needs(fmu3_path):
    with zipfile.ZipFile(fmu3_path) as fmu:
        names, needs = fmu.namelist(), fmu.read(DEPENDENCIES_FILE).decode()
        description = fmu.read("modelDescription.xml")
    if f"{FOLDER}/SpringBlockFriction.so" not in names:
        pytest.skip("the FMU has no aarch64 binaries (the build said why on stderr)")
    assert b'needsExecutionTool="false"' in description
    section = needs.split("on Linux aarch64", 1)[1]
    assert "GLIBC_2.3" in section and f"{FOLDER}/python/libpython3.11.so.1.0" in section
    assert "libstdc++" not in section  # pythonfmu3's binary has its C++ runtime linked in
    inner = (f"- the FMI library's binary: the FMU's build of it ({FOLDER}/python/lib/libpythonfmu3-export.so), which "
             f"the loader loads on every host: it unpacks {packing.packed_name(FOLDER.split('/')[1])} for it also "
             f"where the host process runs a CPython of its own")
    assert inner in section and "the FMI library's binary:" not in needs.split("on Linux aarch64", 1)[0]


def test_a_build_without_the_cross_compiler_or_the_packages_leaves_the_platform_out_and_says_so(
        monkeypatch, tmp_path, capsys):
    """No aarch64 entries, and a note naming what is missing (the loader's compile function is never reached)."""
    entries = {"modelDescription.xml": b""}
    arguments = (True, 3, "token", True)
    monkeypatch.setattr(aarch64_binaries, "compilers", lambda: (("cc", "c++"), "no aarch64 cross-compiler (...)"))
    aarch64_binaries.install(entries, "SpringBlockFriction", arguments, None, None)
    assert "has no aarch64 Linux binaries: no aarch64 cross-compiler" in capsys.readouterr().err
    monkeypatch.setattr(aarch64_binaries, "compilers", lambda: (("cc", "c++"), None))
    monkeypatch.setattr(debian_packages, "arm64_root", lambda: (None, "apt-get download failed: ..."))
    aarch64_binaries.install(entries, "SpringBlockFriction", arguments, "the x86_64 bundle", None)
    assert "Debian's arm64 packages of CPython could not be had: apt-get download failed" in capsys.readouterr().err
    assert entries == {"modelDescription.xml": b""}
    monkeypatch.setenv("PATH", str(tmp_path))
    assert debian_packages.download(tmp_path) == (None, "apt-get is not installed (a Debian or Ubuntu machine fetches "
                                                        "Debian's arm64 packages)")
