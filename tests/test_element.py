"""Pinion-gear element: structure vectors obey rigid-body invariance and Eq. (8b)."""

import math

import numpy as np
import pytest

from gearjax.rigs.baud_velex import baud_velex_pair
from gearjax.gears.mesh import Mesh
from gearjax.structure.element import PinionGearElement

# node dof order (u, v, w, phi, psi, theta): translations along (z, s, t), rotations about (s, t, z)
def _node_dofs(trans_stz, rot_stz):
    t, r = np.asarray(trans_stz), np.asarray(rot_stz)
    return np.array([t[2], t[0], t[1], r[0], r[1], r[2]])


@pytest.fixture(params=[False, True], ids=["spur", "helical"])
def element(request):
    mesh = Mesh.build(baud_velex_pair(request.param), "iso6336", cells_per_line=6)
    return PinionGearElement.at_nodes(mesh, 12, 0, 1)


def test_torsional_components_are_eq_8b(element):
    p = element.mesh.pair
    v = np.asarray(element.cell_vectors(element.mesh.cells(0.1)))
    rb1, rb2 = p.base_radii_m
    np.testing.assert_allclose(v[:, 5], rb1 * math.cos(p.base_helix_angle_rad), rtol=1e-12)
    np.testing.assert_allclose(v[:, 11], rb2 * math.cos(p.base_helix_angle_rad), rtol=1e-12)
    # Eq. (50): restricted to torsion, V = cos(beta_b) W
    w = np.asarray(element.torsional_vector(5, 11))
    vbar = np.asarray(element.mean_vector())
    np.testing.assert_allclose(vbar[[5, 11]], math.cos(p.base_helix_angle_rad) * w[[5, 11]], rtol=1e-12)


def test_rigid_motion_of_both_bodies_gives_no_deflection(element):
    """A rigid translation or rotation of the pinion and gear together cannot deflect the
    mesh: V(M)^T X = 0 (the mesh force pair is self-equilibrated, Fig. A1)."""
    p = element.mesh.pair
    rb1, rb2 = p.base_radii_m
    o1o2 = np.array([p.line_of_action_length_m, -(rb1 + rb2), 0.0])  # in (s, t, z)
    v = np.asarray(element.cell_vectors(element.mesh.cells(0.37)))
    rng = np.random.default_rng(0)
    for _ in range(5):
        d, w = rng.normal(size=3), rng.normal(size=3)
        x_trans = np.concatenate([_node_dofs(d, 0 * d), _node_dofs(d, 0 * d)])
        x_rot = np.concatenate([_node_dofs(0 * w, w), _node_dofs(np.cross(w, o1o2), w)])
        np.testing.assert_allclose(v @ x_trans, 0.0, atol=1e-12)
        np.testing.assert_allclose(v @ x_rot, 0.0, atol=1e-12)


def test_pinion_rotation_gives_base_circle_approach(element):
    """A pinion torsion theta1 approaches the flanks by Rb1 cos(beta_b) theta1 at every cell."""
    p = element.mesh.pair
    x = np.zeros(12)
    x[5] = 1e-4
    v = np.asarray(element.cell_vectors(element.mesh.cells(0.2)))
    np.testing.assert_allclose(v @ x, p.base_radii_m[0] * math.cos(p.base_helix_angle_rad) * 1e-4)


def test_bad_nodes():
    mesh = Mesh.build(baud_velex_pair(False), "uniform", cells_per_line=1)
    with pytest.raises(ValueError, match="gear_node=5"):
        PinionGearElement.at_nodes(mesh, 24, 0, 5)
