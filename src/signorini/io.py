"""Writing results: VTU for ParaView (meshio), CSV tables, JSON summaries."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import meshio
import numpy as np


def _vec3(a):
    a = np.asarray(a, dtype=float)
    return np.column_stack([a, np.zeros(len(a))])


def write_vtu(solution, path, i: int = -1) -> Path:
    """Write one increment as VTU: displacement, contact pressure and multipliers
    (point data), Cauchy stress (cell data), and the sensitivity of each of them
    with respect to every design parameter (``d<field>_d<name>``)."""
    path = Path(path)
    m = solution.model
    X = solution.reference()
    point = {"displacement": _vec3(solution.displacement(i))}
    for name in solution.names:
        point[f"ddisplacement_d{name}"] = _vec3(solution.displacement_sensitivity(name, i))
    for k in range(len(m.surfaces)):
        c = solution.contact(i, k)
        tag = "" if k == 0 else f"_{k}"
        for key in ["p_N", "p_T", "gap"] + [f for f in c if f.startswith(("dp_", "dgap_"))]:
            arr = np.zeros(m.n_nodes)
            arr[c["node"]] = c[key]
            point[key + tag] = arr
    stress, dstress = solution.stress(i)
    cell = {"cauchy_stress": [stress.reshape(-1, 9)]}
    for name, d in dstress.items():
        cell[f"dcauchy_stress_d{name}"] = [np.asarray(d).reshape(-1, 9)]
    mesh = meshio.Mesh(_vec3(X), [("quad", m.conn)], point_data=point, cell_data=cell)
    mesh.write(path)
    return path


def write_csv(path, columns: dict) -> Path:
    """Write equal-length 1-D arrays (or lists) as CSV columns, header = keys."""
    path = Path(path)
    keys = list(columns)
    rows = zip(*[columns[k] for k in keys])
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(keys)
        for r in rows:
            wr.writerow([v if isinstance(v, str) else f"{float(v):.12g}" for v in r])
    return path


def write_json(path, data: dict) -> Path:
    path = Path(path)

    def conv(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(type(o))

    path.write_text(json.dumps(data, indent=2, default=conv) + "\n")
    return path
