"""What a user reads carries no project-internal words: no issue numbers in the help texts of ``stickslip``
and its subcommands, nor in the package's strings (messages, docstrings shown by ``help()``), the docs a user
reads, or the scenario and system files."""

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

from cli_child import STICKSLIP

ROOT = Path(__file__).resolve().parents[1]
INTERNAL = re.compile(r"\bissue \d+", re.IGNORECASE)
#: developers' notes, not user documentation: they cite the issues that found each planted bug
DEVELOPER_DOCS = {"planted-bugs.md"}


def _help(*args):
    done = subprocess.run([*STICKSLIP, *args, "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _subcommands():
    """The subcommand names listed by ``stickslip --help`` (indented four spaces under ``COMMAND``)."""
    names = re.findall(r"^ {4}([a-z][\w-]*)", _help(), re.MULTILINE)
    assert len(names) > 5, "stickslip --help lists no subcommands"
    return names


def test_help_texts_name_no_issue():
    texts = {"stickslip": _help()}
    for name in _subcommands():
        texts[name] = _help(name)
    leaks = {name: INTERNAL.findall(text) for name, text in texts.items() if INTERNAL.search(text)}
    assert not leaks


def _strings(path):
    """Every string constant of the Python module at ``path`` (messages, help texts, docstrings)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    return [node.value for node in ast.walk(tree) if isinstance(node, ast.Constant) and isinstance(node.value, str)]


def test_package_strings_and_user_docs_name_no_issue():
    found = []
    for path in sorted((ROOT / "src" / "stickslip").rglob("*.py")):
        found += [f"{path.relative_to(ROOT)}: {m}" for s in _strings(path) for m in INTERNAL.findall(s)]
    readable = [*(ROOT / "docs").glob("*.md"), *(ROOT / "scenarios").glob("*.toml"), *(ROOT / "systems").glob("*.toml")]
    for path in sorted(readable):
        if path.name not in DEVELOPER_DOCS:
            found += [f"{path.relative_to(ROOT)}: {m}" for m in INTERNAL.findall(path.read_text())]
    assert not found


#: in a fresh Python: ``--help`` of ``stickslip`` and of every command and nested command, each exiting 0; then
#: prints the commands seen and which numerical modules got imported
HELP_CHILD = r"""
import argparse, contextlib, io, json, sys
from stickslip.cli import main
from stickslip.cli.commands import build_parser

def commands(parser, prefix=()):
    yield prefix
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from commands(sub, (*prefix, name))

seen = []
for argv in commands(build_parser()):
    with contextlib.redirect_stdout(io.StringIO()) as out:
        try:
            main([*argv, "--help"])
        except SystemExit as exc:
            assert exc.code == 0 and "usage:" in out.getvalue(), (argv, exc.code)
    seen.append(" ".join(argv))
print(json.dumps({"commands": seen, "heavy": sorted(m for m in sys.modules
                                                  if m.split(".")[0] in ("numpy", "scipy", "fmpy", "matplotlib"))}))
"""


def test_help_imports_no_numerical_module():
    """``--help`` answers at once: building and printing every parser loads none of NumPy, SciPy, FMPy and
    Matplotlib (the handlers import them when a command runs)."""
    done = subprocess.run([sys.executable, "-c", HELP_CHILD], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout.splitlines()[-1])
    assert {"", "run", "map", "bifurcation", "bench-versus", "bench-systems", "system run", "system ssp"} <= set(
        found["commands"])
    assert found["heavy"] == []
