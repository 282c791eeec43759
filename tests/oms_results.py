"""Result files as OMSimulator writes them, for the tests of its by-hand scripts (scripts/omsimulator_*.py)."""

import numpy as np
import scipy.io


def write_result(path, t, columns, parameters=None):
    """An OpenModelica MAT v4 result file as OMSimulator writes it (``binTrans``): ``columns`` {name: values over
    ``t``} in ``data_2`` (a name starting with "-" is stored negated, its dataInfo index negative), ``parameters``
    {name: value} in ``data_1``."""
    parameters = parameters or {}
    names = ["time", *parameters, *(name.lstrip("-") for name in columns)]
    info = [[0, 1, 0, -1]] + [[1, k + 2, 0, 0] for k in range(len(parameters))]
    rows = [np.asarray(t, float)]
    for k, (name, values) in enumerate(columns.items()):
        sign = -1 if name.startswith("-") else 1
        info.append([2, sign * (k + 2), 0, -1])
        rows.append(sign * np.asarray(values, float))
    width = max(map(len, names))
    chars = np.ascontiguousarray(np.array([list(name.ljust(width)) for name in names]).T)
    data_1 = np.array([[t[0], t[-1]]] + [[v, v] for v in parameters.values()])
    scipy.io.savemat(path, {"Aclass": np.array([list("Atrajectory"), list("1.1        "), list("           "),
                                                list("binTrans   ")]),
                            "name": chars, "description": chars, "dataInfo": np.array(info, float).T,
                            "data_1": data_1, "data_2": np.array(rows)}, format="4")
