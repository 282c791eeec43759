"""A Python host of the block FMUs: FMPy for Windows in python.org's embeddable CPython (the Windows tests run it under
Wine, and stop it with Ctrl-C). FMPy's wheels and its dependencies' for Windows, extracted into the folder SITE, go
first on the path. It loads the library CHECK first (``heap_check.c``: at the process's exit, after the FMUs' libraries
have gone, it prints whether every heap is intact), and instantiates the FMI 3 FMU (extracted in the folder FMU3),
which it frees at the end. Then, with the FMI 2 FMU (extracted in the folder FMU2), it prints in the C host's format
(``run_host`` parses it):

- "x T X" (co-simulation) and "m T X" (model exchange, FMPy's CVode at relative tolerance 1e-10) at every output
  point of a run of STOP s, and after each run "x_events N" and "m_events N" (the FMU's n_events at its end);
- "stepping", then it steps an instance (v_drive set before each step, so that both calls run the slave's Python
  code) until it has caught COUNT KeyboardInterrupts, each printed as "interrupted K" and followed by stepping on from
  where the FMU is (fmi2LastSuccessfulTime); then "y T X" (the FMU's time and position);
- "done" after freeing both instances. A failed FMI call ends it with "FMU error ..." and exit code 3.

    python fmpy_windows_run.py SITE CHECK FMU2 FMU3 STOP COUNT
"""

import ctypes
import sys


def step_until_interrupted(folder, count):
    """Step the FMU in ``folder`` until ``count`` KeyboardInterrupts have been caught (see above)."""
    description = fmpy.read_model_description(folder)
    refs = {variable.name: variable.valueReference for variable in description.modelVariables}
    slave = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                      modelIdentifier=description.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    print("stepping", flush=True)
    caught = 0
    while caught < count:
        try:
            t = slave.getRealStatus(fmi2LastSuccessfulTime)
            while True:
                slave.setReal([refs["v_drive"]], [0.1])
                slave.doStep(t, 0.01)
                t += 0.01
        except KeyboardInterrupt:
            caught += 1
            print("interrupted", caught, flush=True)
    print("y", slave.getRealStatus(fmi2LastSuccessfulTime), slave.getReal([refs["x"]])[0], flush=True)
    slave.terminate()
    slave.freeInstance()


if __name__ == "__main__":
    site, check, fmu2, fmu3, stop, count = sys.argv[1:]
    ctypes.CDLL(check)  # loaded before the FMUs' libraries: Windows detaches it after them
    sys.path.insert(0, site)
    import fmpy
    from fmpy import simulate_fmu
    from fmpy.fmi2 import FMU2Slave, fmi2LastSuccessfulTime
    from fmpy.fmi3 import FMU3Slave

    try:
        other = fmpy.read_model_description(fmu3)
        fmi3 = FMU3Slave(guid=other.guid, unzipDirectory=fmu3, modelIdentifier=other.coSimulation.modelIdentifier)
        fmi3.instantiate()  # its loader copy is the first in the process
        for tag, interface in (("x", "CoSimulation"), ("m", "ModelExchange")):
            result = simulate_fmu(fmu2, fmi_type=interface, stop_time=float(stop), output_interval=0.1,
                                  output=["x", "n_events"], relative_tolerance=1e-10, record_events=False)
            for time, x in zip(result["time"], result["x"]):
                print(f"{tag} {float(time)!r} {float(x)!r}", flush=True)
            print(f"{tag}_events {int(result['n_events'][-1])}", flush=True)
        step_until_interrupted(fmu2, int(count))
        fmi3.freeInstance()
    except Exception as failure:  # FMPy raises a plain Exception for a failed FMI call
        print("FMU error", failure, flush=True)
        sys.exit(3)
    print("done", flush=True)
