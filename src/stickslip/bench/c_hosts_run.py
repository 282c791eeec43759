"""``stickslip bench-c-hosts``: every measurement of the C-host benchmarks in one run (see
benchmarks/README.md): the C-host family (:mod:`.c_hosts`) with ours at the peer's error, the FMPy family
against the peer (:mod:`.matched_error`), the ``.fmu`` file against DOP853 and against the floor
(:mod:`.fmu_file_runs`), each block FMU against the same FMU without its carried CPython (:mod:`.carried_cost`), the
FMU states beside a step in the C hosts and FMPy, both FMI versions and the C floor (:mod:`.state_costs`). The result
is one JSON-ready dict; :mod:`.c_hosts_report` writes it out.
"""

import datetime
import os
import platform
import tempfile
from dataclasses import dataclass
from pathlib import Path

from . import c_hosts, carried_cost, dymola_peer, state_costs
from .c_floor import ensure_c_floor_fmu
from .fmu_file_runs import dense_grid, dense_grid_tuned, one_step
from .matched_error import fmpy_family, loosest_rtol
from .scenes import SCENES

STEP = 0.01  # s, the communication step of the C-host family
#: Reference-FMUs built beside fmusim (scripts/build_fmusim.sh): file name, the output read
REFERENCE_FLOORS = (("Feedthrough.fmu", "Float64_continuous_output"), ("Dahlquist.fmu", "x"))


@dataclass
class Inputs:
    """What a run measures: FMU files (``peer`` and ``fmusim`` may be None), the C hosts (FMI 2, FMI 3), the build
    folder; ``carried_python``: also each block FMU against the same FMU built without its carried CPython."""

    fmu: Path
    fmu3: Path
    python_floor: Path
    host: Path
    host3: Path
    build_dir: Path
    peer: Path | None = None
    fmusim: Path | None = None
    carried_python: bool = True


def run_all(inputs, steps, repeats, progress=print, state_rounds=state_costs.ROUNDS):
    """Every measurement (``steps`` per long host run, ``repeats`` timed runs of each, ``state_rounds`` calls per
    block of the FMU-state costs); a dict for JSON."""
    scene = SCENES["msl-pendulum"]
    meta = {"date": datetime.datetime.now().isoformat(timespec="seconds"),
            "machine": f"{platform.platform()}, {os.cpu_count()} CPUs", "load_start": _load(),
            "steps": steps, "step": STEP, "repeats": repeats,
            "files": {k: str(v) for k, v in vars(inputs).items() if v is not None}}
    out = {"meta": meta}
    with tempfile.TemporaryDirectory() as work:
        hosts = [c_hosts.CHost(inputs.host, work)]
        if inputs.fmusim is not None:
            hosts.append(c_hosts.Fmusim(inputs.fmusim, work))
        peer = dymola_peer.subject(inputs.peer) if inputs.peer is not None else None
        if peer is not None:
            meta["peer_mismatches"] = dymola_peer.mismatches(inputs.peer, scene)
        out["matched"], ours = _match_in_hosts(hosts, peer, inputs.fmu, scene, progress)
        c_floor = ensure_c_floor_fmu(inputs.build_dir)
        subjects = [ours, *([peer] if peer else []), c_hosts.Subject("PythonFMU floor", inputs.python_floor),
                    c_hosts.Subject("C floor", c_floor), *_reference_floors(inputs)]
        out["hosts"] = {host.name: c_hosts.measure(host, subjects, STEP, steps, repeats, progress) for host in hosts}
    if peer is not None:
        out["fmpy"] = fmpy_family(inputs.peer, peer, inputs.fmu, scene, repeats, progress)
    out["dense_grid"] = dense_grid(inputs.fmu, repeats, progress)
    out["dense_grid_tuned"] = dense_grid_tuned(inputs.fmu, repeats, progress)
    out["one_step"] = one_step(inputs.fmu, inputs.python_floor, 3 * repeats, progress)
    if inputs.carried_python:
        out["carried_python"] = carried_cost.measure(*_block_fmus(inputs), inputs.build_dir, 3 * repeats, progress)
    out["states"] = state_costs.measure(*_block_fmus(inputs), state_rounds, progress, floor=c_floor)
    meta["load_end"] = _load()
    return out


def _block_fmus(inputs):
    """``({FMI version: FMU}, {FMI version: C host})`` of both block FMUs."""
    return {2: inputs.fmu, 3: inputs.fmu3}, {2: inputs.host, 3: inputs.host3}


def _load():
    return [round(x, 2) for x in os.getloadavg()]


def _match_in_hosts(hosts, peer, fmu, scene, progress):
    """The peer's error (m) on ``scene`` in each host (its own default tolerance), and ours: the subject at the
    loosest rtol as accurate as the peer in our C host (at the reference's 1e-10 without a peer)."""
    progress("msl-pendulum: errors of the peer and of ours in the hosts")
    found = {"peer_error": {}}

    def ours_at(rtol):
        return c_hosts.Subject("ours", Path(fmu).resolve(), "x", scene.start_values(rtol))

    if peer is None:
        rtol, error = 1e-10, c_hosts.scene_error(hosts[0], ours_at(1e-10), scene)
    else:
        for host in hosts:
            found["peer_error"][host.name] = c_hosts.scene_error(host, peer, scene)
        target = found["peer_error"][hosts[0].name]
        rtol, error = loosest_rtol(lambda r: c_hosts.scene_error(hosts[0], ours_at(r), scene), target)
    found.update(our_rtol=rtol, our_error={hosts[0].name: error})
    for host in hosts[1:]:
        found["our_error"][host.name] = c_hosts.scene_error(host, ours_at(rtol), scene)
    return found, ours_at(rtol)


def _reference_floors(inputs):
    """The Reference-FMUs' Feedthrough and Dahlquist beside fmusim, those that are there."""
    if inputs.fmusim is None:
        return []
    folder = Path(inputs.fmusim).resolve().parent
    return [c_hosts.Subject(name.removesuffix(".fmu"), folder / name, output)
            for name, output in REFERENCE_FLOORS if (folder / name).is_file()]
