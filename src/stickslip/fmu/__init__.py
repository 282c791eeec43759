"""Build the SpringBlockFriction FMUs (FMI 2.0 co-simulation; FMI 3.0 co-simulation and model exchange).

- :mod:`~stickslip.fmu.build`: :func:`build`, :func:`ensure_fmu`, the default paths;
- :mod:`~stickslip.fmu.sources`: where the slaves, the runtime and the loader are; the source tag;
- :mod:`~stickslip.fmu.staging`: how the runtime and the slave are laid out in the FMU;
- :mod:`~stickslip.fmu.compile_runtime`: mypyc compilation of the runtime's hot modules;
- :mod:`~stickslip.fmu.model_description`: completion of the library's model description;
- :mod:`~stickslip.fmu.archive`: the FMU's zip archive, written reproducibly;
- :mod:`~stickslip.fmu.loader`: the C loader that becomes the FMU's Linux binary;
- :mod:`~stickslip.fmu.bundle`: the CPythons the FMU carries for hosts without one, and the floors of its binaries;
- :mod:`~stickslip.fmu.variable_docs`: ``docs/variables.md`` from a built FMU.
"""

from .build import FILE_NAMES, FMI_VERSIONS, build, default_fmu_path, ensure_fmu
from .sources import MODEL_NAME, is_current, source_tag

__all__ = ["FILE_NAMES", "FMI_VERSIONS", "MODEL_NAME", "build", "default_fmu_path", "ensure_fmu", "is_current",
           "source_tag"]
