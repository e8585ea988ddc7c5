"""A ball pressed into a slab and then dragged along it, with Coulomb friction (3-D).

The ball moves along two legs of its path: down by d over the first half of
the load factor, then along x by s over the second. The contact force on the
slab along the path and its exact sensitivity to the friction coefficient
(DDM, carried through the stick-slip history) are plotted; at the end the
drag is mu times the load (gross sliding).

    python examples/press_then_slide.py [OUTPUT_DIR]

Writes press_then_slide.png.
"""

import sys
from pathlib import Path

import numpy as np

import signorini as sg


def main(out=".") -> dict:
    press, slide = sg.Ramp(0.0, 0.5), sg.Ramp(0.5, 1.0)
    ball = sg.Sphere(radius="R", centre=(0.5, 0.0, lambda p: p["R"]),
                     motion=(((0.0, 0.0, lambda p: -p["d"]), press), ((lambda p: p["s"], 0.0, 0.0), slide)))
    slab = sg.box(np.linspace(0, 1, 21), np.linspace(-0.5, 0.5, 21), np.linspace(-0.3, 0, 4))
    problem = sg.Problem(
        mesh=slab, material=sg.LinearElastic(),
        params={"E": 100.0, "nu": 0.3, "R": 0.5, "d": 0.02, "s": 0.05, "mu": 0.3, "eps": 1000.0},
        fixed=[sg.Fixed("z0", k) for k in range(3)],
        contact=[sg.Contact(ball, "z1", sg.Coulomb(mu="mu", eps_n="eps", eps_t="eps"))])
    sol = sg.solve(problem, steps=12, wrt=["mu"])
    drag, load = sg.responses.contact_force(component=0), sg.responses.contact_force(component=2)
    t = np.array([inc.t for inc in sol.increments])
    fx = [drag.of(sol, i) for i in range(len(t))]
    F_x = np.array([v for v, _ in fx])
    dF_x = np.array([d["mu"] for _, d in fx])
    F_z = load.path(sol)

    import matplotlib  # noqa: PLC0415  (lazy: a figure at the end)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.plot(t, -F_z, "o-", label="load $-F_z$")
    ax.plot(t, F_x, "s-", label="drag $F_x$")
    ax.plot(t, dF_x, "^--", label=r"$\partial F_x/\partial\mu$ (DDM)")
    ax.axvline(0.5, color="0.7", lw=0.8)
    ax.set_xlabel("load factor t (press, then slide)")
    ax.set_ylabel("force on the slab [N]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(Path(out) / "press_then_slide.png", dpi=120)
    plt.close(fig)
    ratio = F_x[-1] / -F_z[-1]
    print(f"at the end: drag {F_x[-1]:.5f}, load {-F_z[-1]:.5f}, ratio {ratio:.4f} (mu = 0.3); "
          f"dF_x/dmu {dF_x[-1]:.5f}")
    return {"ratio": ratio, "dF_x": dF_x[-1], "F_z": F_z[-1]}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
