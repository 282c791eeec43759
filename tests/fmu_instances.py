"""Direct access to the FMU through FMPy's FMU2Slave, shared by the tests."""

from fmpy.fmi2 import FMU2Slave


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
