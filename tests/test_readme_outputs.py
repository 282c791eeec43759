"""Every folder the documented commands write by default or by their --out is ignored by git (issues 11, 18)."""

import re

from test_docs import DOCUMENTS, command_parsers, ignored_folders


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
