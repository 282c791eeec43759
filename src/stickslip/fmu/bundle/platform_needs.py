"""The FMU's ``documentation/externalDependencies.txt`` with a part per Linux platform it has binaries for: x86_64
(with the Windows DLLs' needs after it) and each of :data:`OTHER_LINUX`, each measured by
:mod:`stickslip.fmu.bundle.floors` from that platform's binaries alone (the runtime is compiled for x86_64 only: the
others run its sources)."""

import dataclasses

from . import floors
from .aarch64_binaries import FOLDER as AARCH64_FOLDER
from .packing import carried_entries, carried_python_platform

#: the folders of the FMU's Linux binaries for machines other than x86_64, and the platform's name in the text
OTHER_LINUX = {f"{AARCH64_FOLDER}/": "Linux aarch64"}


def dependencies_text(model_name, entries):
    """The text of :data:`~stickslip.fmu.bundle.floors.DEPENDENCIES_FILE` for the FMU ``model_name`` of ``entries``
    ({archive name: bytes}); the carried CPythons are read unpacked, each with its platform's binaries."""
    entries = {**{name: data for name, data in entries.items() if carried_python_platform(name) is None},
               **carried_entries(entries)}
    others = tuple(OTHER_LINUX)
    text = floors.dependencies_text(model_name, floors.fmu_floors(
        {name: data for name, data in entries.items() if not name.startswith(others)}))
    for folder, platform in OTHER_LINUX.items():
        part = {name: data for name, data in entries.items() if name.startswith(folder)}
        if part:
            part["modelDescription.xml"] = entries["modelDescription.xml"]
            measured = dataclasses.replace(floors.fmu_floors(part), compiled_for=())  # the runtime runs its sources
            text += "\n" + floors.dependencies_text(model_name, measured, platform)
    return text
