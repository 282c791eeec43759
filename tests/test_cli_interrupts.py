"""Ctrl-C in the commands: ``stickslip run`` and ``stickslip system run`` stop within seconds, print one line (no
traceback), exit with 130 and leave no report of another run, also while a command still loads its modules; a
SIGINT that lands inside an FMI call is an interrupt, never the FMU's error. Each command runs in a child process
that gets SIGINT as a terminal's Ctrl-C sends it (to the process group) or as ``kill -INT`` does (to the process
alone)."""

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from fmpy.fmi1 import FMICallException

from stickslip.hosts import interrupts
from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError
from stickslip.hosts.progress import TimeProgress

from cli_child import STICKSLIP

ROOT = Path(__file__).resolve().parents[1]
#: seconds from SIGINT to the command's exit that the test allows (a second or two, on a loaded machine)
EXIT_WITHIN = 5.0


def start(args):
    """The command ``stickslip args`` started in its own process group."""
    return subprocess.Popen([*STICKSLIP, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def wait_for(condition, proc, seconds=240):
    """Wait until ``condition()`` holds (False if the process ended or time ran out first)."""
    deadline = time.monotonic() + seconds
    while not condition():
        if proc.poll() is not None or time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def interrupt(proc, to_group):
    """Send SIGINT; ``(seconds to the exit, stdout, stderr)``."""
    sent = time.monotonic()
    if to_group:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    try:
        stdout, stderr = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise
    return time.monotonic() - sent, stdout, stderr


def one_line(stderr, command):
    """The command's own lines on stderr (progress bars aside): exactly one, no traceback."""
    assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if line.startswith(f"stickslip {command}")]
    assert len(lines) == 1, stderr
    return lines[0]


@pytest.mark.parametrize("to_group", [True, False], ids=["ctrl-c", "kill-int"])
def test_ctrl_c_stops_the_suite_and_its_workers(tmp_path, fmu_path, to_group):
    """During ``run scenarios/ --jobs 2``: exit 130 within seconds, one line saying how far it got, the previous
    run's report gone, and no worker writes another scenario's files after the exit."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("a previous run's report")
    proc = start(["run", str(ROOT / "scenarios"), "--jobs", "2", "--out", str(out), "--fmu", str(fmu_path)])
    assert wait_for(lambda: any(out.glob("*.csv")), proc), proc.communicate()
    took, _, stderr = interrupt(proc, to_group)
    assert proc.returncode == 130, stderr
    assert took <= EXIT_WITHIN
    line = one_line(stderr, "run")
    scenarios = len(list((ROOT / "scenarios").glob("*.toml")))
    assert line.startswith("stickslip run: interrupted (")
    assert f"of {scenarios} scenarios finished, no report written)" in line
    assert not (out / "report.md").exists()
    written = sorted(out.iterdir())
    time.sleep(2.0)
    assert sorted(out.iterdir()) == written and len(list(out.glob("*.csv"))) < 20


@pytest.mark.parametrize("master, to_group", [("zoh", True), ("adaptive", True), ("adaptive", False),
                                               ("me", True), ("me", False)])
def test_ctrl_c_stops_a_system_run(tmp_path, fmu_path, fmu3_path, master, to_group):
    """During the master's run of the 10-block chain: exit 130 within seconds, one line, the previous report
    removed when the run started and no new one."""
    report = tmp_path / f"bk10-velocity-weakening-{master}.md"
    report.write_text("a previous run's report")
    proc = start(["system", "run", str(ROOT / "systems" / "bk10-velocity-weakening.toml"), "--master", master,
                  "--out", str(tmp_path), "--fmu", str(fmu3_path if master == "me" else fmu_path)])
    assert wait_for(lambda: not report.exists(), proc), proc.communicate()
    time.sleep(1.5)  # into the master's stepping
    assert proc.poll() is None
    took, _, stderr = interrupt(proc, to_group)
    assert proc.returncode == 130, stderr
    assert took <= EXIT_WITHIN
    assert one_line(stderr, "system") == "stickslip system: interrupted"
    assert not report.exists() and not (tmp_path / f"bk10-velocity-weakening-{master}.csv").exists()


def _interrupted_inside(instance):
    """An FMI call whose library catches the KeyboardInterrupt that a SIGINT raises inside it and reports the call
    as failed, as PythonFMU does ("[doStep] KeyboardInterrupt()" with fmi2Error)."""
    def do_step():
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass
        raise FMICallException("fmi2DoStep", 3)
    return instance.call(do_step)


def test_an_interrupt_inside_an_fmi_call_is_not_the_fmus_error(fmu_path):
    """Within the command line's SIGINT counting, a call that failed while a SIGINT arrived raises
    KeyboardInterrupt; a call that fails without one is the FMU's error, as before."""
    with ExtractedFMU(fmu_path) as fmu, fmu.new_instance() as instance:
        with interrupts.counting():
            with pytest.raises(KeyboardInterrupt):
                _interrupted_inside(instance)
        with interrupts.counting():
            with pytest.raises(FmuCallError, match="fmi2DoStep failed with status 3"):
                instance.call(lambda: (_ for _ in ()).throw(FMICallException("fmi2DoStep", 3)))
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def _swallowed_interrupt():
    """A SIGINT whose KeyboardInterrupt a library swallows where it is raised (a bare ``except``; a compiled module's
    initialisation that it breaks, taken for a missing module, as FMPy's import of lxml can)."""
    try:
        signal.raise_signal(signal.SIGINT)
    except KeyboardInterrupt:
        pass


def test_a_swallowed_interrupt_ends_the_command_at_the_next_call_or_progress_step(fmu_path):
    """Within the command line's SIGINT counting, a Ctrl-C that a library swallowed raises KeyboardInterrupt at the
    next FMI call and at the next step of a progress bar; a new counting starts clean."""
    with ExtractedFMU(fmu_path) as fmu, fmu.new_instance() as instance:
        with interrupts.counting():
            _swallowed_interrupt()
            with pytest.raises(KeyboardInterrupt):
                instance.call(instance.fmu.getReal, [0])
            with pytest.raises(KeyboardInterrupt), TimeProgress("run", 1.0, shown=False) as step:
                step(0.5)
        with interrupts.counting():
            instance.call(instance.fmu.getReal, [0])


#: the console script ``stickslip`` that installing the package made beside this Python
CONSOLE_SCRIPT = shutil.which("stickslip", path=str(Path(sys.executable).parent))
#: the modules the console script imports before its ``main`` runs: the package and the command line's entry point
ENTRY_MODULES = {"stickslip", "stickslip.cli"}
#: seconds after a command began loading its own modules at which the early-interrupt test sends SIGINT
EARLY_DELAYS = (0.0, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0)


def test_the_entry_point_imports_nothing_else():
    """The console script's imports before ``main`` runs, which no Ctrl-C handling can cover, load the package and
    the entry point alone: every other module of the command loads inside ``main``."""
    code = ("import sys; before = set(sys.modules); import stickslip.cli; "
            "print(sorted(set(sys.modules) - before))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert done.stdout.strip() == repr(sorted(ENTRY_MODULES)), done.stdout


def _main_with_dispatch(dispatch_body, argv):
    """``(exit code, stderr)`` of the command line's ``main(argv)`` in a child Python whose command dispatch is the
    function body ``dispatch_body`` (source lines, indented by four spaces)."""
    code = ("import signal, sys; import stickslip.cli.commands as c\n"
            f"def dispatch(argv):\n{dispatch_body}\n"
            "c.dispatch = dispatch\n"
            f"from stickslip.cli import main; sys.exit(main({argv!r}))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    return done.returncode, done.stderr


def test_ctrl_c_that_breaks_a_compiled_modules_loading_is_an_interrupt():
    """Ctrl-C inside a compiled module's initialisation reaches the command as that module's ImportError, caused by
    the KeyboardInterrupt (Matplotlib's ft2font did so): the one line and exit code 130, and no crash in Python's
    finalization, which such a half-made module can cause."""
    code, stderr = _main_with_dispatch("    try:\n        raise KeyboardInterrupt\n"
                                       "    except KeyboardInterrupt as exc:\n"
                                       "        raise ImportError('initialization failed') from exc",
                                       ["system", "run", "x"])
    assert code == 130, stderr
    assert one_line(stderr, "system") == "stickslip system: interrupted"


def _module_loads(proc, lines):
    """Put ``(time, line)`` of each line of the child's stderr into the queue ``lines``, then ``None``."""
    for line in proc.stderr:
        lines.put((time.monotonic(), line))
    lines.put(None)


def _interrupted_while_loading(args, delay, after=None):
    """``stickslip args`` run by the console script with Python's import timing on (a line on stderr per module
    loaded), SIGINT sent to its process group ``delay`` s after the module ``after`` (default: its first module
    beyond :data:`ENTRY_MODULES`) loaded; ``(exit code, stderr without the timing lines)``."""
    proc = subprocess.Popen([CONSOLE_SCRIPT, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env={**os.environ, "PYTHONPROFILEIMPORTTIME": "1"})
    lines = queue.Queue()
    threading.Thread(target=_module_loads, args=(proc, lines), daemon=True).start()
    stderr = []
    try:
        while (item := lines.get(timeout=60)) is not None:
            stderr.append(item[1])
            name = item[1].rpartition("|")[2].strip()
            if name == after or after is None and name.startswith("stickslip.") and name not in ENTRY_MODULES:
                time.sleep(max(0.0, item[0] + delay - time.monotonic()))
                break
        assert proc.poll() is None, f"{args} ended before the signal: {''.join(stderr)}"
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    while (item := lines.get(timeout=60)) is not None:
        stderr.append(item[1])
    return proc.returncode, "".join(line for line in stderr if not line.startswith("import time:"))


@pytest.mark.parametrize("delay", EARLY_DELAYS)
@pytest.mark.parametrize("command", ["bifurcation", "system"])
def test_ctrl_c_while_a_command_loads_its_modules(tmp_path, request, command, delay):
    """From the moment a command loads its first module (NumPy, SciPy, FMPy, Matplotlib and the package's own
    still to come) to its work a second later, Ctrl-C ends it with one line and exit code 130, three times in a
    row at each delay."""
    if command == "bifurcation":
        args = ["bifurcation", "--preset", "elmer-fig3", "--jobs", "1", "--out", str(tmp_path)]
    else:
        args = ["system", "run", str(ROOT / "systems" / "bk10-velocity-weakening.toml"), "--master", "me",
                "--out", str(tmp_path), "--fmu", str(request.getfixturevalue("fmu3_path"))]
    for _ in range(3):
        code, stderr = _interrupted_while_loading(args, delay)
        assert code == 130, stderr
        assert one_line(stderr, command) == f"stickslip {command}: interrupted"


def test_ctrl_c_that_a_compiled_modules_initialisation_swallows_still_ends_the_command(tmp_path, fmu3_path):
    """A SIGINT 1 ms after the package lxml loaded lands in the initialisation of lxml.etree, whose KeyboardInterrupt
    never reaches the command (the run went on to its end with exit code 0): the next FMI call or progress step ends
    it with one line and exit code 130, three times in a row."""
    args = ["system", "run", str(ROOT / "systems" / "bk10-velocity-weakening.toml"), "--master", "me",
            "--out", str(tmp_path), "--fmu", str(fmu3_path)]
    for _ in range(3):
        code, stderr = _interrupted_while_loading(args, 0.001, after="lxml")
        assert code == 130, stderr
        assert one_line(stderr, "system") == "stickslip system: interrupted"


def test_a_command_that_ends_after_a_swallowed_interrupt_exits_130():
    """A Ctrl-C swallowed where it was raised, in a command that makes no FMI call or progress step after it, still
    ends the command with one line and exit code 130, not 0."""
    code, stderr = _main_with_dispatch("    try:\n        signal.raise_signal(signal.SIGINT)\n"
                                       "    except KeyboardInterrupt:\n        pass\n    return 0", ["bifurcation"])
    assert code == 130, stderr
    assert one_line(stderr, "bifurcation") == "stickslip bifurcation: interrupted"
