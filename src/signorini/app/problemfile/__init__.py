"""Problem description files: a contact problem, its solve and its outputs in TOML.

:func:`load` reads a file into a :class:`~signorini.model.problem.Problem` and a
:class:`RunConfig`; :func:`run` also solves it (with DDM sensitivities) and
writes the results into a directory; :func:`fit` identifies the parameters of
its ``[fit]`` section from measured curves (:func:`signorini.fit`).
``signorini run FILE --out DIR`` calls :func:`run`, ``signorini fit FILE --out
DIR`` :func:`fit`.

The full schema, with 3-D meshes (boxes, hexahedral and tetrahedral mesh files),
several bodies (``[[body]]``), 2-D and 3-D obstacles (implicit surfaces given by
an expression, parsed safely by :mod:`.expr`), obstacle motions along load
paths, two-body pairs (``[[pair]]``), the responses of :mod:`signorini.responses`
by name and fits: docs/problem-files.md. The modules: :mod:`.reader` (strict
tables, the key's line in every error), :mod:`.parts` (meshes, bodies,
materials, obstacles), :mod:`.schema` (the rest and :func:`load`),
:mod:`.fitfile` (``[fit]`` and its CSV files), :mod:`.run`, :mod:`.fitrun`.

The 2-D schema in short (the first example of docs/problem-files.md).

Example (``block.toml``: an elastic block pressed against a rigid cylinder,
half model with a symmetry line)::

    title = "block on a cylinder"

    [params]                 # named design parameters: derivatives are taken w.r.t. these
    E = 100.0
    nu = 0.3
    P = 2.0
    R = 20.0
    W = 2.0

    [mesh]                   # uniform nx x ny Q4 grid; or:  file = "body.msh"
    type = "rectangle"
    x = [0.0, "W"]           # a parameter name here makes W a shape parameter
    y = [-2.0, 0.0]
    nx = 32
    ny = 16

    [material]
    type = "linear_elastic"  # or "neo_hooke" (finite strain)
    E = "E"
    nu = "nu"

    [[fixed]]                # one table per prescribed displacement component
    set = "left"
    component = "x"          # 0 / 1 or "x" / "y"
    value = 0.0              # default 0

    [[load]]
    type = "pressure"        # or "traction" with value = [fx, fy]
    edges = "bottom"
    value = "P"
    resultant = true         # value is the resultant force (per unit thickness)

    [[contact]]
    edges = "top"
    obstacle = { type = "circle", radius = "R", centre = [0.0, "R"] }
    method = "al"            # "al" | "penalty" | "coulomb"
    # eps = 400.0            # default E/h (h: shortest contact edge); required for "penalty"
    # mu = 0.3               # "coulomb" only (required), with eps_t (default eps)
    # kinematics = "auto"    # "auto" | "linear" | "finite"

    [solve]
    steps = 2                # equal load increments (cut automatically on failure)
    sensitivities = ["R", "E", "W"]
    rtol = 1e-10             # Newton tolerances (signorini.NewtonOptions)
    max_iter = 25

    [[response]]             # scalar results with their sensitivities, in summary.json
    name = "p_max"
    type = "max_pressure"    # | "normal_force" | "displacement" | "reaction"
    surface = "top"          # contact edges (default: the first [[contact]])

    [output]
    vtu = true               # <stem>.vtu: last increment
    pvd = true               # <stem>.pvd + <stem>_0001.vtu, ... when there are several increments
    csv = true               # contact.csv (contact_1.csv, ... for further surfaces)

Schema (every key not listed is an error; "number" means a number or the
name of a parameter of ``[params]``, which makes it a design variable):

``title``
    optional string, copied to ``summary.json``.
``[params]``
    ``name = value`` (numbers). Parameter names used elsewhere must be defined
    here (:class:`~signorini.errors.UnknownParameterError` otherwise).
``[mesh]`` (required)
    either ``file = "body.msh"`` (relative to the TOML file; read by
    :func:`signorini.fem.meshfile.read_mesh`: gmsh physical groups of lines become edge
    and node sets, of points node sets, plus ``all``; a 2-D mesh of quadrilaterals,
    or a 3-D mesh: docs/problem-files.md), or
    ``type = "rectangle"``, ``x = [x0, x1]``, ``y = [y0, y1]`` (numbers),
    ``nx``, ``ny`` (cells, integers >= 1): sets ``left``, ``right``,
    ``bottom``, ``top`` (edges and nodes) and ``all`` (nodes). A parameter
    name among the corners makes that parameter a shape parameter (the exact
    design velocity of the uniform grid is supplied).
``[material]`` (required)
    ``type`` = ``"linear_elastic"`` | ``"neo_hooke"``, ``E``, ``nu`` (numbers).
``[[fixed]]``
    ``set`` (node set), ``component`` (0, 1, "x" or "y"), ``value`` (number,
    default 0; ramped with the load factor).
``[[load]]``
    ``type`` = ``"pressure"`` (``value``: number, positive pushes into the
    body) | ``"traction"`` (``value = [fx, fy]``), ``edges`` (edge set),
    ``resultant`` (bool, default false: value is the resultant force).
``[[contact]]``
    ``edges`` (edge set); ``obstacle`` = ``{type = "circle", radius, centre =
    [cx, cy], motion = [vx, vy]}`` or ``{type = "line", point = [x, y],
    normal = [nx, ny], motion = [vx, vy]}`` (normal points into the body;
    motion: displacement of the obstacle at t = 1, default [0, 0]);
    ``method`` = ``"al"`` (default) | ``"penalty"`` | ``"coulomb"``; ``eps``
    (> 0; default E/h with h the shortest edge of the surface, evaluated at the
    nominal values; required for ``"penalty"``, whose solution depends on it);
    ``mu`` (``"coulomb"`` only, required), ``eps_t`` (``"coulomb"`` only,
    default ``eps``); ``kinematics`` = ``"auto"`` | ``"linear"`` | ``"finite"``.
``[solve]``
    ``steps`` (int >= 1, default 1), ``sensitivities`` (list of parameter
    names), and the Newton options ``rtol``, ``atol``, ``max_iter``,
    ``max_cuts``, ``predictor`` (``"extrapolate"`` | ``"none"``), ``start``
    (``"auto"`` | ``"coarse"`` | ``"rest"``: the first increment's start),
    ``reuse_factor`` (``"auto"`` | ``"always"`` | ``"never"``) (defaults of
    :class:`~signorini.algorithms.newton.NewtonOptions`).
``[[response]]``
    ``name`` (unique), ``type``: one of :mod:`signorini.responses` by name
    (``contact_force``, ``contact_area``, ``pressure_norm``, ... docs/problem-files.md), or ``"max_pressure"`` (largest p_N of a surface,
    with its DDM sensitivity at that node) or ``"normal_force"`` (sum of p_N
    A_S over the surface) with optional ``surface`` (edges of a
    ``[[contact]]``, default the first); ``"displacement"`` (mean of a
    displacement component over a node set) or ``"reaction"`` (sum of the
    support reactions of a component over a node set; every DOF must be
    prescribed by ``[[fixed]]``; the force of the supports on the body) with
    ``set`` and ``component``.
``[output]``
    ``vtu``, ``pvd``, ``csv`` (bools, default true).

Outputs of :func:`run` in ``out``: ``summary.json`` (status, the failure
reason, parameters, mesh size, load factors and Newton iterations per
increment, warnings, responses and their sensitivities, per-surface contact
summary, files written), ``contact.csv`` per contact surface at the last
increment (``node, x_ref, y_ref, x, y, p_N, p_T, gap, dp_N_d<name>...``; with
friction also ``dp_T_d<name>``, ``status`` and ``slip``), ``<stem>.vtu`` (last
increment; ``<stem>`` is the TOML file's name without extension) and, when
there are several increments, the ParaView series ``<stem>.pvd``.

Every problem in the file is reported as :class:`~signorini.errors.InputError`
naming the file and the key, e.g. ``problem.toml: [material] unknown key
'Ee'; allowed: E, nu, type``.
"""

from .fitrun import fit
from .run import run
from .schema import Response, RunConfig, load

__all__ = ["Response", "RunConfig", "fit", "load", "run"]
