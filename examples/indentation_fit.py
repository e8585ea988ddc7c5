"""Identify a block's Young's modulus from a measured indentation curve (3-D).

A rigid sphere is pushed into an elastic block by a prescribed depth; the force
on the sphere along the path is the "measurement" (here computed at E = 100 and
perturbed by 0.5 % noise). The modulus is fitted by minimising the misfit of
the whole force history, with its exact DDM gradient through the contact.

    python examples/indentation_fit.py [OUTPUT_DIR]

Writes indentation_fit.png (measured and fitted force against depth).
"""

import sys
from pathlib import Path

import numpy as np

import signorini as sg


def main(out=".") -> dict:
    ball = sg.Sphere(radius="R", centre=(0.0, 0.0, lambda p: p["R"]),
                     motion=(0.0, 0.0, lambda p: -p["d"]))
    block = sg.box(np.linspace(0, 0.6, 13), np.linspace(0, 0.6, 13), np.linspace(-0.6, 0, 7))
    problem = sg.Problem(
        mesh=block, material=sg.LinearElastic(),
        params={"E": 100.0, "nu": 0.3, "R": 1.0, "d": 0.02, "eps": 2000.0},
        fixed=[sg.Fixed("z0", 2), sg.Fixed("x0", 0), sg.Fixed("y0", 1)],  # a quarter, on symmetry planes
        contact=[sg.Contact(ball, "z1", sg.AugmentedLagrangian(eps="eps"))])
    steps = 5
    force = sg.responses.contact_force(component=2)  # on the block (negative: pushed down)
    truth = sg.solve(problem, steps=steps)
    t = np.array([inc.t for inc in truth.increments])
    rng = np.random.default_rng(0)
    measured = force.path(truth) * (1 + 0.005 * rng.standard_normal(t.size))

    fit = sg.responses.misfit(force, t, measured, weights=1 / measured ** 2)
    objective = sg.Objective(problem.with_params(E=60.0), ["E"], fit, steps=steps, increments="all")
    result = sg.minimize(objective, [60.0], method="L-BFGS-B", bounds=[(10.0, 1000.0)])
    E = float(result.x[0])
    fitted = force.path(sg.solve(problem.with_params(E=E), steps=steps))

    import matplotlib  # noqa: PLC0415  (lazy: a figure at the end)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    depth = t * problem.params["d"]
    fig, ax = plt.subplots(figsize=(5, 3.6))
    ax.plot(depth, -4 * measured, "o", label="measured (E = 100, 0.5 % noise)")
    ax.plot(depth, -4 * fitted, "-", label=f"fitted, E = {E:.2f}")
    ax.set_xlabel("depth [mm]")
    ax.set_ylabel("indentation force [N]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(Path(out) / "indentation_fit.png", dpi=120)
    plt.close(fig)
    print(f"E fitted {E:.3f} (true 100) in {result.nit} iterations, {result.n_solves} solves")
    return {"E": E, "nit": result.nit}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
