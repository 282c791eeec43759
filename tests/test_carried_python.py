"""The CPython an FMU carries is packed (``stickslip.fmu.bundle.packing``) and unpacked by the loader
(``loader/carried.c``) only where a host without Python starts it: into ``$SBF_PYTHON_CACHE`` here, each test with a
folder of its own. Two processes and two threads that unpack at once leave one complete folder; a folder that cannot
be made or written, a disk that fills up and an archive that was not extracted are messages naming the folder, the
reason and what to set; a folder that lost files is unpacked again; the runs equal FMPy's bit for bit; the files
unpacked equal liblzma's decoding of the archives (its own, its x86 branch filter undone, and its standard library's
in the archive the Linux platforms share); and a Python host (FMPy) unpacks
nothing."""

import shutil
import subprocess
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from stickslip.fmu.bundle import packing
from stickslip.hosts.c_host import host_env, run_host
from stickslip.hosts.fmpy_host import run_fmu
from stickslip.suite.scenario import load_scenario

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
SHORT = 20.0  # s


@pytest.fixture(scope="module")
def fmpy_x(fmu_path):
    """FMPy's (times, x) of the session's FMI 2 FMU over SHORT."""
    result = run_fmu(fmu_path, START, SHORT, SCENE.output_interval, outputs=["x"])
    return list(result["time"]), list(result["x"])


def run(host, folder, cache, mode="run"):
    """A C host's run of the FMU extracted to ``folder``, its CPython unpacked into ``cache``."""
    return run_host(host, folder, mode, SHORT, SCENE.output_interval, START, env={"SBF_PYTHON_CACHE": str(cache)})


def only_unpacked(cache):
    """The one folder the loader left in ``cache``, with nothing else (no half-written folder) beside it."""
    left = sorted(Path(cache).iterdir())
    assert len(left) == 1 and left[0].name.startswith("cpython-"), left
    return left[0]


def refusal(run):
    """The message of an instantiation the loader refused."""
    assert run.returncode == 1 and run.lines[-1] == ["failed", "fmi2Instantiate", "NULL"], (run.lines, run.stderr)
    return " ".join(text for _, _, text in run.logs)


def test_two_processes_unpacking_at_once_leave_one_folder_and_run_as_fmpy(host, unzipped, fmpy_x, tmp_path):
    with ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(lambda _: run(host, unzipped[0], tmp_path), range(2)))
    for each in runs:
        assert each.completed, (each.lines[-3:], each.logs, each.stderr[-2000:])
        assert each.series("x") == fmpy_x
    folder = only_unpacked(tmp_path)
    assert (folder / f"libpython{sys.version_info[0]}.{sys.version_info[1]}.so.1.0").is_file()
    extracted = Path(unzipped[0])
    files = {**packing.unpack((extracted / packing.packed_name("linux64")).read_bytes(), "linux64"),
             **packing.unpack_shared((extracted / packing.SHARED_PACK).read_bytes(), "linux64")}
    assert "python311.zip" in files and {name: (folder / name).read_bytes() for name in files} == files


def test_two_threads_starting_at_once_unpack_once(host, unzipped, fmpy_x, tmp_path):
    both = run(host, unzipped[0], tmp_path, "threads")
    assert both.completed and both.series("a") == both.series("b") == fmpy_x
    only_unpacked(tmp_path)


def test_a_folder_that_lost_files_is_unpacked_again(host, unzipped, fmpy_x, tmp_path):
    assert run(host, unzipped[0], tmp_path).completed
    folder = only_unpacked(tmp_path)
    standard_library = next(folder.glob("python3*.zip"))
    standard_library.unlink()
    again = run(host, unzipped[0], tmp_path)
    assert again.completed and again.series("x") == fmpy_x
    assert only_unpacked(tmp_path) == folder and standard_library.is_file()


def test_a_folder_that_cannot_be_made_is_a_message_naming_it(host, unzipped):
    message = refusal(run(host, unzipped[0], "/proc/sbf_cache"))
    assert "the CPython the FMU carries cannot be unpacked into /proc/sbf_cache/cpython-" in message
    assert "cannot make the folder" in message and "Set SBF_PYTHON_CACHE to a folder" in message


def test_a_full_disk_is_a_message_and_leaves_nothing_half_written(host, unzipped, tmp_path):
    """A 1 MB tmpfs (mounted in a user and mount namespace of its own) as the cache."""
    cache = tmp_path / "small"
    cache.mkdir()
    command = ["unshare", "-rm", "sh", "-c", f'mount -t tmpfs -o size=1m tmpfs "{cache}" || exit 9; "$0" "$@"; '
               f'code=$?; echo "left: $(ls -A "{cache}")" >&2; exit $code']
    probe = subprocess.run([*command, "true"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"no tmpfs can be mounted here: {probe.stderr.strip()}")
    full = run_host(host, unzipped[0], "run", SHORT, SCENE.output_interval, START,
                    env={"SBF_PYTHON_CACHE": str(cache)}, wrapper=command)
    message = refusal(full)
    assert "cannot be unpacked into" in message and "No space left on device" in message, message
    assert full.stderr.splitlines()[-1] == "left: "  # the half-written folder removed


def test_an_archive_the_host_did_not_extract_is_a_message(host, unzipped, tmp_path):
    partial = shutil.copytree(unzipped[0], tmp_path / "fmu", ignore=shutil.ignore_patterns("extra"))
    message = refusal(run(host, partial, tmp_path / "cache"))
    assert f"{packing.packed_name('linux64')} cannot be read" in message and "extract the whole FMU" in message


def test_a_python_host_unpacks_nothing(fmu_path, tmp_path):
    """FMPy extracts binaries/ and resources/ only, and starts no carried CPython."""
    script = textwrap.dedent(f"""
        import fmpy
        result = fmpy.simulate_fmu({str(fmu_path)!r}, stop_time=1.0, output_interval=0.1, output=["x"])
        print(repr(float(result["x"][-1])))
    """)
    cache = tmp_path / "cache"
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path,
                            env=host_env({"SBF_PYTHON_CACHE": str(cache)}), timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert not cache.exists()
