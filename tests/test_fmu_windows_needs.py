"""Each built FMU's ``documentation/externalDependencies.txt`` lists what its Windows DLLs need of the host: per
DLL its subsystem version, the newest Windows API function it imports and the DLLs it imports, and overall the
oldest Windows and what provides each imported DLL; checked against MinGW-w64's ``objdump -p`` (the PE header's
versions and the import tables), not against the builder's own PE reader."""

import re
import shutil
import subprocess
import zipfile

import pytest

from stickslip.fmu.bundle import packing
from stickslip.fmu.bundle.floors import DEPENDENCIES_FILE
from stickslip.fmu.bundle.windows_needs import API_SINCE, NotPE, release, windows_needs

OBJDUMP = "x86_64-w64-mingw32-objdump"


def objdump_needs(path):
    """``(subsystem version, operating system version, {DLL name: imported function names})`` of the PE file at
    ``path``, from objdump."""
    run = subprocess.run([OBJDUMP, "-p", str(path)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    subsystem, system = ("{}.{}".format(*(re.search(rf"^{part}{kind}Version\s+(\d+)", run.stdout, re.M)[1]
                                          for part in ("Major", "Minor"))) for kind in ("Subsystem", "OSystem"))
    imports = {}
    for block in re.split(r"^\s*DLL Name: ", run.stdout, flags=re.M)[1:]:
        dll, _, rest = block.partition("\n")
        table = rest.split("\n\n")[0]
        imports[dll.strip()] = re.findall(r"^\s*[0-9a-f]+\s+\d+\s+(\S+)", table, re.M)
    return subsystem, system, imports


@pytest.fixture(scope="module")
def has_objdump():
    if shutil.which(OBJDUMP) is None:
        pytest.skip(f"{OBJDUMP} (Debian's binutils-mingw-w64-x86-64) is not installed: the check reads the DLLs "
                    "with it")


@pytest.mark.parametrize("fmu", ["fmu_path", "fmu3_path", "coupling_path"])
def test_the_fmu_lists_the_windows_needs_objdump_finds(request, fmu, tmp_path, has_objdump):
    packing.extract(request.getfixturevalue(fmu), tmp_path)  # with its carried CPythons unpacked
    dlls = sorted([*(tmp_path / "binaries").rglob("*.dll"), *(tmp_path / "binaries").rglob("*.pyd")])
    if not dlls:
        pytest.skip("the FMU has no Windows binaries (the build found no MinGW-w64 cross-compiler)")
    text = (tmp_path / DEPENDENCIES_FILE).read_text()
    windows = text[text.index("on Windows x86_64"):]
    summary, _, per_binary = windows.partition("\nEach Windows binary:")
    floor, users_of_msvcp = (0, 0), []
    for dll in dlls:
        subsystem, system, imports = objdump_needs(dll)
        known = [(API_SINCE[name], name) for names in imports.values() for name in names if name in API_SINCE]
        newest = max(known) if known else None
        name = dll.relative_to(tmp_path).as_posix()
        api = f"{newest[1]} needs {release(newest[0])}" if newest else "no function newer than Windows XP"
        dll_names = ", ".join(imports) or "no DLLs"
        line = f"\n{name}: subsystem {subsystem} (operating system {system}); {api}; {dll_names}\n"
        assert line in per_binary
        version = tuple(map(int, subsystem.split(".")))
        floor = max(floor, version, newest[0] if newest else version)
        users_of_msvcp += [name] if "MSVCP140.dll" in imports else []
    assert f"\n- {release(floor)} or newer: " in summary
    redistributable = next(line for line in summary.splitlines() if "MSVCP140.dll" in line) if users_of_msvcp else ""
    assert all(name in redistributable.partition("(for ")[2] for name in users_of_msvcp)
    assert ("Visual C++ 2015-2022 Redistributable" in redistributable) == bool(users_of_msvcp)


def test_the_loader_needs_windows_7_for_the_functions_it_imports(fmu_path, tmp_path, has_objdump):
    with zipfile.ZipFile(fmu_path) as archive:
        names = [name for name in archive.namelist() if name == "binaries/win64/SpringBlockFriction.dll"]
        if not names:
            pytest.skip("the FMU has no Windows binaries (the build found no MinGW-w64 cross-compiler)")
        needs = windows_needs(archive.read(names[0]))
    assert set(needs.imports) == {"KERNEL32.dll", "msvcrt.dll"}
    assert needs.newest_api()[0] == (6, 1) and needs.floor() == (6, 1)


@pytest.mark.parametrize("data", [b"", b"\x7fELF\x02\x01\x01" + bytes(57), b"MZ" + bytes(58) + b"\x40\0\0\0",
                                  b"MZ" + bytes(58) + b"\x40\0\0\0PE\0\0" + bytes(4)],
                         ids=["empty", "linux", "no-signature", "truncated"])
def test_what_is_no_pe_binary_is_refused_with_the_reason(data):
    with pytest.raises(NotPE):
        windows_needs(data)
