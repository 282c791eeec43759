"""The compact form of a system file: a ``[template]`` table of ``N`` like blocks (docs/systems.md).

``[template]`` holds ``n`` (the number of blocks) and ``seed`` (of the random offsets, NumPy's
``default_rng``); ``[template.block]`` every block's parameters once, as a ``[[blocks]]`` table; ``[template.lists]``
per-block values (a list of ``n`` values for a parameter, block ``b1`` first); ``[template.spread]`` random
per-block offsets: block ``i`` takes its value plus ``spread u_i``, ``u_i`` uniform in ``[-1, 1]`` (in the
parameter's unit), drawn for one parameter after another in the order of their names. :func:`expand_template`
turns the table into the ``[[blocks]]`` tables it stands for, which the system file then checks as any others.
"""

import numpy as np

from ..core.ranges import NON_NEGATIVE, Range

TEMPLATE_KEYS = {"n", "seed", "block", "lists", "spread"}
#: the most blocks a template makes
MAX_BLOCKS = 1_000_000


def expand_template(f, template, is_integer):
    """The ``[[blocks]]`` tables of the ``[template]`` table ``template`` (checked; ``f`` the system file's checks,
    :class:`stickslip.systems.system_file._File`); ``is_integer(name)``: whether the parameter is an integer (a law
    code), which takes no random offset. Parameter names are checked later, block by block."""
    template = f.table(template, "template", TEMPLATE_KEYS)
    n = _whole(f, template.get("n"), "template.n", 1, MAX_BLOCKS)
    seed = _whole(f, template.get("seed", 0), "template.seed", 0, 2**63 - 1)
    block, lists, spread = (_part(f, template, part) for part in ("block", "lists", "spread"))
    columns = {name: [value] * n for name, value in block.items()}
    for name, values in lists.items():
        if not isinstance(values, list) or len(values) != n:
            raise f.error(f"template.lists.{name}", f"a list of {n} values (one per block, b1 first)", values)
        columns[name] = list(values)
    rng = np.random.default_rng(seed)
    for name in sorted(spread):
        key = f"template.spread.{name}"
        width = f.number(spread[name], key, NON_NEGATIVE)
        if is_integer(name):
            raise f.error(key, "a real-valued parameter (a law code takes no offset)", spread[name])
        base = columns.get(name)
        if base is None:
            raise f.error(key, f"a parameter given in template.block or template.lists ({name} is not)",
                          spread[name])
        offsets = width * rng.uniform(-1.0, 1.0, n)
        columns[name] = [f.number(v, f"template.block.{name}") + float(d) for v, d in zip(base, offsets)]
    return [{name: values[i] for name, values in columns.items()} for i in range(n)]


def _part(f, template, part):
    """``[template.<part>]`` as ``{dotted name: value}`` (the names are checked block by block, later)."""
    table = template.get(part, {})
    return flat_table(f.table(table, f"template.{part}", table if isinstance(table, dict) else ()))


def _whole(f, value, key, low, high):
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise f.error(key, f"an integer in {Range(low, high)}", value)
    return value


def flat_table(table, prefix=""):
    """``{dotted name: value}``: ``kinetic.F0 = 0.5`` without quotes is a nested table in TOML."""
    out = {}
    for key, value in table.items():
        if isinstance(value, dict):
            out.update(flat_table(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out
