"""A derivative we print is the derivative a user measures: central differences
of the CSV files written by two CLI runs with R +- dR equal the DDM column that
the nominal run printed (the mesh must not follow the perturbed R)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from signorini.app.cli import main


def read(path):
    rows = list(csv.DictReader(open(path)))
    return {k: np.array([float(r[k]) if k != "status" else 0.0 for r in rows]) for k in rows[0]
            if k != "status"}


def cli_fd(tmp_path, command, R, rel, files, extra=()):
    dR = rel * R
    runs = {}
    for tag, value in (("0", R), ("p", R + dR), ("m", R - dR)):
        out = tmp_path / f"{command}-{tag}"
        argv = [command, "--out", str(out), "--no-fd", "-q", "--set", f"R={value!r}", *extra]
        assert main(argv) == 0
        runs[tag] = out
    s0 = json.loads((runs["0"] / "summary.json").read_text())
    sp = json.loads((runs["p"] / "summary.json").read_text())
    assert s0["mesh"] == sp["mesh"]  # the same mesh at R and R + dR
    out = []
    for f in files:
        c0, cp, cm = (read(runs[t] / f) for t in ("0", "p", "m"))
        assert np.array_equal(c0["x_ref"], cp["x_ref"]) and np.array_equal(c0["x_ref"], cm["x_ref"])
        out.append((c0, cp, cm, dR))
    return out


def compare(c0, cp, cm, dR, field, inner):
    fd = (cp[field] - cm[field]) / (2 * dR)
    ddm = c0[f"d{field}_dR"]
    return float(np.max(np.abs(fd[inner] - ddm[inner])) / np.max(np.abs(ddm[inner])))


def test_hertz_cli_finite_difference_equals_printed_ddm(tmp_path):
    """R = 1, dR = 1e-4 R (the step of the built-in check). Away from the contact
    edge x = a (where p_N is not differentiable), FD = DDM to 1e-5 relative."""
    ((c0, cp, cm, dR),) = cli_fd(tmp_path, "hertz", 1.0, 1e-4, ["contact.csv"])
    a = c0["x_ref"][c0["p_N"] > 0].max()
    inner = c0["x_ref"] < 0.9 * a
    err = compare(c0, cp, cm, dR, "p_N", inner)
    print(f"hertz: CLI FD vs DDM of p_N, max rel. diff. {err:.2e}")
    assert err < 1e-5


@pytest.mark.timeout(600)
def test_hertz_friction_cli_finite_difference_equals_printed_ddm(tmp_path):
    """R = 10, dR = 1e-5 R; p_N and p_T at P1, P2, P3 on x < 0.9 a. The runs use
    the default mesh and path (30 increments)."""
    res = cli_fd(tmp_path, "hertz-friction", 10.0, 1e-5,
                 ["contact_P1.csv", "contact_P2.csv", "contact_P3.csv"])
    for i, (c0, cp, cm, dR) in enumerate(res, start=1):
        a = c0["x_ref"][c0["p_N"] > 0].max()
        inner = c0["x_ref"] < 0.9 * a
        for field in ("p_N", "p_T"):
            err = compare(c0, cp, cm, dR, field, inner)
            print(f"hertz-friction P{i}: CLI FD vs DDM of {field}, max rel. diff. {err:.2e}")
            assert err < 1e-5
