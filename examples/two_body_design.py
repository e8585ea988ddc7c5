"""Design the radius of one of two elastic spheres so that the peak contact
pressure meets a target (3-D, two deformable bodies, mortar contact).

The upper sphere's radius R2 is a shape parameter of its mesh: the mesh is
built once, at R2 = 1, and moves along the design velocity dX/dR2 there, so
that a design R2 is the sphere of that radius to first order (its curvature at
the axis is 1 - (R2 - 1) = 2 - R2, where a sphere's is 1 / R2). The peak
pressure is measured by a smooth proxy, the area-weighted 8-norm of the
pressure (sg.responses.pressure_norm), and the squared relative distance to
the target is minimised with its exact DDM gradient. Hertz's theory predicts
the answer: the proxy scales as p0 a^(2/8) ~ k^(7/12) with the curvature sum
k = 1/R1 + (2 - R2).

    python examples/two_body_design.py [OUTPUT_DIR]

Writes two_body_design.png (the pressure before and after, with Hertz's).
"""

import sys
from pathlib import Path

import numpy as np

import signorini as sg
from signorini.problems.spheres import analytical, spheres_problem

GOAL = 0.85  # the target: this fraction of the starting peak


def main(out=".") -> dict:
    problem = spheres_problem({"R2": 1.0}, n_fine=6)
    peak = sg.responses.pressure_norm(order=8)
    start = sg.solve(problem)
    target = GOAL * peak(start)

    def distance(model):
        fn = peak(model)
        return lambda w, p, t, s: (fn(w, p, t, s) / target - 1.0) ** 2
    objective = sg.Objective(problem, ["R2"], sg.responses.Response("peak-target", distance))
    result = sg.minimize(objective, [1.0], method="L-BFGS-B", bounds=[(0.6, 4.0)], gtol=1e-10)
    R2 = float(result.x[0])
    final = sg.solve(problem.with_params(R2=R2))
    R1 = problem.params["R1"]
    k = (1.0 / R1 + 1.0) * GOAL ** (12.0 / 7.0)  # Hertz: the norm ~ k^(7/12)
    R2_hertz = 2.0 - (k - 1.0 / R1)

    import matplotlib  # noqa: PLC0415  (lazy: a figure at the end)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, ax = plt.subplots(figsize=(5, 3.6))
    for sol, r2, colour in ((start, 1.0, "C0"), (final, R2, "C1")):
        c = sol.contact()
        r = np.hypot(c["x_ref"][:, 0], c["x_ref"][:, 1])
        ax.plot(r, c["p_N"], "o", ms=3, color=colour, label=f"R2 = {r2:.3f}")
        v = {n: sol.params[n] for n in ("P", "R1", "E1", "E2", "nu1", "nu2")}
        h = analytical(R2=1.0 / (2.0 - r2), **v)  # the cap's radius of curvature
        rr = np.linspace(0.0, h["a"], 100)
        ax.plot(rr, h["p0"] * np.sqrt(1.0 - (rr / h["a"]) ** 2), "-", lw=1, color=colour)
    ax.set_xlabel("distance from the axis r [mm]")
    ax.set_ylabel("contact pressure [N/mm²]")
    ax.set_xlim(0.0, 1.6 * analytical(**{k: start.params[k] for k in
                                         ("P", "R1", "R2", "E1", "E2", "nu1", "nu2")})["a"])
    ax.legend(title=f"nodes and Hertz; target norm {target:.3f}", loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(Path(out) / "two_body_design.png", dpi=120)
    plt.close(fig)
    print(f"R2 = {R2:.5f} (Hertz's scaling: {R2_hertz:.5f}): peak norm {peak(final):.6f} "
          f"(target {target:.6f}) in {result.nit} iterations")
    return {"R2": R2, "R2_hertz": R2_hertz, "peak": peak(final), "target": target}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
