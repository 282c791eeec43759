"""scripts/omsimulator_chain.py without OMSimulator (which CI cannot get): a fake result file in OMSimulator's MAT
layout is read back, its events found, and its comparison with the chain's reference gives the offset put in."""

import importlib.util
import re
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from oms_results import write_result

from stickslip.reference import ChainEvent, simulate_chain
from stickslip.systems.system_file import load_system

REPO = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("omsimulator_chain", REPO / "scripts" / "omsimulator_chain.py")
oms = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(oms)
ROOT = "chain2-coulomb.chain2-coulomb"


def _fake_columns(t, x):
    """Block columns of a run with positions ``x`` (times, 2): block 1 slips once at 0.05 s, block 2 never."""
    steps = len(t)
    slipped = (t > 0.05).astype(float)
    columns = {}
    for i in range(2):
        columns[f"{ROOT}.b{i + 1}.x"] = x[:, i]
        columns[f"{ROOT}.b{i + 1}.v"] = np.full(steps, 0.1)
        columns[f"{ROOT}.b{i + 1}.mode"] = slipped if i == 0 else np.zeros(steps)
        columns[f"{ROOT}.b{i + 1}.n_events"] = slipped if i == 0 else np.zeros(steps)
        columns[f"{ROOT}.b{i + 1}.t_last_event"] = 0.05 * slipped
    return columns


def test_the_result_file_is_read_back_with_its_events_and_the_repeated_stop_time_left_out(tmp_path):
    t = np.array([0.0, 0.1, 0.2 - 1e-12, 0.2, 0.2])
    x = np.column_stack([np.arange(5.0), 10.0 + np.arange(5.0)])
    columns = _fake_columns(t, x)
    columns["-" + f"{ROOT}.b2.v"] = columns.pop(f"{ROOT}.b2.v")
    write_result(tmp_path / "r.mat", t, columns, {f"{ROOT}.b1.M": 1.0})
    signals = oms.read_mat(tmp_path / "r.mat")
    assert signals[f"{ROOT}.b1.M"].tolist() == [1.0, 1.0]
    assert signals[f"{ROOT}.b2.v"].tolist() == [0.1] * 5
    read = oms.block_columns(signals, 2)
    assert read["time"].tolist() == [0.0, 0.1, 0.2]
    assert read["x"].tolist() == [[0.0, 10.0], [1.0, 11.0], [4.0, 14.0]]
    result = oms.to_result("oms-ma", read, np.array([0.0, 0.1, 0.2]), 1.0)
    assert result.events == [ChainEvent(0.05, 0, "slip", 0, 1)] and result.events_complete
    assert result.event_counts.tolist() == [1, 0]
    assert oms.to_result("oms-mav", read, np.array([0.0, 0.05, 0.2]), 1.0).t.tolist() == [0.0, 0.1, 0.2]
    with pytest.raises(RuntimeError, match="stopped at t = 0.2 s"):
        oms.to_result("oms-mav", read, np.array([0.0, 0.3]), 1.0)


def test_the_comparison_gives_the_offset_put_into_the_result_file(tmp_path):
    system = load_system(REPO / "systems" / "chain2-coulomb.toml")
    t = system.times()
    reference = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, t)
    write_result(tmp_path / "r.mat", t, _fake_columns(t, reference.x + np.array([0.0, 1e-3])))
    result = oms.to_result("oms-ma", oms.block_columns(oms.read_mat(tmp_path / "r.mat"), 2), t, 1.0)
    comparison = oms.measure(system, result)
    assert comparison.max_abs_dx.tolist() == pytest.approx([0.0, 1e-3], abs=1e-12)
    assert comparison.max_rel_dx == pytest.approx(1e-3 / reference.amplitude(), rel=1e-9)


def test_the_master_annotation_is_xml_that_names_the_master_and_its_steps():
    text = oms.master_annotation("mav", {"initialStepSize": 1e-3, "maximumStepSize": 0.1})
    namespaces = 'xmlns:ssd="s" xmlns:ssc="c" xmlns:oms="o"'
    root = ET.fromstring(text.replace("<ssd:Annotations>", f"<ssd:Annotations {namespaces}>", 1))
    master = root.find(".//{o}VariableStepMaster")
    assert master.attrib == {"description": "oms-mav", "initialStepSize": "0.001", "maximumStepSize": "0.1"}


def test_the_blocks_declared_output_order_is_all_the_copy_changes(fmu_path):
    original = Path(fmu_path).read_bytes()
    with zipfile.ZipFile(fmu_path) as archive:
        before = archive.read("modelDescription.xml").decode()
    with zipfile.ZipFile(__import__("io").BytesIO(oms.declared_output_order(original, 1))) as archive:
        after = archive.read("modelDescription.xml").decode()
    assert 'maxOutputDerivativeOrder="2"' in before
    assert after == before.replace('maxOutputDerivativeOrder="2"', 'maxOutputDerivativeOrder="1"')
