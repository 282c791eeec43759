"""A plain C FMI 2.0 importer (``host.c``) that runs an FMU outside any Python process.

It stands for the C/C++ system simulators: it opens the FMU's binary with
``dlopen(RTLD_NOW | RTLD_LOCAL)`` and nothing preloaded. :func:`compile_host`
builds it with the system C compiler (``$CC``, default ``cc``); :func:`run_host`
runs one of its modes (see ``host.c``) in a child process, so that a crash only
shows as a return code, and parses what it printed.
"""

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import fmpy

SOURCE = Path(__file__).resolve().with_name("host.c")


class HostBuildError(RuntimeError):
    """The C host cannot be compiled here."""


def compile_host(build_dir):
    """Compile ``host.c`` into ``build_dir`` (unless it is newer than the source); return the executable's path."""
    dest = Path(build_dir) / "sbf_c_host"
    if dest.is_file() and dest.stat().st_mtime >= SOURCE.stat().st_mtime:
        return dest
    compiler = os.environ.get("CC") or "cc"
    if shutil.which(compiler) is None:
        raise HostBuildError(f"no C compiler: {compiler!r} not found (set CC)")
    dest.parent.mkdir(parents=True, exist_ok=True)
    partial = dest.with_name(f".{dest.name}.{os.getpid()}")
    result = subprocess.run([compiler, "-O2", "-o", str(partial), str(SOURCE), "-ldl", "-lpthread", "-lm"],
                            capture_output=True, text=True)
    if result.returncode != 0:
        raise HostBuildError(f"{compiler} failed to compile {SOURCE.name}:\n{result.stderr}")
    os.replace(partial, dest)
    return dest


@dataclass
class HostRun:
    """What one run of the host printed: ``lines`` (without the log lines), ``logs`` as (status, instance, text)."""

    returncode: int
    lines: list
    logs: list
    stderr: str

    @property
    def completed(self):
        """The mode ran to its end (the host printed "done" and exited with 0)."""
        return self.returncode == 0 and self.lines[-1:] == [["done"]]

    def series(self, tag):
        """``(times, values)`` of the lines starting with ``tag`` (floats exactly as the host had them)."""
        rows = [line[1:] for line in self.lines if line[0] == tag]
        return [float(t) for t, _ in rows], [float(x) for _, x in rows]

    def value(self, key):
        """The words after the first line starting with ``key`` (a list), or None."""
        return next((line[1:] for line in self.lines if line[0] == key), None)


def run_host(host, fmu_folder, mode, stop_time, step, start_values=(), output="x", env=None, timeout=600):
    """Run ``host`` in ``mode`` on the FMU extracted to ``fmu_folder``.

    ``start_values``: {name: value} or (name, value) pairs, set in this order (mode "bad" leaves the last
    one out of its second instance).
    The child gets only ``PATH`` from this process's environment, plus ``env``.
    """
    folder = Path(fmu_folder).resolve()
    description = fmpy.read_model_description(str(folder))
    variables = {v.name: v for v in description.modelVariables}
    settings = [f"{'i' if variables[name].type == 'Integer' else 'r'}{variables[name].valueReference}={value!r}"
                for name, value in (start_values.items() if hasattr(start_values, "items") else start_values)]
    binary = folder / "binaries" / "linux64" / f"{description.coSimulation.modelIdentifier}.so"
    command = [str(host), str(binary), (folder / "resources").as_uri(), description.guid, mode, repr(stop_time),
               repr(step), str(variables[output].valueReference), *settings]
    child_env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), **(env or {})}
    result = subprocess.run(command, capture_output=True, text=True, env=child_env, timeout=timeout)
    lines, logs = [], []
    for line in result.stdout.splitlines():
        if line.startswith("log "):
            _, status, instance, text = (line.split(" ", 3) + [""])[:4]
            logs.append((int(status), instance, text))
        else:
            lines.append(line.split())
    return HostRun(result.returncode, lines, logs, result.stderr)
