"""What a component must provide (signorini.interfaces): the built-in components
satisfy their protocols, and a component of one's own that lacks a member is
refused when the Problem is made, with the missing members named."""

from __future__ import annotations

import dataclasses

import pytest

import signorini as sg
from signorini import interfaces as itf
from signorini.problems import hertz


@pytest.mark.parametrize("obj,proto", [
    (sg.LinearElastic(), itf.Material), (sg.NeoHooke(), itf.Material), (sg.J2Plasticity(), itf.Material),
    (sg.AugmentedLagrangian(), itf.ContactLaw), (sg.Penalty(), itf.ContactLaw), (sg.Coulomb(), itf.ContactLaw),
    (sg.Circle(), itf.Obstacle), (sg.Line(), itf.Obstacle),
    (sg.PlaneStrain(), itf.Kinematics), (sg.Axisymmetric(), itf.Kinematics),
    (sg.Standard(), itf.ElementFormulation), (sg.FBar(), itf.ElementFormulation)])
def test_built_in_components_satisfy_their_protocols(obj, proto):
    itf.require(obj, proto, "component")
    assert isinstance(obj, proto)


def test_optional_capabilities_are_none_where_absent():
    assert sg.LinearElastic().yield_ratio is None and sg.J2Plasticity().yield_ratio is not None
    assert sg.AugmentedLagrangian().status is None and sg.Coulomb().status is not None
    assert sg.AugmentedLagrangian().driver is None and not sg.AugmentedLagrangian().has_history


class HalfMaterial:
    """A material of one's own that forgot most of the protocol."""

    n_state = 0

    def update(self, H, h_n, mp):
        return H, h_n


def test_a_component_missing_members_is_refused_with_their_names():
    pb = hertz.hertz_problem(n_fine=8)
    with pytest.raises(sg.InputError, match=r"material HalfMaterial does not provide .*finite_strain.*values"):
        dataclasses.replace(pb, material=HalfMaterial())
    c = pb.contact[0]
    with pytest.raises(sg.InputError, match=r"obstacle object does not provide .*gap"):
        dataclasses.replace(pb, contact=(sg.Contact(object(), c.edges, c.method),))


def test_public_names_cover_2d_axisymmetric_and_3d_problems():
    """What a user needs to build, solve, differentiate and optimise a 2-D, an
    axisymmetric and a 3-D problem is a name of ``signorini`` (in ``__all__``, resolved
    lazily to the class or function of the module that defines it), not a
    submodule's."""
    from signorini.contact import obstacles, obstacles3d
    from signorini.design import optimize
    from signorini.fem import kinematics, mesh, mesh3d, meshfile

    expected = {
        "Mesh": mesh, "rectangle": mesh, "merge": mesh, "read_mesh": meshfile,
        "PlaneStrain": kinematics, "Axisymmetric": kinematics, "Circle": obstacles, "Line": obstacles,
        "Mesh3D": mesh3d, "box": mesh3d, "tetrahedra": mesh3d,
        "Plane": obstacles3d, "Sphere": obstacles3d, "Cylinder": obstacles3d, "Implicit": obstacles3d,
        "Objective": optimize, "minimize": optimize,
    }
    for name, module in expected.items():
        assert name in sg.__all__, name
        assert getattr(sg, name) is getattr(module, name), name
    assert len(set(sg.__all__)) == len(sg.__all__)
    for name in sg.__all__:
        assert getattr(sg, name) is not None, name
    # the 3-D pieces fit together through the public names alone
    part = sg.tetrahedra(sg.box([0.0, 1.0], [0.0, 1.0], [-1.0, 0.0]))
    assert isinstance(part, sg.Mesh3D) and part.n_cells == 6
    for tool in (sg.Plane(), sg.Sphere(), sg.Cylinder(), sg.Implicit(lambda y, p: y[2])):
        itf.require(tool, itf.Obstacle, "obstacle")
