"""Shared fixtures: the FMUs (FMI 2 and FMI 3) built once per test session from the current sources."""

import shutil

import fmpy
import pytest

from stickslip.fmu import build


@pytest.fixture(scope="session")
def fmu_path(tmp_path_factory):
    """Path of a SpringBlockFriction.fmu freshly built from the working tree (dist/ is left alone)."""
    return build(tmp_path_factory.mktemp("fmu") / "SpringBlockFriction.fmu")


@pytest.fixture(scope="session")
def fmu3_path(tmp_path_factory):
    """Path of a SpringBlockFriction-fmi3.fmu freshly built from the working tree."""
    return build(fmi_version=3, dest=tmp_path_factory.mktemp("fmu3") / "SpringBlockFriction-fmi3.fmu")


def _extracted(path):
    """(extracted folder, model description, {name: variable}) of the FMU at ``path``; removes the folder after."""
    folder = fmpy.extract(str(path))
    description = fmpy.read_model_description(str(path))
    yield folder, description, {v.name: v for v in description.modelVariables}
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session")
def unzipped(fmu_path):
    """(extracted folder, model description, {name: variable}) of the session's FMU."""
    yield from _extracted(fmu_path)


@pytest.fixture(scope="session")
def unzipped3(fmu3_path):
    """The same for the session's FMI 3 FMU."""
    yield from _extracted(fmu3_path)
