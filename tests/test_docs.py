"""The documents name only what exists, and the README stays a front door (issue 18).

Checked in README.md, docs/*.md, benchmarks/README.md and examples/README.md: every repository path they name
(in inline code or as a link), every ``stickslip <command>``, every ``python -m <module>`` and every ``stickslip.<name>``
in code; every scenario file is in the table of docs/scenarios.md and the table names no other.
"""

import argparse
import fnmatch
import functools
import importlib
import importlib.util
import os
import re
from pathlib import Path

import pytest

from stickslip.cli.commands import COMMANDS

REPO = Path(__file__).resolve().parents[1]
DOCUMENTS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), REPO / "benchmarks" / "README.md",
             REPO / "examples" / "README.md"]
README_MAX_LINES = 200
#: a name in inline code is taken for a repository path if it ends in one of these, or in "/" (a folder), or
#: starts with a top-level entry of the repository (``.ci/run``); so ``F_K/kappa`` is a formula, not a path
PATH_SUFFIXES = (".py", ".md", ".toml", ".c", ".h", ".sh")
PATH_LIKE = re.compile(r"[\w.*<>-]+(/[\w.*<>-]+)*/?")
#: folders inside a built FMU, which the documents describe; they are not in the repository
FMU_FOLDERS = {"binaries", "resources", "sources", "documentation"}
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)
SHELL_BLOCK = re.compile(r"^```(?:bash|sh)\n(.*?)^```", re.S | re.M)
HEADING = re.compile(r"^#+ (.+)$", re.M)
INLINE_CODE = re.compile(r"`([^`]+)`")
LINK = re.compile(r"\]\(([^)\s]+)\)")
COMMAND = re.compile(r"(?<![\w.-])stickslip\s+([a-z][\w-]*)")
MODULE_RUN = re.compile(r"\bpython3?\s+-m\s+([\w.]+)")
DOTTED = re.compile(r"(?<![\w./-])stickslip(?:\.\w+)+")


def command_parsers():
    """``{command name or alias: its argparse parser}`` of the ``stickslip`` command line."""
    subparsers = argparse.ArgumentParser().add_subparsers()
    for add in COMMANDS:
        add(subparsers)
    return dict(subparsers.choices)


@functools.cache
def ignored_folders():
    """Top-level folders that .gitignore names (output folders of the commands, the venv, build folders)."""
    lines = (REPO / ".gitignore").read_text().splitlines()
    return {line.strip("/") for line in lines if line.endswith("/") and "*" not in line and "/" not in line[:-1]}


def repository_paths():
    """Every file and folder of the working tree outside the ignored folders, relative to the top (posix)."""
    skip = ignored_folders() | {".git", ".mypy_cache", "__pycache__"}
    paths = set()
    for folder, subfolders, files in os.walk(REPO):
        subfolders[:] = [s for s in subfolders if s not in skip and not s.endswith(".egg-info")]
        relative = Path(folder).relative_to(REPO)
        paths.update((relative / name).as_posix() for name in subfolders + files)
    return paths


def code_blocks(text):
    """The code of a Markdown text: its fenced blocks, then its inline code spans (line breaks as spaces)."""
    inline = [" ".join(span.split()) for span in INLINE_CODE.findall(FENCE.sub("", text))]
    return FENCE.findall(text) + inline


def path_candidates(text):
    """The inline code spans of ``text``, and the words of its shell blocks (without comments), that look like
    repository paths (see :data:`PATH_SUFFIXES`)."""
    top_level = {path.name for path in REPO.iterdir()}
    spans = [" ".join(span.split()) for span in INLINE_CODE.findall(FENCE.sub("", text))]
    for block in SHELL_BLOCK.findall(text):
        spans += [word.strip("\"'") for line in block.splitlines() for word in line.split("#", 1)[0].split()]
    return [span for span in spans if PATH_LIKE.fullmatch(span)
            and (span.endswith((*PATH_SUFFIXES, "/")) or ("/" in span and span.split("/", 1)[0] in top_level))]


def anchors(text):
    """The link anchors of the headings of a Markdown text, as GitHub makes them."""
    return {re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-") for heading in HEADING.findall(
        FENCE.sub("", text))}


def is_outside_repository(path):
    """A path in an output folder, inside an FMU, absolute or in the user's home: not the repository's."""
    top = path.split("/", 1)[0]
    return path.startswith(("/", "~", "$")) or top in ignored_folders() or top in FMU_FOLDERS


def missing_paths(text, document, known):
    """The paths that ``text`` (the text of ``document``) names and that do not exist.

    An inline code span names a path from the top of the repository, or the end of one (``loader/``,
    ``host.c``); ``<...>`` and ``*`` match any name. A link is relative to the document's folder, and its
    ``#anchor`` must be a heading of the document it points to. ``known``: :func:`repository_paths`.
    """
    missing = []
    for span in path_candidates(text):
        if is_outside_repository(span):
            continue
        pattern = re.sub(r"<[^>]*>", "*", span.rstrip("/"))
        if not any(fnmatch.fnmatchcase(p, pattern) or fnmatch.fnmatchcase(p, "*/" + pattern) for p in known):
            missing.append(span)
    for link in LINK.findall(text):
        target, _, anchor = link.partition("#")
        if "://" in target or target.startswith("mailto:"):
            continue
        resolved = Path(os.path.normpath(document.parent / target)) if target else document
        if not resolved.exists() or REPO not in (resolved, *resolved.parents):
            missing.append(link)
        elif anchor and (resolved.suffix != ".md" or anchor not in anchors(resolved.read_text())):
            missing.append(link)
    return missing


def unknown_commands(text, commands):
    """The ``stickslip <command>`` names in the code of ``text`` that are not in ``commands``."""
    return sorted({name for block in code_blocks(text) for name in COMMAND.findall(block)} - set(commands))


def module_exists(name):
    """Whether the module ``name`` can be imported (its parent packages are imported to find it)."""
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def missing_modules(text):
    """The modules of ``python -m <module>`` in ``text`` that cannot be found."""
    return sorted({name for name in MODULE_RUN.findall(text) if not module_exists(name)})


def resolves(dotted):
    """Whether ``stickslip.a.b...`` is a module, or a name in the longest importable module prefix."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            target = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            if not hasattr(target, name):
                return False
            target = getattr(target, name)
        return True
    return False


def unresolved_names(text):
    """The ``stickslip.<name>`` references in the code of ``text`` that name nothing."""
    return sorted({name for block in code_blocks(text) for name in DOTTED.findall(block) if not resolves(name)})


def scenario_table_names(text):
    """The scenario names in the first column of the table headed ``| file |`` in ``text``."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| file |"))
    names = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        names.append(line.split("|")[1].strip().strip("`").removesuffix(".toml"))
    return names


def _label(document):
    return document.relative_to(REPO).as_posix()


@pytest.fixture(scope="module")
def known_paths():
    return repository_paths()


@pytest.mark.parametrize("document", DOCUMENTS, ids=_label)
def test_named_paths_exist(document, known_paths):
    missing = missing_paths(document.read_text(), document, known_paths)
    assert not missing, f"{_label(document)} names paths that do not exist: {missing}"


@pytest.mark.parametrize("document", DOCUMENTS, ids=_label)
def test_named_commands_exist(document):
    unknown = unknown_commands(document.read_text(), command_parsers())
    assert not unknown, f"{_label(document)} names stickslip commands that do not exist: {unknown}"


@pytest.mark.parametrize("document", DOCUMENTS, ids=_label)
def test_named_modules_exist(document):
    text = document.read_text()
    missing, unresolved = missing_modules(text), unresolved_names(text)
    assert not missing, f"{_label(document)} runs modules that do not exist: python -m {missing}"
    assert not unresolved, f"{_label(document)} names what does not exist: {unresolved}"


def test_every_scenario_file_is_in_the_scenario_table():
    files = sorted(path.stem for path in (REPO / "scenarios").glob("*.toml"))
    table = scenario_table_names((REPO / "docs" / "scenarios.md").read_text())
    assert sorted(set(files) - set(table)) == [], "scenario files missing from docs/scenarios.md's table"
    assert sorted(set(table) - set(files)) == [], "docs/scenarios.md's table names scenarios with no file"
    assert len(table) == len(set(table)), "a scenario is listed twice"


def test_readme_is_a_front_door():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; move details into docs/"


def test_the_checks_catch_what_drifted(known_paths):
    """Planted drift is caught: an old path, an old command, an old module, a broken link, an old name."""
    text = ("`src/stickslip/fmu_loader/loader.c`, `fmu_build.py`, [spec](SPEC.md), [gone](gone.md),\n"
            "[a section](variables.md#defaults), [no section](variables.md#speed), [here](#threads),\n"
            "[not here](#planted-drift), `stickslip build-fmux`, python -m stickslip.variable_table,\n"
            "python -m nowhere.module, `stickslip.fmu_driver.run`, `stickslip.core.Trajectory`\n"
            "```bash\ncc src/stickslip/c_host/host.c -o build/host   # src/ok.c\n```\n")
    document = REPO / "docs" / "hosts.md"
    assert missing_paths(text, document, known_paths) == [
        "src/stickslip/fmu_loader/loader.c", "fmu_build.py", "src/stickslip/c_host/host.c", "gone.md",
        "variables.md#speed", "#planted-drift"]
    assert unknown_commands(text, command_parsers()) == ["build-fmux"]
    assert missing_modules(text) == ["nowhere.module", "stickslip.variable_table"]
    assert unresolved_names(text) == ["stickslip.fmu_driver.run"]
    assert scenario_table_names("| file | x |\n|---|---|\n| `a` | 1 |\n| `b.toml` | 2 |\n\nafter") == ["a", "b"]
