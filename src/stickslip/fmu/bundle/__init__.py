"""The CPythons an FMU carries for hosts that have none, and what a host machine needs to run the FMU's binaries.

- :mod:`~stickslip.fmu.bundle.linux_python`: the building Python's shared library, the part of its standard library
  the FMU imports and the libraries beside them that glibc does not provide;
- :mod:`~stickslip.fmu.bundle.windows_python`: python.org's embeddable CPython for Windows, trimmed;
- :mod:`~stickslip.fmu.bundle.aarch64_python`: Debian's arm64 CPython, cut to the x86_64 one's modules
  (:mod:`~stickslip.fmu.bundle.debian_packages` fetches its packages), and
  :mod:`~stickslip.fmu.bundle.aarch64_binaries`: the FMI 3 FMU's aarch64 Linux binaries, cross-compiled;
- :mod:`~stickslip.fmu.bundle.packing`: each platform's carried CPython as one compressed file of the FMU, which the
  loader unpacks only where it starts that CPython, run through xz's branch filter of its machine code first
  (:mod:`~stickslip.fmu.bundle.branch_filters`: ARM64's, which Python's lzma module lacks);
- :mod:`~stickslip.fmu.bundle.floors`, :mod:`~stickslip.fmu.bundle.windows_needs`: the oldest glibc, libstdc++ and
  Windows versions the FMU's ELF and PE binaries (carried CPythons included) need, read from the binaries, and
  :mod:`~stickslip.fmu.bundle.platform_needs`: their text in the FMU, a part per Linux platform.
"""
