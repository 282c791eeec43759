"""Build dist/SpringBlockFriction.fmu (FMI 2.0) and dist/SpringBlockFriction-fmi3.fmu (FMI 3.0) and print
their paths: ``python build_fmu.py``."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "src"))

from stickslip.fmu3_build import build3  # noqa: E402
from stickslip.fmu_build import build  # noqa: E402

if __name__ == "__main__":
    print(build())
    print(build3())
