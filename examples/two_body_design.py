"""Design the radius of one of two elastic cylinders so that the peak contact
pressure meets a target (2-D, two deformable bodies, mortar contact).

The upper cylinder's radius R2 is a shape parameter of its mesh; the peak
pressure is measured by a smooth proxy (the area-weighted 8-norm of the
pressure, sg.responses.pressure_norm), and the squared distance to the target
is minimised with its exact DDM gradient.

    python examples/two_body_design.py [OUTPUT_DIR]

Writes two_body_design.png (the pressure before and after).
"""

import sys
from pathlib import Path

import numpy as np

import signorini as sg
from signorini.problems.cylinders import cylinders_problem


def main(out=".") -> dict:
    problem = cylinders_problem({"R2": 1.0}, n_fine=12)
    peak = sg.responses.pressure_norm(order=8)
    start = sg.solve(problem)
    target = 0.8 * peak(start)

    def distance(model):
        fn = peak(model)
        return lambda w, p, t, s: (fn(w, p, t, s) / target - 1.0) ** 2
    objective = sg.Objective(problem, ["R2"], sg.responses.Response("peak-target", distance))
    result = sg.minimize(objective, [1.0], method="L-BFGS-B", bounds=[(0.6, 3.0)], gtol=1e-10)
    R2 = float(result.x[0])
    final = sg.solve(problem.with_params(R2=R2))

    import matplotlib  # noqa: PLC0415  (lazy: a figure at the end)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, ax = plt.subplots(figsize=(5, 3.6))
    for sol, label in ((start, "R2 = 1"), (final, f"R2 = {R2:.3f}")):
        c = sol.contact()
        order = np.argsort(c["x_ref"][:, 0])
        ax.plot(c["x_ref"][order, 0], c["p_N"][order], "o-", ms=3, label=label)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("contact pressure [N/mm²]")
    ax.set_xlim(-0.15, 0.15)
    ax.legend(title=f"target peak norm {target:.3f}")
    fig.tight_layout()
    fig.savefig(Path(out) / "two_body_design.png", dpi=120)
    plt.close(fig)
    print(f"R2 = {R2:.5f}: peak norm {peak(final):.6f} (target {target:.6f}) in {result.nit} iterations")
    return {"R2": R2, "peak": peak(final), "target": target}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
