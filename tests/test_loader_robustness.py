"""Nothing a host does through the loader's fronts crashes or hangs it (issue 20, items 1-5, 7, 10 and 14), for the
FMI 2 and the FMI 3 FMU alike.

Every case runs in a child process with a time limit: ``loader_probe.py``, a plain ctypes host of the extracted
binary, or the C hosts (``stickslip.hosts.c_host``), where the loader starts Python itself. Each asserts what the
FMI standard asks for: a refused instantiation returns NULL after a message that names the value and the cause,
a refused call returns the error status with a message, and the instance goes on working afterwards.
"""

import json
import shutil
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

from stickslip.hosts.c_host import run_host

PROBE = Path(__file__).resolve().with_name("loader_probe.py")
TIMEOUT = 60  # s: a case that has not ended by then hangs
ERROR = 3  # fmi2Error, fmi3Error
STUCK = {"v_start": 0.1}  # the default block, stuck to the surface: x grows with v_drive = 0.1 m/s
PREFIX = {2: "fmi2", 3: "fmi3"}


@dataclass
class Probe:
    """What a probe printed: ``said`` (the case's lines, each a list) and ``logs`` as (status, category, text)."""

    returncode: int
    said: list
    logs: list
    stderr: str

    def __getitem__(self, key):
        """The words after the first line starting with ``key``."""
        return next(line[1:] for line in self.said if line[0] == key)

    def all(self, key):
        """The words after every line starting with ``key``."""
        return [line[1:] for line in self.said if line[0] == key]


def probe(folder, case, timeout=TIMEOUT):
    """Run the Python ``case`` in ``loader_probe.py`` on the extracted FMU ``folder``; it must end, and normally."""
    try:
        proc = subprocess.run([sys.executable, str(PROBE), str(folder)], input=textwrap.dedent(case),
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as hung:
        pytest.fail(f"the host hung ({timeout} s) in:\n{case}\nit printed: {hung.stdout}")
    lines = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("[")]
    said = [line for line in lines if line[0] != "log"]
    run = Probe(proc.returncode, said, [tuple(line[1:]) for line in lines if line[0] == "log"], proc.stderr)
    assert proc.returncode == 0 and said[-1:] == [["done"]], \
        f"the host died (exit {proc.returncode}) after {lines[-3:]}: {proc.stderr[-2000:]}"
    return run


def errors(run):
    """The texts of the error messages the host's logger received."""
    return [text for status, _, text in run.logs if status == ERROR]


@pytest.fixture(params=[2, 3], ids=["fmi2", "fmi3"])
def extracted(request):
    """(FMI version, the extracted FMU's folder) of each FMU."""
    return request.param, request.getfixturevalue("unzipped" if request.param == 2 else "unzipped3")[0]


# ---------------------------------------------------------------------------
# items 1, 2 and 5: the arguments of the instantiation
# ---------------------------------------------------------------------------

GOOD_LOCATIONS = {
    "file-three-slashes": "uri",
    "file-one-slash": "b'file:' + str(folder / 'resources').encode()",
    "file-localhost": "b'file://localhost' + str(folder / 'resources').encode()",
    "file-localhost-capitals": "b'FILE://LOCALHOST' + str(folder / 'resources').encode()",
    "escaped-letter": "uri.replace(b'/resources', b'/%72esources')",
    "plain-path": "str(folder / 'resources').encode()",
    "plain-path-with-slash": "path",
}


@pytest.mark.parametrize("location", GOOD_LOCATIONS.values(), ids=GOOD_LOCATIONS.keys())
def test_every_form_of_a_local_resource_location_instantiates(extracted, location):
    """RFC 8089 file URIs (any percent-escape decoded) and plain absolute paths, in FMI 2 as in FMI 3."""
    run = probe(extracted[1], f"""
        c = instantiate(resources={location})
        say("instantiated", c is not None)
        say("run", initialized(c, v_start=0.1), step(c, 0.0, 1.0), get(c, "x"))
    """)
    assert run["instantiated"] == [True]
    assert run["run"] == [0, 0, [0, pytest.approx(0.1)]]


def test_a_folder_with_a_non_ascii_name_and_a_space(extracted, tmp_path):
    """The FMU extracted under ``/.../jürgen x/``: its file URI (UTF-8 percent-encoded, as FMPy makes it) and its
    path both work."""
    folder = shutil.copytree(extracted[1], tmp_path / "jürgen x" / "fmu")
    run = probe(folder, """
        for location in (uri, path):
            c = instantiate(resources=location)
            say("run", location.decode(), initialized(c, v_start=0.1), step(c, 0.0, 1.0), get(c, "x"))
    """)
    assert [words[1:] for words in run.all("run")] == [[0, 0, [0, pytest.approx(0.1)]]] * 2
    assert "j%C3%BCrgen%20x" in run.all("run")[0][0]


def test_fmpy_simulates_an_fmu_extracted_under_a_non_ascii_folder(extracted, tmp_path):
    folder = shutil.copytree(extracted[1], tmp_path / "jürgen" / "fmu")
    code = (f"import fmpy; r = fmpy.simulate_fmu({str(folder)!r}, stop_time=1.0, start_values={STUCK!r}); "
            "print('x', r['x'][-1])")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-2] == "x" and float(proc.stdout.split()[-1]) == pytest.approx(0.1)


BAD_LOCATIONS = {  # the location (Python in the probe) and what the message says
    "missing-folder": ("b'file:///nonexistent/resources'", "names the folder /nonexistent/resources, which does not "
                                                           "exist"),
    "missing-path": ("b'/nonexistent/resources/'", "which does not exist"),
    "percent-in-a-path": ("str(folder / 'res%75').encode()", "res%75, which does not exist"),
    "empty": ("b''", '"" is empty'),
    "null": ("None", "the resource location is NULL"),
    "relative": ("b'resources'", "is neither a file URI (file:///path) nor an absolute path"),
    "remote-host": ("b'file://server/share/resources'", "names the host 'server': only local folders"),
    "broken-escape": ("uri + b'%4'", "has a '%' not followed by two hexadecimal digits"),
    "nul-escape": ("uri + b'%00'", "encodes a NUL byte"),
    "not-utf8": ("uri + b'%FF'", "not UTF-8 text"),
    "a-file": ("str(folder / 'modelDescription.xml').encode()", "modelDescription.xml, which is not a folder"),
    "not-the-resources": ("str(folder).encode()", "is not this FMU's resources folder: "),
}


@pytest.mark.parametrize("location, message", BAD_LOCATIONS.values(), ids=BAD_LOCATIONS.keys())
def test_a_bad_resource_location_is_null_with_a_message(extracted, location, message):
    """Item 1 (FMI 2 crashed) and item 2 (FMI 3 hung): NULL after a message naming the location and the cause;
    then a good instance works in the same process."""
    fmi, folder = extracted
    run = probe(folder, f"""
        say("instance", instantiate(resources={location}))
        say("then", initialized(instantiate(), v_start=0.1))
    """)
    assert run["instance"] == [None] and run["then"] == [0]
    [text] = errors(run)
    assert text.startswith(f"{PREFIX[fmi]}Instantiate") and message in text, text


@pytest.mark.parametrize("argument, message", [
    ("name=None", "the instance name is NULL"),
    ("token=b'0000'", 'the {token} "0000" is not this FMU\'s {token} "{guid}"'),
    ("token=None", "the {token} NULL is not this FMU's {token} \"{guid}\""),
], ids=["null-name", "wrong-token", "null-token"])
def test_a_null_name_or_a_wrong_token_is_null_with_a_message(extracted, argument, message):
    """Item 5 (a NULL name aborted the FMI 2 host) and the misuse list (a wrong GUID was accepted)."""
    fmi, folder = extracted
    run = probe(folder, f"""
        say("instance", instantiate({argument}))
        say("guid", guid.decode())
    """)
    assert run["instance"] == [None]
    token = "GUID" if fmi == 2 else "instantiation token"
    assert [message.format(token=token, guid=run["guid"][0]) in text for text in errors(run)] == [True]


def test_an_fmi2_fmu_type_the_fmu_does_not_offer_is_refused(unzipped, unzipped_coupling):
    """The block's FMU makes model-exchange instances (its model description has <ModelExchange>), the coupling FMU
    does not; an fmuType that is neither is refused by both."""
    case = 'say("me", instantiate(interface="me") is not None)\nsay("other", instantiate(interface=2))'
    block, coupling = probe(unzipped[0], case), probe(unzipped_coupling[0], case)
    assert block["me"] == [True] and block["other"] == [None] and coupling["other"] == [None]
    assert errors(block) == ["fmi2Instantiate: fmuType = 2 is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)"]
    assert coupling["me"] == [False]
    assert errors(coupling) == [f"fmi2Instantiate: this FMU offers co-simulation only (fmuType = fmi2CoSimulation, "
                                f"1), not fmuType = {code}" for code in ("0 (fmi2ModelExchange)", "2")]


def test_a_bad_resource_location_in_the_c_host_returns(extracted, request):
    """The C host, where the loader starts Python itself: the FMI 3 FMU hung there."""
    fmi, folder = extracted
    host = _host(request, fmi)
    run = run_host(host, folder, "run", 1.0, 0.5, STUCK, resources="/nonexistent/", timeout=TIMEOUT)
    assert run.returncode == 1 and run.lines == [["failed", f"{PREFIX[fmi]}Instantiate" + ("" if fmi == 2 else
                                                                                           "CoSimulation"), "NULL"]]
    assert [(status, "does not exist" in text) for status, _, text in run.logs] == [(ERROR, True)]


# ---------------------------------------------------------------------------
# item 3: log categories
# ---------------------------------------------------------------------------


def test_no_message_reaches_the_host_without_a_category(extracted):
    """A bad parameter, with logging on and off: every message has a category (OMSimulator aborts on NULL), the
    errors "logStatusError"."""
    run = probe(extracted[1], """
        for logging in (True, False):
            say("exit", initialized(instantiate(logging=logging), M=-1.0))
    """)
    assert run.all("exit") == [[ERROR], [ERROR]]
    assert all(category for _, category, _ in run.logs), run.logs
    assert {category for status, category, _ in run.logs if status == ERROR} == {"logStatusError"}
    assert len(errors(run)) == 2


# ---------------------------------------------------------------------------
# items 4 and 10: FMU states
# ---------------------------------------------------------------------------

BAD_STATES = {"empty": "b''", "random": "bytes(range(7, 250, 3))", "truncated": "serialized(c)[:40]",
              "json-list": "b'[1, 2]'", "json-without-the-keys": "b'{\"t\": 1e300}'",
              "another-fmu": "serialized(c)[:10] + bytes(4) + serialized(c)[14:]"}


@pytest.mark.parametrize("data", BAD_STATES.values(), ids=BAD_STATES.keys())
def test_deserializing_bad_bytes_is_an_error_and_the_instance_goes_on(extracted, data):
    """Item 4: the error (FMI 2 returned fatal, and its next call crashed; FMI 3 crashed at the second try), then
    the instance reads, steps, deserializes a good state and terminates normally."""
    fmi, folder = extracted
    run = probe(folder, f"""
        c = instantiate()
        initialized(c, v_start=0.1)
        good = serialized(c)
        for t in (0.0, 1.0):
            data, state = {data}, c_void_p()
            say("deserialize", call(STATE["deserialize"], c, data, len(data), byref(state)), state.value)
            say("then", get(c, "x")[0], step(c, t, 1.0))
        state = c_void_p()
        say("good", call(STATE["deserialize"], c, good, len(good), byref(state)), state.value is not None)
        say("terminate", call("{PREFIX[fmi]}Terminate", c))
    """)
    assert run.all("deserialize") == [[ERROR, None]] * 2
    assert run.all("then") == [[0, 0]] * 2
    assert run["good"] == [0, True] and run["terminate"] == [0]
    assert [text.startswith("the ") and "bytes are not a serialized FMU state of this FMU" in text
            for text in errors(run)] == [True, True]


def test_a_state_saved_during_initialization_is_refused_after_it(extracted):
    """Item 10: restoring it froze the FMI 2 instance (steps OK, x still); now an error naming the cause, and the
    instance steps on from where it was."""
    run = probe(extracted[1], """
        c, state = instantiate(), c_void_p()
        start(c, v_start=0.1)
        say("save", call(STATE["get"], c, byref(state)))
        call(f"fmi{fmi}ExitInitializationMode", c)
        step(c, 0.0, 1.0)
        say("restore", call(STATE["set"], c, state))
        say("step", step(c, 1.0, 1.0), get(c, "x"))
    """)
    assert run["save"] == [0] and run["restore"] == [ERROR]
    assert run["step"] == [0, [0, pytest.approx(0.2)]]
    assert ["saved during initialization mode and cannot be restored after initialization ended" in text
            for text in errors(run)] == [True]


# ---------------------------------------------------------------------------
# the misuse list: a communication step outside the stepping states
# ---------------------------------------------------------------------------

OUT_OF_STEP = {
    "before-initialization": ("", "before initialization"),
    "during-initialization": ("start(c)", "during initialization"),
    "after-terminate": ("initialized(c); call(f'fmi{fmi}Terminate', c)", "after termination"),
    "after-a-failed-initialization": ("initialized(c, M=-1.0)", "during initialization"),
}


@pytest.mark.parametrize("before, message", OUT_OF_STEP.values(), ids=OUT_OF_STEP.keys())
def test_a_communication_step_outside_the_stepping_state_is_an_error(extracted, before, message):
    """FMI 2 returned OK (doing nothing before initialization, stepping on after terminate); after a reset and
    a new initialization the instance steps normally."""
    fmi, folder = extracted
    run = probe(folder, f"""
        c = instantiate()
        {before}
        say("step", step(c, 0.0, 1.0))
        say("reset", call(f"fmi{{fmi}}Reset", c), initialized(c, v_start=0.1), step(c, 0.0, 1.0), get(c, "x"))
    """)
    assert run["step"] == [ERROR]
    assert run["reset"] == [0, 0, 0, [0, pytest.approx(0.1)]]
    assert any(f"{PREFIX[fmi]}DoStep at t = 0 s is not allowed {message}" in text for text in errors(run)), run.logs


def test_fmi3_a_model_exchange_instance_takes_no_communication_step(unzipped3):
    run = probe(unzipped3[0], """
        m = instantiate(interface="me")
        say("step", initialized(m), step(m, 0.0, 1.0))
    """)
    assert run["step"] == [0, ERROR]
    assert errors(run) == ["fmi3DoStep at t = 0 s is not allowed for a model-exchange instance"]


# ---------------------------------------------------------------------------
# item 14: a host thread per call
# ---------------------------------------------------------------------------


def _host(request, fmi):
    """The session's C host of FMI version ``fmi`` (conftest: skipped, naming the need, where it cannot be built)."""
    return request.getfixturevalue("host" if fmi == 2 else "host3")


def _growth_kb(run):
    """The resident memory (kB) a host run gained from its "rss_kb_warm" line to its "rss_kb_end" line; the run must
    have completed."""
    assert run.completed, (run.returncode, run.lines[-3:], run.stderr[-2000:])
    return int(run.value("rss_kb_end")[0]) - int(run.value("rss_kb_warm")[0])


def test_a_new_thread_per_step_keeps_memory_flat(extracted, request):
    """Each host thread's Python thread state is deleted when the thread ends: 2,000 steps, each from a new thread,
    grew the process by 8.5 MB (4.4 kB per thread; 50,000: 22 -> 240 MB); now by less than 1 MB."""
    fmi, folder = extracted
    host = _host(request, fmi)
    run = run_host(host, folder, "thread_steps", 20.0, 0.01, STUCK, timeout=TIMEOUT)
    growth = _growth_kb(run)
    assert run.value("steps") == ["2000"]
    alone = run_host(host, folder, "run", 20.0, 0.01, STUCK, timeout=TIMEOUT)
    assert alone.completed, (alone.returncode, alone.stderr[-2000:])
    _, x = alone.series("x")
    assert run.series("x") == ([20.0], x[-1:])  # the same run as from one thread
    assert growth < 1024, f"{growth} kB more after 1,900 steps from new threads"


#: FMU: (the session's fixture of it extracted, start values, the output the host reads, its value after a run)
CYCLED = {"block": ("unzipped", STUCK, "x", 0.03), "coupling": ("unzipped_coupling", {"kc_left": 2.0, "x_left": 0.5},
                                                                 "F", 1.0)}
#: how many instances one host process makes and frees, each count in a process of its own: the growth is linear in
#: them where instances leak, whereas caches level off
CYCLES = (3000, 10000)
LEAK_PER_INSTANCE = 0.1  # kB; before the loader kept freed instances for reuse, 1.44-1.50 (block), and PythonFMU's
#: instantiation leaked 17 Python objects each time; the coupling FMU once leaked 25 kB per instance


@pytest.mark.parametrize("cycles", CYCLES)
@pytest.mark.parametrize("fmu", CYCLED)
def test_instances_made_and_freed_keep_memory_flat(fmu, cycles, host, request):
    """Instantiate, initialize, step, terminate and free, thousands of times in a C host: the memory from a tenth of
    the cycles to the end grows by less than LEAK_PER_INSTANCE per instance (the coupling FMU grew the process by 25
    kB per instance, 21.7 -> 122 MB over 4,000: PythonFMU ran the slave's source again at each instantiation and
    kept each new copy of its class; the block by 1.47 kB)."""
    fixture, start, output, value = CYCLED[fmu]
    run = run_host(host, request.getfixturevalue(fixture)[0], "cycles", 0.3, 0.1, start, output=output,
                   env={"HOST_CYCLES": str(cycles)}, timeout=TIMEOUT)
    growth = _growth_kb(run)
    ends = [float(line[3]) for line in run.lines if line[0] == "c"]
    assert ends == [pytest.approx(value, rel=1e-12)] * cycles
    per_instance = growth / (cycles - cycles // 10)
    assert per_instance < LEAK_PER_INSTANCE, f"{per_instance:.3f} kB more per instance ({growth} kB in all)"


def test_a_new_thread_per_step_of_the_coupling_fmu_keeps_memory_flat(unzipped_coupling, host):
    """The coupling FMU's loader deletes the thread states of the host threads that called it, as the block's."""
    run = run_host(host, unzipped_coupling[0], "thread_steps", 20.0, 0.01, {"kc_left": 2.0, "x_left": 0.5},
                   output="F", timeout=TIMEOUT)
    growth = _growth_kb(run)
    assert run.value("steps") == ["2000"] and run.value("x") == ["20", "1"]
    assert growth < 1024, f"{growth} kB more after 1,900 steps from new threads"
