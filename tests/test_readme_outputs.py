"""What the documents say about the commands holds: every folder the documented commands write by default or by
their --out is ignored by git (issues 11, 18); every command they show exists with the options shown, and the
README's commands run as written, in order (issue 30)."""

import argparse
import contextlib
import io
import re
import shlex

import pytest

from test_docs import DOCUMENTS, FENCE, INLINE_CODE, REPO, SHELL_BLOCK, _label, command_parsers, ignored_folders


def _default_outs():
    """``{command: its default --out folder}`` of the commands that have one."""
    defaults = {name: parser.get_default("out") for name, parser in command_parsers().items()}
    return {name: out for name, out in defaults.items() if out}


def test_default_output_folders_are_ignored():
    outs = _default_outs()
    assert {"run", "bench", "bifurcation", "vc", "map", "slow-manifold", "chart"} <= set(outs)
    missing = {name: out for name, out in outs.items() if out.strip("/") not in ignored_folders()}
    assert not missing, f"add to .gitignore: {missing}"


def test_documented_out_folders_are_ignored():
    """The ``--out`` folders of the commands in README.md, docs/ and benchmarks/README.md (not placeholders
    such as ``DIR``)."""
    found = [re.findall(r"stickslip \S+ .*--out ([^\s`\]]+)", document.read_text()) for document in DOCUMENTS]
    outs = [out for per_document in found for out in per_document if not out.isupper()]
    assert len(outs) >= 4
    missing = [out for out in outs if out.strip("/").split("/")[0] not in ignored_folders()]
    assert not missing, f"add to .gitignore: {missing}"


# ----------------------------------------------------------------------
# the commands the documents show: they exist with those options, and the README's run as written
# ----------------------------------------------------------------------

SHELL_OPERATORS = {"&&", "||", "|", ";", ">", ">>", "2>&1"}
ACTIVATE = "source .venv/bin/activate"


def shell_lines(text):
    """The command lines of the shell blocks of a Markdown text, in order: continuation lines joined, comments
    cut."""
    lines = []
    for block in SHELL_BLOCK.findall(text):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split(" #", 1)[0].strip()
            if line and not line.startswith("#"):
                lines.append(line)
    return lines


def invocations(line):
    """The ``stickslip`` calls of one shell line: ``(program as written, [arguments])`` each."""
    words, found = shlex.split(line), []
    for i, word in enumerate(words):
        if word == "stickslip" or word.endswith("/stickslip"):
            rest = words[i + 1:]
            end = next((k for k, w in enumerate(rest) if w in SHELL_OPERATORS), len(rest))
            found.append((word, rest[:end]))
    return found


def subcommand_parser(words):
    """``(parser, words left)`` of the (sub)command that ``words`` name (``system run`` goes two deep); KeyError
    for an unknown command."""
    parser, words = command_parsers()[words[0]], words[1:]
    choices = {name: sub for action in parser._actions if isinstance(action, argparse._SubParsersAction)
               for name, sub in action.choices.items()}
    while words and words[0] in choices:
        parser, words = choices[words[0]], words[1:]
        choices = {name: sub for action in parser._actions if isinstance(action, argparse._SubParsersAction)
                   for name, sub in action.choices.items()}
    return parser, words


def refused_commands(text):
    """The ``stickslip`` calls in the shell blocks of ``text`` that the command line would refuse, with argparse's
    reason."""
    refused, parsers = [], command_parsers()
    for line in shell_lines(text):
        for _, words in invocations(line):
            if not words or words[0] not in parsers:  # ``--help``; an unknown command: test_named_commands_exist
                continue
            message = io.StringIO()
            try:
                with contextlib.redirect_stderr(message), contextlib.redirect_stdout(io.StringIO()):
                    parsers[words[0]].parse_args(words[1:])
            except SystemExit as exc:
                if exc.code:
                    refused.append(f"{shlex.join(['stickslip', *words])}: {message.getvalue().strip().splitlines()[-1]}")
    return refused


def unknown_options(text):
    """The ``--options`` of the ``stickslip <command>`` spans in the inline code of ``text`` that the command's
    ``--help`` does not list."""
    unknown = []
    for span in INLINE_CODE.findall(FENCE.sub("", text)):
        words = span.replace("\\|", "|").split()
        if len(words) < 2 or words[0] != "stickslip" or words[1] not in command_parsers():
            continue
        parser, _ = subcommand_parser(words[1:])
        listed = set(re.findall(r"--[\w-]+", parser.format_help()))
        unknown += [f"{span}: {option}" for option in re.findall(r"(?<![\w-])--[\w-]+", span) if option not in listed]
    return unknown


def unactivated_commands(text):
    """The bare ``stickslip`` and ``python`` calls in the shell blocks of ``text`` before the line that activates
    the virtual environment (which puts them on the PATH)."""
    bare, active = [], False
    for line in shell_lines(text):
        active = active or line.startswith(ACTIVATE)
        words = shlex.split(line)
        if not active and words and words[0] in ("stickslip", "python"):
            bare.append(line)
    return bare


@pytest.mark.parametrize("document", DOCUMENTS, ids=_label)
def test_shown_commands_parse(document):
    refused, unknown = refused_commands(document.read_text()), unknown_options(document.read_text())
    assert not refused, f"the command line refuses these commands of {_label(document)}: {refused}"
    assert not unknown, f"options that the commands of {_label(document)} do not have: {unknown}"


def test_readme_commands_run_as_written():
    """A reader who types the README's shell blocks in order has ``stickslip`` and ``python`` on the PATH."""
    text = (REPO / "README.md").read_text()
    assert ACTIVATE in text
    assert not unactivated_commands(text)
    assert any(program == "stickslip" for line in shell_lines(text) for program, _ in invocations(line))


def test_the_command_checks_catch_what_drifted():
    text = ("```bash\nstickslip run scenarios/ --workers 2\nstickslip system run systems/x.toml --master fast\n"
            "stickslip vc --v-min 0.1   # ok\n.venv/bin/stickslip bifurcation -n many --out bif\n"
            f"python examples/x.py\n{ACTIVATE}\nstickslip map\n```\n"
            "`stickslip build [--out DIR]`, `stickslip chart --outdir DIR`, `stickslip system run FILE --master me`\n")
    refused = refused_commands(text)
    assert [entry.split(":", 1)[0] for entry in refused] == [
        "stickslip run scenarios/ --workers 2", "stickslip system run systems/x.toml --master fast",
        "stickslip bifurcation -n many --out bif"]
    assert "unrecognized arguments: --workers 2" in refused[0] and "invalid choice: 'fast'" in refused[1]
    assert unknown_options(text) == ["stickslip chart --outdir DIR: --outdir"]
    assert unactivated_commands(text) == ["stickslip run scenarios/ --workers 2",
                                          "stickslip system run systems/x.toml --master fast",
                                          "stickslip vc --v-min 0.1", "python examples/x.py"]
