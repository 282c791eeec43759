"""Build dist/SpringBlockFriction.fmu and print its path: ``python build_fmu.py``."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "src"))

from stickslip.fmu_build import build  # noqa: E402

if __name__ == "__main__":
    print(build())
