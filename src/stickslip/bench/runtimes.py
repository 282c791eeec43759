"""The two implementations of the runtime the benchmark compares: compiled (mypyc) and pure Python.

:data:`PURE_CORE` is the runtime from its Python sources only, imported beside the
(compiled) ``stickslip.core`` as a package of its own; :func:`ensure_pure_fmu` builds the
FMU without compiling its runtime. Both run the same sources, so they give the same numbers.
"""

import os
from pathlib import Path

from .. import core
from ..core._implementation import import_pure_copy
from ..fmu import build, source_tag
from ..fmu.build import announce_build

PURE_CORE = import_pure_copy(os.path.dirname(core.__file__), "stickslip_bench_pure_core")


def in_core(runtime, p):
    """``Parameters`` ``p`` rebuilt with the classes of the runtime package ``runtime``."""
    if runtime is core:
        return p
    return runtime.Parameters(p.M, p.kappa, runtime.kinetic_law(p.kinetic.CODE, **p.kinetic.parameters()),
                              runtime.static_law(p.static.CODE, **p.static.parameters()))


def ensure_pure_fmu(build_dir):
    """``SpringBlockFriction-pure.fmu`` in ``build_dir``, built from the current sources unless it is."""
    dest = Path(build_dir) / "SpringBlockFriction-pure.fmu"
    marker = dest.with_suffix(".tag")
    tag = source_tag()
    if not (dest.is_file() and marker.is_file() and marker.read_text() == tag):
        announce_build(dest)
        build(dest, pure=True)
        marker.write_text(tag)
    return dest
