"""The branch filters of the packed CPythons (``stickslip.fmu.bundle.branch_filters``, ``packing.py``): ARM64's
on instructions worked out by hand, and xz-utils (an implementation of its own) reads every pack of the session's FMI
3 FMU, and the archive its Linux platforms share, as the tar archive of the files the build packed."""

import shutil
import struct
import subprocess
import zipfile

import pytest

from stickslip.fmu.bundle import packing
from stickslip.fmu.bundle.branch_filters import arm64_branches


def words(*values):
    return struct.pack(f"<{len(values)}I", *values)


def test_arm64_makes_bl_and_near_adrp_absolute_and_back():
    plain = words(
        0xD503201F,                          # pc 0x0: NOP, left as it is
        0x94000010,                          # pc 0x4: BL +0x10 words
        0x97FFFFFF,                          # pc 0x8: BL -1 word
        0x90000001 | (5 >> 2) << 5 | (5 & 3) << 29,  # pc 0xc: ADRP x1, +5 pages
        0x90200002,                          # pc 0x10: ADRP x2, +2^18 pages: out of range, left as it is
    ) + b"\x01\x02"                          # a partial word at the end, left as it is
    encoded = arm64_branches(plain, encode=True)
    assert encoded[:4] == plain[:4] and encoded[16:] == plain[16:]
    assert struct.unpack("<3I", encoded[4:16]) == (
        0x94000000 | (0x10 + 0x4 // 4),      # the offset plus pc/4
        0x94000000 | 0x1,                    # -1 + 2, modulo 2^26
        0x90000001 | (5 >> 2) << 5 | (5 & 3) << 29)  # pc 0xc is on page 0: +5 stays
    page = 0x1000 * 3                        # the same ADRP on page 3 becomes page 8
    assert arm64_branches(b"\0" * page + plain[12:16], encode=True)[page:] == words(0x90000001 | (8 >> 2) << 5)
    assert arm64_branches(encoded, encode=False) == plain


def test_xz_reads_the_packs_of_the_fmi3_fmu(fmu3_path):
    xz = shutil.which("xz")
    if xz is None:
        pytest.skip("xz-utils (xz) is not installed: the independent decoding of the packs")
    with zipfile.ZipFile(fmu3_path) as fmu:
        packs = {name: fmu.read(name) for name in fmu.namelist() if packing.carried_python_platform(name)}
    assert {"x86_64-linux", "x86_64-windows"} <= {packing.carried_python_platform(name) for name in packs}
    for name, data in packs.items():
        platform = packing.carried_python_platform(name)
        branch_filter = packing.FILTERS[platform]
        lc, lp, pb = packing.LITERAL_BITS.get(branch_filter, (3, 0, 2))
        command = [xz, "-dc", "--format=raw", f"--{branch_filter}", f"--lzma1=lc={lc},lp={lp},pb={pb},dict=8MiB"]
        tar = subprocess.run(command, input=data[packing.HEADER_SIZE:], capture_output=True, check=True).stdout
        assert tar == packing.tar_archive(packing.unpack(data, platform)), name
    shared = zipfile.ZipFile(fmu3_path).read(packing.SHARED_PACK)  # plain LZMA
    tar = subprocess.run([xz, "-dc", "--format=lzma"], input=shared, capture_output=True, check=True).stdout
    linux = {packing.carried_python_platform(name) for name in packs} - {"x86_64-windows"}
    assert tar == packing.tar_archive({f"{packing.shared_prefix(platform)}{name}": data for platform in linux
                                       for name, data in packing.unpack_shared(shared, platform).items()})
