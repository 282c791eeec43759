"""Build dist/SpringBlockFriction.fmu (FMI 2.0), dist/SpringBlockFriction-fmi3.fmu (FMI 3.0) and
dist/ChainCoupling.fmu (a chain's coupling springs, FMI 2.0) and print their paths: ``python build_fmu.py
[--out DIR]``, the same as ``stickslip build [--out DIR]``. Needs the package installed (``bash scripts/setup.sh``
or ``pip install .``)."""

import sys

try:
    from stickslip.cli import main
except ImportError as exc:
    sys.exit(f"build_fmu.py: the stickslip package is not installed ({exc}); run: bash scripts/setup.sh")

if __name__ == "__main__":
    sys.exit(main(["build", *sys.argv[1:]]))
