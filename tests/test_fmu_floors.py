"""Each built FMU's ``documentation/externalDependencies.txt`` lists what its ELF binaries need of the host: the
newest glibc, libstdc++ (GLIBCXX, CXXABI) and libgcc_s versions over all of them, each binary's libraries and
newest versions, and the CPython shared library; checked against binutils' ``objdump`` (``-T``: the versions of
the undefined dynamic symbols; ``-p``: the NEEDED entries), not against the builder's own ELF reader."""

import re
import shutil
import subprocess
import sys
import zipfile

import pytest

from stickslip.fmu.bundle import packing
from stickslip.fmu.bundle.floors import DEPENDENCIES_FILE, NotELF, binary_needs
from stickslip.fmu.loader.install import build_libpython

VERSION = re.compile(r"\(?\b([A-Z]+)_(\d+(?:\.\d+)*)\)?")


def objdump(flag, path):
    run = subprocess.run(["objdump", flag, str(path)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    return run.stdout


def objdump_needs(path):
    """``(NEEDED names in order, {prefix: newest version name})`` of the ELF file at ``path``, from objdump."""
    newest = {}
    for line in objdump("-T", path).splitlines():
        match = VERSION.search(line) if "*UND*" in line else None
        if match:
            number = tuple(map(int, match[2].split(".")))
            if match[1] not in newest or number > newest[match[1]][1]:
                newest[match[1]] = (f"{match[1]}_{match[2]}", number)
    needed = re.findall(r"^\s*NEEDED\s+(\S+)", objdump("-p", path), re.M)
    return tuple(needed), {prefix: name for prefix, (name, _) in newest.items()}


@pytest.fixture(scope="module")
def has_objdump():
    if shutil.which("objdump") is None:
        pytest.skip("objdump (binutils) is not installed: the check reads the binaries' version needs with it")


@pytest.mark.parametrize("fmu", ["fmu_path", "fmu3_path", "coupling_path"])
def test_the_fmu_lists_the_floors_objdump_finds(request, fmu, tmp_path, has_objdump):
    path = request.getfixturevalue(fmu)
    packing.extract(path, tmp_path)  # with its carried CPythons unpacked
    text = (tmp_path / DEPENDENCIES_FILE).read_text()
    x86_64, _, aarch64 = text.partition(" on Linux aarch64, measured")
    _check_section(x86_64, [p for p in _elf_files(tmp_path) if "aarch64-linux" not in p.parts], tmp_path)
    if (tmp_path / "binaries" / "aarch64-linux").is_dir():  # the FMI 3 FMU where the build could cross-compile
        _check_section(aarch64, [p for p in _elf_files(tmp_path) if "aarch64-linux" in p.parts], tmp_path, ("GLIBC",))


def _elf_files(folder):
    return sorted(p for p in folder.rglob("*.so*") if re.fullmatch(r".*\.so(\.\d+)*", p.name)
                  and p.relative_to(folder).parts[0] in ("binaries", "resources"))


def _check_section(text, binaries, tmp_path, families=("GLIBC", "GLIBCXX", "CXXABI")):
    """The part of the file on one Linux platform lists each of its ``binaries`` and their overall floors."""
    summary, _, per_binary = text.partition("\nEach binary:")
    overall = {}
    assert any("binaries" in p.parts for p in binaries) and binaries
    for binary in binaries:
        needed, newest = objdump_needs(binary)
        name = binary.relative_to(tmp_path).as_posix()
        line = next(line for line in per_binary.splitlines() if line.startswith(f"{name}: "))
        assert line == f"{name}: {', '.join(needed) or 'no libraries'}; " + (
            ", ".join(sorted(newest.values())) or "no versioned symbols")
        for prefix, version in newest.items():
            if prefix not in overall or _number(version) > _number(overall[prefix]):
                overall[prefix] = version
    assert set(families) <= set(overall)
    assert sorted(re.findall(r": ([A-Z]+_[0-9.]+) or newer", summary)) == sorted(overall.values())


def _number(version):
    return tuple(map(int, VERSION.fullmatch(version)[2].split(".")))


@pytest.mark.parametrize("fmu", ["fmu_path", "coupling_path"])
def test_the_fmu_names_the_cpython_library_its_loader_starts(request, fmu):
    with zipfile.ZipFile(request.getfixturevalue(fmu)) as archive:
        text = archive.read(DEPENDENCIES_FILE).decode()
        tags = {re.search(r"\.cpython-3(\d+)-", name)[1] for name in archive.namelist()
                if name.startswith("resources/") and name.endswith(".so")}
    path, soname = build_libpython()
    carried = re.search(r"else the one the FMU carries \((binaries/[^/]+/python/[^,]+), with", text)
    assert (carried[1].endswith(f"/python/{soname}") if path else f"else {soname} (the build's;" in text), text
    assert (carried is None) == (not path)
    versions = ", ".join(f"3.{minor}" for minor in sorted(tags, key=int))
    assert (f"The runtime is compiled for CPython {versions};" in text) == bool(tags), text
    assert not tags or str(sys.version_info[1]) in tags


@pytest.mark.parametrize("data", [b"", b"MZ\x90\x00" + bytes(60), b"\x7fELF\x02\x01\x01" + bytes(57),
                                  b"\x7fELF\x02\x01\x01" + bytes(33) + b"\x40" + bytes(14) + b"\x40\x00\x05"],
                         ids=["empty", "windows", "no-sections", "truncated"])
def test_what_is_no_elf_shared_object_is_refused_with_the_reason(data):
    with pytest.raises(NotELF):
        binary_needs(data)


@pytest.mark.parametrize("fmu, floor", [("fmu_path", "3.8"), ("coupling_path", "3.8"), ("fmu3_path", "3.9")])
def test_the_fmu_names_the_oldest_cpython_its_python_code_runs_in(request, fmu, floor):
    """The FMI 2 FMUs' runtime needs 3.8 (typing.Final), pythonfmu3 3.9; the loader refuses older ones
    (tests/test_loader_host_python.py)."""
    with zipfile.ZipFile(request.getfixturevalue(fmu)) as archive:
        text = archive.read(DEPENDENCIES_FILE).decode()
    assert f"the host process's own CPython ({floor} or newer) if it runs one" in text
