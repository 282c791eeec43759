"""Shared fixtures: the FMU built once per test session from the current sources."""

import pytest

from stickslip.fmu_build import build


@pytest.fixture(scope="session")
def fmu_path(tmp_path_factory):
    """Path of a SpringBlockFriction.fmu freshly built from the working tree (dist/ is left alone)."""
    return build(tmp_path_factory.mktemp("fmu") / "SpringBlockFriction.fmu")
