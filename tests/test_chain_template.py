"""A chain from a template: :func:`stickslip.chain.template.chain_system` and the ``[template]`` table of system
files (:mod:`stickslip.systems.template_table`) against the explicit ``[[blocks]]`` form."""

import textwrap
import tomllib
from pathlib import Path

import numpy as np
import pytest

from stickslip.chain.template import chain_system, template_table
from stickslip.systems import SystemFileError, load_system
from stickslip.systems.system_file import system_from_data

SYSTEMS = Path(__file__).resolve().parents[1] / "systems"
BK10 = SYSTEMS / "bk10-velocity-weakening.toml"
BK100 = SYSTEMS / "bk100-velocity-weakening.toml"

BK_BLOCK = """
[template.block]
M = 1.0
kappa = 1.0
kinetic.law = 3
kinetic.F0 = 0.5
kinetic.F_stribeck = 0.4
kinetic.v_stribeck = 0.05
kinetic.delta = 1.0
kinetic.gamma = 0.0
static.law = 1
static.F0 = 1.0
x_start = 0.0
v_start = 0.01
"""


def compact(tmp_path, template="n = 10\nseed = 3", extra="", block=BK_BLOCK, coupling="4.0"):
    path = tmp_path / "compact.toml"
    path.write_text(f"[system]\nstop_time = 300.0\noutput_interval = 0.1\nv_drive = 0.01\ncoupling = {coupling}\n"
                    f"[template]\n{template}\n{textwrap.dedent(block)}\n{extra}")
    return path


def test_the_compact_form_of_bk10_is_bk10(tmp_path):
    explicit = load_system(BK10)
    starts = ", ".join(repr(b["x_start"]) for b in explicit.blocks)
    system = load_system(compact(tmp_path, extra=f"[template.lists]\nx_start = [{starts}]\n"))
    assert system.blocks == explicit.blocks
    assert (system.coupling, system.v_drive, system.stop_time, system.output_interval) == \
        (explicit.coupling, explicit.v_drive, explicit.stop_time, explicit.output_interval)


def test_chain_system_is_the_shipped_compact_file():
    shipped = load_system(BK100)
    system = chain_system(100, seed=1, stop_time=1000.0, output_interval=1.0)
    assert system.blocks == shipped.blocks and system.coupling == shipped.coupling
    assert system.v_drive == shipped.v_drive == 0.01
    assert chain_system(100, seed=1, name="bk").name == "bk"
    assert chain_system(100, seed=1).name == "chain100-seed1"


def test_the_offsets_are_uniform_in_the_spread_and_follow_the_seed():
    starts = np.array([b["x_start"] for b in chain_system(2000, seed=5, x_start=0.5, offset_spread=0.02).blocks])
    assert np.all(np.abs(starts - 0.5) <= 0.02)
    # uniform in [-s, s]: mean 0, variance s^2 / 3 (2000 draws: 5 standard errors)
    assert abs(starts.mean() - 0.5) < 5 * 0.02 / np.sqrt(3 * 2000)
    assert abs(starts.var() / (0.02**2 / 3) - 1) < 5 * np.sqrt(0.8 / 2000)
    again = [b["x_start"] for b in chain_system(2000, seed=5, x_start=0.5, offset_spread=0.02).blocks]
    other = [b["x_start"] for b in chain_system(2000, seed=6, x_start=0.5, offset_spread=0.02).blocks]
    assert list(starts) == again and list(starts) != other
    assert all(b["x_start"] == 0.5 for b in chain_system(5, seed=5, x_start=0.5, offset_spread=0.0).blocks)


def test_lists_and_offsets_combine_and_every_block_is_alike_otherwise(tmp_path):
    system = load_system(compact(tmp_path, template="n = 3\nseed = 0",
                                 extra="[template.lists]\nM = [1.0, 2.0, 3.0]\n[template.spread]\nM = 0.5\n"))
    offsets = 0.5 * np.random.default_rng(0).uniform(-1.0, 1.0, 3)
    assert [b["M"] for b in system.blocks] == list(np.array([1.0, 2.0, 3.0]) + offsets)
    assert all(b["kinetic.F_stribeck"] == 0.4 and b["static.F0"] == 1.0 for b in system.blocks)


def test_a_template_chain_is_not_refused_for_its_length():
    data = template_table(100, seed=1, stop_time=1e6, output_interval=1.0)
    with pytest.raises(SystemFileError, match="key 'system.stop_time'.*free periods"):
        system_from_data(data, "long.toml")
    assert chain_system(100, seed=1, stop_time=1e6, output_interval=1.0).stop_time == 1e6


@pytest.mark.parametrize("template, extra, message", [
    ("n = 0", "", r"key 'template.n': allowed is an integer in \[1, 1e\+06\], got 0"),
    ("n = 2.5", "", r"key 'template.n': allowed is an integer in \[1, 1e\+06\], got 2.5"),
    ("seed = 1", "", r"key 'template.n': allowed is an integer in \[1, 1e\+06\], got nothing"),
    ("n = 3\nseed = -1", "", r"key 'template.seed': allowed is an integer in \[0, "),
    ("n = 3\nsize = 3", "", r"key 'template.size': allowed is one of the keys \['block', 'lists', 'n', 'seed', "
                            r"'spread'\]"),
    ("n = 3", "[template.lists]\nx_start = [0.0, 0.1]\n",
     r"key 'template.lists.x_start': allowed is a list of 3 values \(one per block, b1 first\), got \[0.0, 0.1\]"),
    ("n = 3", "[template.spread]\nx_start = -0.1\n",
     r"key 'template.spread.x_start': allowed is a finite number in \[0, inf\), got -0.1"),
    ("n = 3", "[template.spread]\n\"kinetic.law\" = 1.0\n",
     r"key 'template.spread.kinetic.law': allowed is a real-valued parameter \(a law code takes no offset\)"),
    ("n = 3", "[template.spread]\n\"static.A\" = 1.0\n",
     r"key 'template.spread.static.A': allowed is a parameter given in template.block or template.lists"),
    ("n = 3", "[template.lists]\nM = [1.0, -1.0, 1.0]\n", r"block b2: M = -1.0 kg is out of range"),
    ("n = 3", "[template.lists]\nkapa = [1.0, 1.0, 1.0]\n", r"key 'b1.kapa': allowed is an FMU parameter"),
    ("n = 3", "[[blocks]]\nM = 1.0\n", r"key 'blocks': allowed is no \[\[blocks\]\] tables beside a \[template\]"),
])
def test_a_bad_template_is_refused_naming_the_key_and_range(tmp_path, template, extra, message):
    with pytest.raises(SystemFileError, match=message):
        load_system(compact(tmp_path, template=template, extra=extra))


def test_a_bad_coupling_is_refused_naming_the_spring(tmp_path):
    with pytest.raises(SystemFileError, match=r"key 'system.coupling\[0\]': allowed is a finite number in \[0, inf\)"):
        chain_system(5, seed=0, kc=-1.0)
    with pytest.raises(SystemFileError, match=r"key 'system.coupling': allowed is a list of 2 stiffnesses \(N/m\) for "
                                              r"3 blocks, or one for all"):
        load_system(compact(tmp_path, template="n = 3", coupling="[4.0]"))
    with pytest.raises(SystemFileError, match=r"block b1: "):
        chain_system(5, seed=0, kinetic={"law": 3, "F0": 1.5, "F_stribeck": 0.4, "v_stribeck": 0.05})


def test_the_shipped_compact_file_is_a_template():
    data = tomllib.loads(BK100.read_text())
    assert "blocks" not in data and data["template"]["n"] == 100
