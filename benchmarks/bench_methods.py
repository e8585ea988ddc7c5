"""AL (one Newton) vs Uzawa (nested loops) vs penalty on the Hertz problem (paper 3.2-3.3).

For each method and regularisation eps (multiples of E/h): Newton iterations,
linear solves (factorisations + back-substitutions) for the solution and for
one DDM parameter (R), wall time, peak-pressure error vs eq. 22, penetration,
and the error of the R-sensitivity of the multipliers against the exact (AL)
one. For Uzawa also the error left after truncating the sensitivity iteration
at 5 outer iterations. Prints a table and writes benchmarks/results/methods.csv.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from _report import report

import signorini as sg
from signorini.contact.uzawa import UzawaPenalty
from signorini.problems import hertz
from signorini.algorithms.uzawa import solve_uzawa

OPT = sg.NewtonOptions(rtol=1e-11)


def main():
    base = hertz.hertz_problem()
    an = hertz.analytical(1.2, 1.0, 100.0, 0.3)
    eps0 = base.params["eps"]
    sg.solve(base, sensitivities=["R"], options=OPT)  # compile
    ref = sg.solve(base, sensitivities=["R"], options=OPT)
    dlam_ref = ref.multiplier_sensitivity("R")[:, 0]
    rows = []
    c = base.contact[0]
    for f in (1.0, 10.0, 100.0):
        pb = base.with_params(eps=f * eps0)
        t0 = time.perf_counter()
        al = sg.solve(pb, sensitivities=["R"], options=OPT)
        t = time.perf_counter() - t0
        ct = al.contact()
        its = sum(al.newton_iterations)
        rows.append({"method": "AL (one Newton)", "eps/(E/h)": f, "outer": 1, "newton": its,
                     "linear_solves": its + 1 + 1, "time_s": t,
                     "p0_error": ct["p_N"].max() / an["p0"] - 1, "penetration": -min(ct["gap"].min(), 0),
                     "dlam_dR_error": np.abs(al.multiplier_sensitivity("R")[:, 0] - dlam_ref).max()
                     / np.abs(dlam_ref).max(), "dlam_dR_error_5_outer": float("nan")})
        pu = dataclasses.replace(pb, contact=(sg.Contact(c.obstacle, c.edges, UzawaPenalty("eps")),))
        solve_uzawa(pu, wrt=["R"], options=OPT, tol=1e-9)  # compile
        t0 = time.perf_counter()
        uz = solve_uzawa(pu, wrt=["R"], options=OPT, tol=1e-9)  # above the inner noise
        t = time.perf_counter() - t0
        errs = [np.abs(h - dlam_ref).max() / np.abs(dlam_ref).max() for h in uz.sens_history["R"]]
        rows.append({"method": "Uzawa (nested)", "eps/(E/h)": f, "outer": uz.outer_iterations[0],
                     "newton": sum(uz.newton_iterations), "linear_solves": uz.linear_solves,
                     "time_s": t, "p0_error": uz.pressure.max() / an["p0"] - 1, "penetration": 0.0,
                     "dlam_dR_error": errs[-1], "dlam_dR_error_5_outer": errs[min(4, len(errs) - 1)]})
        pp = hertz.hertz_problem(method="penalty").with_params(eps=f * eps0)
        sg.solve(pp, sensitivities=["R"], options=OPT)  # compile
        t0 = time.perf_counter()
        pe = sg.solve(pp, sensitivities=["R"], options=OPT)
        t = time.perf_counter() - t0
        cp = pe.contact()
        its = sum(pe.newton_iterations)
        dp = cp["dp_N_dR"]
        rows.append({"method": "penalty", "eps/(E/h)": f, "outer": 1, "newton": its,
                     "linear_solves": its + 1 + 1, "time_s": t,
                     "p0_error": cp["p_N"].max() / an["p0"] - 1, "penetration": -cp["gap"].min(),
                     "dlam_dR_error": np.abs(-dp - dlam_ref).max() / np.abs(dlam_ref).max(),
                     "dlam_dR_error_5_outer": float("nan")})
        print(f"eps = {f:g} E/h done", flush=True)
    report(rows, Path(__file__).parent / "results" / "methods.csv", width=16)


if __name__ == "__main__":
    main()
