"""Every folder the README's commands write by default or by their --out is ignored by git (issue 11)."""

import argparse
import re
from pathlib import Path

from stickslip.cli import COMMANDS

REPO = Path(__file__).resolve().parents[1]


def _ignored():
    return {line.strip() for line in (REPO / ".gitignore").read_text().splitlines()}


def _default_outs():
    parser = argparse.ArgumentParser()
    subparsers = parser.add_subparsers()
    for add in COMMANDS:
        add(subparsers)
    outs = {}
    for name, sub in subparsers.choices.items():
        for action in sub._actions:
            if action.dest == "out" and action.default:
                outs[name] = action.default
    return outs


def test_default_output_folders_are_ignored():
    outs = _default_outs()
    assert {"run", "bench", "bifurcation", "vc", "map", "slow-manifold", "chart"} <= set(outs)
    missing = {name: out for name, out in outs.items() if f"{out.strip('/')}/" not in _ignored()}
    assert not missing, f"add to .gitignore: {missing}"


def test_readme_out_folders_are_ignored():
    outs = re.findall(r"stickslip \S+ .*--out (\S+)", (REPO / "README.md").read_text())
    assert len(outs) >= 4
    missing = [out for out in outs if f"{out.strip('/').split('/')[0]}/" not in _ignored()]
    assert not missing, f"add to .gitignore: {missing}"
