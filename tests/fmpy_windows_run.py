"""Run the FMI 2 block FMU with FMPy for Windows in python.org's embeddable CPython (the Windows tests run it under
Wine): FMPy's wheels and its dependencies' for Windows, extracted into the folder SITE, go first on the path. Prints
"x T X" (co-simulation) and "m T X" (model exchange, FMPy's CVode at relative tolerance 1e-9) at every output point,
then "done", in the C host's format (``run_host`` parses it).

    python fmpy_windows_run.py SITE FMU STOP
"""

import sys

if __name__ == "__main__":
    site, fmu, stop = sys.argv[1:]
    sys.path.insert(0, site)
    from fmpy import simulate_fmu

    for tag, interface in (("x", "CoSimulation"), ("m", "ModelExchange")):
        result = simulate_fmu(fmu, fmi_type=interface, stop_time=float(stop), output_interval=0.1, output=["x"],
                              relative_tolerance=1e-9, record_events=False)
        for time, x in zip(result["time"], result["x"]):
            print(f"{tag} {float(time)!r} {float(x)!r}", flush=True)
    print("done", flush=True)
