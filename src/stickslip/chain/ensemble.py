"""Ensembles of chains: many seeds of one template, or one template parameter swept over a list of values.

Each member is a chain of :func:`~.template.chain_system` (its own seed and values) run by the chain engine into its
own folder ``<out>/<label>/`` (``block_events.csv``, ``slip_events.csv``, ``positions.csv`` where an output interval
is given, and ``member.json``, written last: a folder without it holds an unfinished member). Members run in
parallel through :class:`stickslip.analysis.parallel_scan.Executor`: a local process pool (one worker per core by
default) or a Dask cluster (its workers must see ``<out>``: a local cluster, or a shared file system). A member's
numbers depend only on its seed and values, never on where it ran, so the ensemble is the same bit for bit
serially, on the pool or on Dask.

The ensemble's own files: ``members.csv`` (``member,label,seed,<swept parameter>,slip_events,block_events``),
``slip_events.csv`` (every finished member's catalogue, in member order, with a first column ``member``) and the
combined statistics (:func:`combine_statistics`).
"""

import contextlib
import json
import math
import multiprocessing
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..hosts.interrupts import Interrupted, check as check_interrupts
from .statistics import STATISTICS_JSON

#: a worker's exit status after Ctrl-C (128 + SIGINT)
INTERRUPTED = 130
#: the file a member writes last: its folder holds a finished member
MEMBER_FILE = "member.json"
ENSEMBLE_JSON = "ensemble.json"
ENSEMBLE_MD = "ensemble.md"
EXPONENTS_PNG = "exponents.png"
#: the template's values a sweep may change, besides ``kinetic.<parameter>`` and ``static.<parameter>``
SWEEPABLE = ("M", "kappa", "kc", "v_drive", "x_start", "offset_spread")


class EnsembleError(ValueError):
    """Bad ensemble input (seeds, sweep, workers); the message names the option and what is allowed."""


@dataclass(frozen=True)
class Member:
    """One chain of an ensemble: ``index`` (0-based, its place in the merged catalogue), ``seed`` of its start
    offsets, ``values`` (keyword arguments of :func:`~.template.chain_system`, the swept value included) and
    ``label`` (its folder's name, e.g. ``seed3`` or ``kc=4.5-seed3``)."""

    index: int
    seed: int
    values: dict
    label: str
    swept: tuple = ()


@dataclass
class EnsembleRun:
    """What :func:`run_ensemble` did: the ensemble's folder, its members, the labels of those that finished, and
    the files it wrote (merged catalogue, statistics)."""

    out: Path
    members: list
    finished: list = field(default_factory=list)
    files: dict = field(default_factory=dict)
    wall_time: float = 0.0


def parse_seeds(text):
    """The seeds of ``--seeds``: ``"0-9"`` (both ends included), ``"0,1,2"`` or a mix (``"0-4,10"``), each a whole
    number >= 0, none twice."""
    seeds = []
    for part in str(text).split(","):
        low, dash, high = part.strip().partition("-")
        try:
            first = int(low)
            last = int(high) if dash else first
        except ValueError:
            raise EnsembleError(f"--seeds {text!r}: allowed is a list of whole numbers >= 0 and ranges, "
                                f"e.g. 0-9 or 0,1,2") from None
        if first < 0 or last < first:
            raise EnsembleError(f"--seeds {text!r}: the range {part.strip()!r} must run from a seed >= 0 upwards")
        seeds.extend(range(first, last + 1))
    if len(set(seeds)) != len(seeds):
        raise EnsembleError(f"--seeds {text!r}: a seed is given twice")
    return seeds


def parse_sweep(text):
    """``(name, values)`` of ``--sweep NAME=V1,V2,...``: a template value of :data:`SWEEPABLE`,
    ``kinetic.<parameter>`` or ``static.<parameter>``, and finite numbers, none twice."""
    name, equals, values = str(text).partition("=")
    name = name.strip()
    if not equals or not (name in SWEEPABLE or name.split(".")[0] in ("kinetic", "static") and "." in name):
        raise EnsembleError(f"--sweep {text!r}: allowed is NAME=V1,V2,... with NAME one of {', '.join(SWEEPABLE)}, "
                            f"kinetic.<parameter> or static.<parameter>")
    try:
        numbers = [float(v) for v in values.split(",")]
    except ValueError:
        numbers = [math.nan]
    if not all(math.isfinite(v) for v in numbers) or len(set(numbers)) != len(numbers):
        raise EnsembleError(f"--sweep {text!r}: the values of {name} must be distinct finite numbers, "
                            f"comma-separated")
    return name, numbers


def ensemble_members(values, seeds, sweep=None):
    """The members of an ensemble of the template ``values`` (keyword arguments of :func:`~.template.chain_system`
    but the seed): every seed of ``seeds``, for every value of ``sweep = (name, values)`` if given (the sweep's
    values outermost)."""
    if not seeds:
        raise EnsembleError("--seeds: an ensemble needs at least one seed")
    name, sweep_values = sweep if sweep else (None, [None])
    members = []
    for value in sweep_values:
        for seed in seeds:
            label = f"seed{seed}" if name is None else f"{name}={value!r}-seed{seed}"
            given = dict(values) if name is None else with_template_value(values, name, value)
            swept = () if name is None else ((name, value),)
            members.append(Member(len(members), int(seed), given, label, swept))
    return members


def with_template_value(values, name, value):
    """A copy of the template ``values`` with ``name`` (:func:`parse_sweep`) set to ``value``: ``kinetic.<p>`` and
    ``static.<p>`` go into that law's table (the Burridge-Knopoff law where ``values`` gives none)."""
    from .template import BK_KINETIC, BK_STATIC

    out = dict(values)
    kind, _, parameter = name.partition(".")
    if parameter:
        law = out.get(kind) or (BK_KINETIC if kind == "kinetic" else BK_STATIC)
        out[kind] = {**law, parameter: value}
    else:
        out[name] = value
    return out


def default_workers():
    """One worker per core of this machine."""
    return max(1, os.cpu_count() or 1)


def run_ensemble(n, members, stop_time, out, *, rtol=1e-10, output_interval=None, workers=None, dask=None,
                 progress=True):
    """Run the ``members`` (:func:`ensemble_members`) as chains of ``n`` blocks over ``stop_time`` (s) at the
    engine's ``rtol`` into ``out/<label>/``, then merge their catalogues and combine their statistics into ``out``.

    ``workers``: local worker processes (default :func:`default_workers`; 1: in this process); ``dask``: the
    address of a Dask scheduler, ``"local"`` (a local Dask cluster of ``workers`` processes), or a Dask cluster or
    client object, instead of local processes. On Ctrl-C the
    finished members stay with their files and the merged catalogue holds them; KeyboardInterrupt then says how
    many finished and where."""
    from ..analysis.parallel_scan import Executor

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise EnsembleError(f"--workers {workers}: allowed is a whole number >= 1")
    run = EnsembleRun(out, list(members))
    tasks = [(n, m, float(stop_time), rtol, output_interval, str(out / m.label)) for m in run.members]
    for m in run.members:  # a member of an earlier run in the same folder is not taken for one of this run
        (out / m.label / MEMBER_FILE).unlink(missing_ok=True)
    start = time.perf_counter()
    try:
        with dask_scheduler(dask, workers) as scheduler, \
                Executor(jobs=min(workers, len(tasks)), scheduler=scheduler, progress=progress) as executor:
            executor.map(run_member, tasks, desc=f"{len(tasks)} chains", unit="chain")
    except KeyboardInterrupt:
        finish_ensemble(run, time.perf_counter() - start)
        raise Interrupted(f"{len(run.finished)} of {len(run.members)} chains finished, their files and the "
                                f"merged catalogue in {out}; the others hold what they wrote") from None
    return finish_ensemble(run, time.perf_counter() - start)


@contextlib.contextmanager
def dask_scheduler(dask, workers):
    """``dask`` as the executor's scheduler: ``"local"`` becomes a local Dask cluster of ``workers`` single-threaded
    processes, closed at the end; anything else (None, an address, a cluster or client) is passed on."""
    if dask != "local":
        yield dask
        return
    from distributed import LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=None) as cluster:
        yield cluster


def run_member(n, member, stop_time, rtol, output_interval, folder):
    """Run one member into ``folder`` as ``stickslip chain`` would (:func:`~.folder_run.run_into_folder`, then its
    statistics and figures), then write :data:`MEMBER_FILE` (what it ran and counted). Returns that record."""
    from .folder_run import run_into_folder, summarise_folder
    from .template import chain_system

    _quiet_interrupts_in_workers()
    check_interrupts()  # run in this process: a Ctrl-C swallowed during the member before ends the run here
    system = chain_system(n, seed=member.seed, name=member.label, stop_time=stop_time, output_interval=stop_time,
                          **member.values)
    run = run_into_folder(system, folder, stop_time=stop_time, output_interval=output_interval, rtol=rtol)
    record = {"member": member.index, "label": member.label, "seed": member.seed, "n": n,
              "swept": dict(member.swept), "values": member.values, "stop_time": stop_time, "rtol": rtol,
              "block_events": run.grouper.n_block_events, "slip_events": run.slip_events,
              "open_event": run.grouper.open_event and run.grouper.open_event.summary(),
              "wall_time": run.summary.wall_time}
    summarise_folder(folder, system, member.label, record)
    (Path(folder) / MEMBER_FILE).write_text(json.dumps(record, indent=1) + "\n")
    return record


def _quiet_interrupts_in_workers():
    """In a worker process of the local pool, Ctrl-C (SIGINT to the whole process group) ends the worker at once and
    quietly: what its member wrote is flushed already, and the main process says what finished. Elsewhere (this
    process, Dask's worker threads) nothing changes."""
    if multiprocessing.parent_process() is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, lambda *_: os._exit(INTERRUPTED))


def finished_records(run):
    """The records (:data:`MEMBER_FILE`) of the members of ``run`` that finished, in member order."""
    records = []
    for m in run.members:
        path = run.out / m.label / MEMBER_FILE
        if path.exists():
            records.append(json.loads(path.read_text()))
    return records


def finish_ensemble(run, wall_time):
    """Merge the finished members' files and combine their statistics into ``run.out``; fill ``run``."""
    records = finished_records(run)
    run.finished = [r["label"] for r in records]
    run.wall_time = wall_time
    run.files["members"] = write_members(run.out / "members.csv", run.members, records)
    run.files["slip_events"] = merge_catalogues(run.out / "slip_events.csv", [run.out / r["label"] for r in records],
                                                [r["member"] for r in records])
    if records:
        run.files.update(combine_statistics(run.out, records))
    return run


def write_members(path, members, records):
    """``members.csv``: ``member,label,seed``, the swept parameter if any, and the counts of the finished ones
    (empty for the others)."""
    done = {r["member"]: r for r in records}
    swept = [name for name, _ in members[0].swept] if members else []
    lines = [",".join(["member", "label", "seed", *swept, "block_events", "slip_events"])]
    for m in members:
        r = done.get(m.index, {})
        lines.append(",".join([str(m.index), m.label, str(m.seed), *(repr(v) for _, v in m.swept),
                               str(r.get("block_events", "")), str(r.get("slip_events", ""))]))
    path.write_text("\n".join(lines) + "\n")
    return path


def merge_catalogues(path, folders, indices):
    """Write ``path``: the ``slip_events.csv`` of each folder, in the given order, each row led by its member's
    index (a first column ``member``); the rows are copied as text, line by line (memory: one line)."""
    from .catalogue import SLIP_EVENT_COLUMNS, SLIP_EVENTS_FILE

    with Path(path).open("w") as merged:
        merged.write(",".join(["member", *SLIP_EVENT_COLUMNS]) + "\n")
        for folder, index in zip(folders, indices):
            with (Path(folder) / SLIP_EVENTS_FILE).open() as rows:
                next(rows, None)
                for line in rows:
                    merged.write(f"{index},{line}")
    return path


def member_groups(records):
    """The finished members' records grouped by their swept value (one group without a sweep), in member order:
    ``[(swept dict, [records])]``."""
    groups = {}
    for r in records:
        groups.setdefault(tuple(r["swept"].items()), []).append(r)
    return [(dict(key), members) for key, members in groups.items()]


def combine_statistics(out, records, bootstrap=200):
    """The statistics of each group of members (:func:`member_groups`): the pooled catalogue's
    (:func:`~.statistics.catalogue_statistics`: one fitted exponent of sizes and of moments with its uncertainty),
    and the spread of the members' own exponents; written as ``ensemble.json``, ``ensemble.md``, a figure of the
    pooled distributions per group (``pooled[-<swept>].png``) and ``exponents.png``. Returns ``{kind: path}``."""
    from .catalogue import SLIP_EVENTS_FILE, read_slip_events
    from .plots import plot_statistics
    from .statistics import catalogue_statistics

    out, files, groups = Path(out), {}, []
    for swept, members in member_groups(records):
        tables = [read_slip_events(out / r["label"] / SLIP_EVENTS_FILE) for r in members]
        pooled = {name: np.concatenate([t[name] for t in tables]) for name in tables[0]}
        n = members[0]["n"]
        statistics = catalogue_statistics(pooled, n, bootstrap=bootstrap)
        own = [json.loads((out / r["label"] / STATISTICS_JSON).read_text()) for r in members]
        name = "pooled" + "".join(f"-{k}={v!r}" for k, v in swept.items())
        plot_statistics(out / f"{name}.png", f"{len(members)} chains{_swept_text(swept)} pooled", pooled, statistics)
        files[name] = out / f"{name}.png"
        groups.append({"swept": swept, "members": [r["label"] for r in members], "pooled": statistics,
                       "spread": {key: exponent_spread([o[f"{key}_fit"] for o in own]) for key in ("size", "moment")}})
    files["json"] = out / ENSEMBLE_JSON
    files["json"].write_text(json.dumps({"groups": groups}, indent=2) + "\n")
    files["md"] = out / ENSEMBLE_MD
    files["md"].write_text(ensemble_markdown(groups))
    files["exponents"] = plot_exponents(out / EXPONENTS_PNG, groups)
    return files


def exponent_spread(fits):
    """``{"count", "mean", "std", "min", "max", "alphas"}`` of the fitted exponents among ``fits`` (members whose
    catalogue had too few events for a fit are left out: ``count`` says how many were fitted)."""
    alphas = [f["alpha"] for f in fits if "alpha" in f]
    if not alphas:
        return {"count": 0, "mean": None, "std": None, "min": None, "max": None, "alphas": []}
    return {"count": len(alphas), "mean": float(np.mean(alphas)),
            "std": float(np.std(alphas, ddof=1)) if len(alphas) > 1 else None,
            "min": float(min(alphas)), "max": float(max(alphas)), "alphas": alphas}


def _swept_text(swept):
    return "".join(f", {k} = {v:g}" for k, v in swept.items())


def ensemble_markdown(groups):
    """The combined statistics as a short markdown report: per group the pooled fits and the members' spread."""
    lines = ["# Ensemble statistics", ""]
    for g in groups:
        pooled = g["pooled"]
        lines += [f"## {len(g['members'])} chains{_swept_text(g['swept'])}", "",
                  f"{pooled['events']} slip events pooled ({pooled['spanning_events']} span the chain).", ""]
        for key, unit in (("size", "blocks"), ("moment", "m, of |moment|")):
            fit, spread = pooled[f"{key}_fit"], g["spread"][key]
            if "alpha" in fit:
                text = (f"alpha = {fit['alpha']:.3f} +- {fit['standard_error']:.3f} (maximum likelihood) above "
                        f"x_min = {fit['x_min']:.4g} ({fit['n_tail']} of {fit['n']} events)")
            else:
                text = f"no power law fitted ({fit['not_fitted']})"
            if spread["count"]:
                text += (f"; the members' own: mean {spread['mean']:.3f}, std {_number(spread['std'])}, "
                         f"from {spread['min']:.3f} to {spread['max']:.3f} ({spread['count']} fitted)")
            lines.append(f"- {key} ({unit}): pooled {text}")
        lines.append("")
    return "\n".join(lines)


def _number(value):
    return "n/a" if value is None else f"{value:.3f}"


def plot_exponents(path, groups):
    """``path``: the fitted exponents of sizes and moments of each chain (dots) and of the pooled catalogue with its
    standard error: over the swept value (a bar per value), or without a sweep over the chains (a band)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    name = next(iter(groups[0]["swept"]), None)
    for ax, key in zip(fig.subplots(1, 2), ("size", "moment")):
        for g in groups:
            alphas, fit = g["spread"][key]["alphas"], g["pooled"][f"{key}_fit"]
            if name is None:
                ax.plot(range(1, len(alphas) + 1), alphas, "o", color="C0", label="each chain")
                if "alpha" in fit:
                    low, high = fit["alpha"] - fit["standard_error"], fit["alpha"] + fit["standard_error"]
                    ax.axhspan(low, high, color="C3", alpha=0.2, label="pooled (standard error)")
                    ax.axhline(fit["alpha"], color="C3")
                continue
            ax.plot([g["swept"][name]] * len(alphas), alphas, ".", color="C0", alpha=0.6)
            if "alpha" in fit:
                ax.errorbar([g["swept"][name]], [fit["alpha"]], yerr=[fit["standard_error"]], fmt="s", color="C3",
                            capsize=4)
        if name is not None:
            ax.plot([], [], ".", color="C0", label="each chain")
            ax.errorbar([], [], yerr=[], fmt="s", color="C3", label="pooled (standard error)")
        ax.set(xlabel=name or "chain (those with a fit)", ylabel=f"exponent alpha of {key}",
               title=f"{key} distribution")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    fig.savefig(path, dpi=100)
    return path
