"""Direct access to the FMUs through FMPy's FMU2Slave and FMU3Slave, shared by the tests."""

from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave


def instantiate(unzipped, name, start):
    """An initialized instance of the extracted FMU ``unzipped`` with the given start values."""
    folder, description, variables = unzipped
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(loggingOn=True)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    for key, value in start.items():
        variable = variables[key]
        setter = fmu.setInteger if variable.type in ("Integer", "Enumeration") else fmu.setReal
        setter([variable.valueReference], [value])
    fmu.exitInitializationMode()
    return fmu


def instantiate3(unzipped3, name, start, cls=FMU3Slave, start_time=0.0):
    """An initialized instance of the extracted FMI 3 FMU ``unzipped3`` (``cls``: ``FMU3Slave`` for co-simulation or
    ``FMU3Model``) with the given start values, started at ``start_time`` (s)."""
    folder, description, variables = unzipped3
    fmu = cls(guid=description.guid, unzipDirectory=folder, instanceName=name,
              modelIdentifier=description.coSimulation.modelIdentifier)
    fmu.instantiate(loggingOn=True)
    fmu.enterInitializationMode(startTime=start_time)
    for key, value in start.items():
        variable = variables[key]
        setter = {"Int32": fmu.setInt32, "Enumeration": fmu.setInt64}.get(variable.type, fmu.setFloat64)
        setter([variable.valueReference], [value])
    fmu.exitInitializationMode()
    return fmu
