"""Identify the yield stress and the hardening of a forged billet from its force-stroke curve.

A cylindrical billet (axisymmetric, finite-strain J2 plasticity with linear
hardening, F-bar) is upset between flat rigid dies with Coulomb friction by 30 %
of its height (signorini.problems.forging, a coarse 9 x 6 half model). The die
force along the stroke is the "measurement" (computed at sigma_y = 100, H = 1000
and perturbed by Gaussian noise of 1 % of its largest value). sg.fit identifies
sigma_y and H from 20-30 % off with the exact DDM Jacobian of the whole curve,
and gives their standard errors.

    python examples/fit_forging.py [OUTPUT_DIR]

Writes fit_forging.png (measured and fitted die force against the stroke, the
fitted values +- one standard error in the legend).
"""

import sys
from pathlib import Path

import numpy as np

import signorini as sg
from signorini.problems import forging


def main(out=".") -> dict:
    truth = {"sigma_y": 100.0, "H": 1000.0}
    problem = forging.forging_problem({**truth, "stroke": 0.3}, mesh=(9, 6))
    options = forging.options(rtol=1e-12)
    steps = 12
    force = sg.responses.contact_force(component=1)  # the die's axial force on the billet (< 0)
    exact = sg.solve(problem, steps=steps, options=options)
    t = np.array([inc.t for inc in exact.increments])  # load factors k / 12
    y = force.path(exact)
    sd = 0.01 * np.abs(y).max()
    measured = y + sd * np.random.default_rng(0).standard_normal(t.size)

    curve = sg.Curve(force, t, measured, weights=np.full(t.size, sd ** -2))
    result = sg.fit(problem, ["sigma_y", "H"], curve, start={"sigma_y": 80.0, "H": 1300.0},
                    bounds={"sigma_y": (10.0, 1000.0), "H": (0.0, 1e4)}, options=options)
    print(result)
    v, se = result.values, result.stderr

    import matplotlib  # noqa: PLC0415  (lazy: a figure at the end)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    stroke = t * problem.params["stroke"]
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    ax.plot(stroke, -measured, "o", label="measured (σy = 100, H = 1000, 1 % noise)")
    ax.plot(stroke, -result.fitted[0], "-",
            label=f"fitted: σy = {v['sigma_y']:.1f} ± {se['sigma_y']:.1f},\n"
                  f"            H = {v['H']:.0f} ± {se['H']:.0f}")
    ax.set_xlabel("stroke / initial height")
    ax.set_ylabel("die force")
    ax.set_xlim(0, None)
    ax.legend(loc="upper left", fontsize=8.5)
    ax.set_title("Force-stroke curve of an upset billet (J2, axisymmetric)", fontsize=9.5)
    fig.tight_layout()
    fig.savefig(Path(out) / "fit_forging.png", dpi=120)
    plt.close(fig)
    return {"truth": truth, "values": dict(v), "stderr": dict(se), "sigma": result.sigma,
            "n_solves": result.n_solves, "success": result.success}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
