"""The catalogue (:mod:`stickslip.chain.catalogue`): block events grouped into slip events, on hand-made event
lists and on random ones against the union of the blocks' slip intervals."""

import csv

import numpy as np
import pytest

from stickslip.chain.catalogue import (SLIP_EVENT_COLUMNS, CatalogueError, CatalogueSink, catalogue_file,
                                       group_slip_events, read_slip_events)
from stickslip.chain.output import EVENT_KINDS, MemorySink

V = 0.01  # m/s, the surface


def group(events, **kwargs):
    t, block, kind, x = zip(*events)
    return group_slip_events(t, block, kind, x, v_drive=V, **kwargs)


def rel(t0, x0, t1, x1):
    """A slip interval's slip relative to the surface (m)."""
    return x1 - x0 - V * (t1 - t0)


def test_a_single_block_event():
    table, open_event = group([(1.0, 3, "slip", 0.5), (1.5, 3, "stick", 0.2)])
    assert open_event is None
    assert {k: v.tolist() for k, v in table.items()} == {
        "start": [1.0], "duration": [0.5], "size": [1], "moment": [rel(1.0, 0.5, 1.5, 0.2)], "first_block": [3],
        "end": [1.5], "n_slips": [1], "n_block_events": [2]}


def test_overlapping_slips_make_one_event_and_a_gap_makes_two():
    table, _ = group([(1.0, 2, "slip", 0.5), (1.1, 3, "slip", 0.6), (1.3, 2, "stick", 0.1), (1.4, 3, "stick", 0.3),
                      (2.0, 1, "slip", 0.4), (2.2, 1, "stick", 0.0)])
    assert table["start"].tolist() == [1.0, 2.0] and table["end"].tolist() == [1.4, 2.2]
    assert table["size"].tolist() == [2, 1] and table["first_block"].tolist() == [2, 1]
    assert table["moment"][0] == pytest.approx(rel(1.0, 0.5, 1.3, 0.1) + rel(1.1, 0.6, 1.4, 0.3), abs=1e-15)
    assert table["duration"][0] == pytest.approx(0.4, abs=1e-15)


def test_a_block_slipping_twice_counts_once_in_size_and_twice_in_moment():
    table, _ = group([(1.0, 1, "slip", 0.5), (1.1, 2, "slip", 0.6), (1.2, 1, "stick", 0.3), (1.25, 1, "slip", 0.31),
                      (1.3, 2, "stick", 0.2), (1.4, 1, "stick", 0.1)])
    assert table["size"].tolist() == [2] and table["n_slips"].tolist() == [3]
    moment = rel(1.0, 0.5, 1.2, 0.3) + rel(1.1, 0.6, 1.3, 0.2) + rel(1.25, 0.31, 1.4, 0.1)
    assert table["moment"][0] == pytest.approx(moment, abs=1e-15)
    assert table["n_block_events"].tolist() == [6]


def test_overshoots_inside_an_event_count_as_block_events_only():
    table, _ = group([(1.0, 1, "slip", 0.5), (1.2, 1, "overshoot", 0.1), (1.3, 1, "overshoot", 0.15),
                      (1.5, 1, "stick", 0.12)])
    assert table["size"].tolist() == [1] and table["n_slips"].tolist() == [1]
    assert table["n_block_events"].tolist() == [4]
    assert table["moment"].tolist() == [rel(1.0, 0.5, 1.5, 0.12)]
    with pytest.raises(CatalogueError, match=r"block 2 has a 'overshoot' at t = 2.0 s while it is stuck"):
        group([(1.0, 1, "slip", 0.5), (2.0, 2, "overshoot", 0.1)])


def test_an_event_open_at_the_end_is_left_out_and_reported():
    table, open_event = group([(1.0, 1, "slip", 0.5), (1.5, 1, "stick", 0.2), (3.0, 4, "slip", 0.5),
                               (3.1, 5, "slip", 0.5), (3.2, 4, "stick", 0.1)])
    assert table["start"].tolist() == [1.0]
    assert open_event.summary() == {"start": 3.0, "first_block": 4, "blocks_so_far": 2, "n_block_events": 3}


def test_blocks_slipping_from_the_start_open_an_event_at_zero():
    table, _ = group([(0.5, 3, "stick", 0.1), (0.7, 2, "stick", 0.2)], slipping_at_start={3: 0.4, 2: 0.3})
    assert table["start"].tolist() == [0.0] and table["first_block"].tolist() == [2]
    assert table["moment"][0] == pytest.approx(rel(0.0, 0.4, 0.5, 0.1) + rel(0.0, 0.3, 0.7, 0.2), abs=1e-15)


@pytest.mark.parametrize("events, message", [
    ([(1.0, 1, "stick", 0.5)], r"block 1 has a 'stick' at t = 1.0 s while it is stuck \(no slip before\)"),
    ([(1.0, 1, "slip", 0.5), (1.1, 1, "slip", 0.5)], r"block 1 slips at t = 1.1 s while it is slipping already"),
    ([(1.0, 1, "slip", 0.5), (0.9, 1, "stick", 0.5)], r"t = 0.9 s \(block 1, stick\) comes after t = 1.0 s"),
    ([(1.0, 1, "slide", 0.5)], r"kind 'slide': allowed is one of \['slip', 'stick', 'overshoot'\]"),
    ([(1.0, 1, 3, 0.5)], r"kind '3': allowed is one of \['slip', 'stick', 'overshoot'\]"),
])
def test_events_that_cannot_be_grouped_are_refused_naming_the_event(events, message):
    with pytest.raises(CatalogueError, match=message):
        group(events)


def random_events(rng, n_blocks=6, n_intervals=400):
    """Random block events (distinct times) with overshoots, and each block's slip intervals
    ``[(t_slip, x_slip, t_stick, x_stick)]``."""
    events, intervals, t = [], [], 0.0
    free = {b: 0.0 for b in range(1, n_blocks + 1)}  # block: the time it is stuck from
    for _ in range(n_intervals):
        b = int(rng.integers(1, n_blocks + 1))
        t0 = max(free[b], t + float(rng.exponential(0.3))) + 1e-3
        t1 = t0 + float(rng.exponential(0.5))
        x0, x1 = rng.normal(size=2).tolist()
        events += [(t0, b, "slip", x0), (t1, b, "stick", x1)]
        events += [(s, b, "overshoot", 0.0) for s in np.sort(rng.uniform(t0, t1, rng.integers(0, 3))).tolist()]
        intervals.append((t0, b, x0, t1, x1))
        free[b], t = t1, t0
    return sorted(events), intervals


def union_of_intervals(intervals):
    """The slip events as the connected parts of the union of the slip intervals (an independent grouping)."""
    out, current = [], None
    for t0, b, x0, t1, x1 in sorted(intervals):
        if current is None or t0 > current["end"]:
            current = {"start": t0, "end": t1, "blocks": set(), "moment": 0.0, "first_block": b, "n": 0}
            out.append(current)
        current["end"] = max(current["end"], t1)
        current["blocks"].add(b)
        current["moment"] += rel(t0, x0, t1, x1)
        current["n"] += 1
    return out


def test_random_events_group_as_the_union_of_the_slip_intervals():
    rng = np.random.default_rng(7)
    events, intervals = random_events(rng)
    table, open_event = group(events)
    expected = union_of_intervals(intervals)
    assert open_event is None and len(table["start"]) == len(expected) > 50
    assert table["start"].tolist() == [e["start"] for e in expected]
    assert table["end"].tolist() == [e["end"] for e in expected]
    assert table["size"].tolist() == [len(e["blocks"]) for e in expected]
    assert table["n_slips"].tolist() == [e["n"] for e in expected]
    assert table["first_block"].tolist() == [e["first_block"] for e in expected]
    np.testing.assert_allclose(table["moment"], [e["moment"] for e in expected], rtol=0, atol=1e-12)
    assert max(table["size"]) > 2 and max(table["n_slips"] - table["size"]) > 0


@pytest.mark.parametrize("chunk_rows", [1, 2, 3, 7, 1000])
def test_chunk_boundaries_inside_events_change_nothing(tmp_path, chunk_rows):
    events, _ = random_events(np.random.default_rng(3), n_intervals=60)
    path = tmp_path / "block_events.csv"
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time", "block", "kind", "x"])
        writer.writerows((repr(t), b, k, repr(x)) for t, b, k, x in events)
    grouper, rows = catalogue_file(path, tmp_path / "slip_events.csv", v_drive=V, chunk_rows=chunk_rows)
    written = read_slip_events(tmp_path / "slip_events.csv")
    expected, _ = group(events)
    assert rows == len(expected["start"]) and grouper.n_block_events == len(events) and grouper.open_event is None
    for name in SLIP_EVENT_COLUMNS:
        assert written[name].tolist() == expected[name].tolist(), name


def test_a_file_with_other_columns_is_refused(tmp_path):
    path = tmp_path / "block_events.csv"
    path.write_text("t,block,kind,x\n1.0,1,slip,0.0\n")
    with pytest.raises(CatalogueError, match=r"block_events.csv: the first line must be the columns time,block,kind,x"):
        catalogue_file(path, tmp_path / "slip_events.csv", v_drive=V)
    path.write_text("time,block,kind,x\n1.0,one,slip,0.0\n")
    with pytest.raises(CatalogueError, match=r"a row of block events that is not time,block,kind,x"):
        catalogue_file(path, tmp_path / "slip_events.csv", v_drive=V)


def test_the_sink_passes_the_events_on_and_writes_the_catalogue_as_they_come(tmp_path):
    events, _ = random_events(np.random.default_rng(11), n_intervals=80)
    t, block, kind, x = (np.array(c) for c in zip(*events))
    codes = np.array([EVENT_KINDS.index(k) for k in kind])
    inner = MemorySink()
    sink = CatalogueSink(inner, tmp_path, V)
    for part in np.array_split(np.arange(len(t)), 9):  # batches as the engine gives them: blocks 0-based, codes
        sink.events(t[part], block[part] - 1, codes[part], x[part])
    assert read_slip_events(tmp_path / "slip_events.csv")["start"].size == sink.writer.rows > 0  # flushed
    sink.close()
    expected, _ = group(events)
    written = read_slip_events(tmp_path / "slip_events.csv")
    assert all(written[name].tolist() == expected[name].tolist() for name in SLIP_EVENT_COLUMNS)
    assert inner.kinds() == kind.tolist() and inner.event_block.tolist() == (block - 1).tolist()
