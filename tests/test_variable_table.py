"""The variable table in docs/variables.md is the built FMU's model description (issue 11)."""

import math
from pathlib import Path

from stickslip.core import ANY_FINITE, KINETIC_LAWS, POSITIVE, RTOL_RANGE, STATIC_LAWS
from stickslip.fmu.variable_docs import DOC, doc_table, markdown, replace_table, rows, split_description

VARIABLES_DOC = Path(__file__).resolve().parents[1] / DOC

OWN_RANGES = {"M": POSITIVE, "kappa": POSITIVE, "x_start": ANY_FINITE, "v_start": ANY_FINITE,
              "solver.rtol": RTOL_RANGE, "v_drive": ANY_FINITE, "F_ext": ANY_FINITE}


def test_documented_table_is_the_fmus_model_description(fmu_path):
    """Fails while docs/variables.md and the FMU disagree: run ``python -m stickslip.fmu.variable_docs``."""
    assert doc_table(VARIABLES_DOC.read_text()) == markdown(fmu_path)


def test_every_variable_has_default_unit_range_and_meaning(unzipped):
    _, description, _ = unzipped
    for v in description.modelVariables:
        meaning, allowed = split_description(v.description)
        assert meaning, v.name
        if v.causality in ("parameter", "input"):
            assert v.start is not None, v.name
            assert allowed or v.type == "Integer", v.name


def test_stated_ranges_are_the_ones_the_runtime_checks(unzipped):
    """Each description's range is the law's or model's Range, and min/max are its closed ends."""
    _, description, _ = unzipped
    expected = dict(OWN_RANGES)
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        for law in laws.values():
            for name, (_, allowed, _) in law.PARAMETERS.items():
                assert str(expected.setdefault(f"{kind}.{name}", allowed)) == str(allowed)
    stated = {}
    for v in description.modelVariables:
        _, allowed = split_description(v.description)
        if allowed:
            stated[v.name] = allowed
            r = expected[v.name]
            low = None if r.low is None or r.low_open else r.low
            high = None if r.high is None or r.high_open else r.high
            assert (None if v.min is None else float(v.min)) == low, v.name
            assert (None if v.max is None else float(v.max)) == high, v.name
    assert stated == {name: str(r) for name, r in expected.items()}


def test_defaults_in_the_table_are_the_start_values(unzipped, fmu_path):
    _, description, _ = unzipped
    table = {row[0]: row for row in rows(fmu_path)}
    for v in description.modelVariables:
        if v.start is not None:
            assert math.isclose(float(table[v.name][3]), float(v.start)), v.name


def test_replacing_the_table_keeps_the_rest_of_the_document(fmu_path):
    text = VARIABLES_DOC.read_text()
    stale = text.replace("| `M` | parameter | Real | 1 |", "| `M` | parameter | Real | 2 |")
    assert doc_table(stale) != markdown(fmu_path)
    assert replace_table(stale, markdown(fmu_path)) == text
