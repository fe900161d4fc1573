"""Natural frequencies of the Baud-Velex rig structure against ROSS (independent code).

What is compared: the shafts, discs, bearings and couplings of the Baud-Velex rig (the
structure of ``examples/rigs/baud_velex_spur.toml``, identical to the built-in rig),
without the pinion-gear element, which a single ROSS rotor does not have. Without the mesh
our ``(M, K)`` is block-diagonal, so its modes are the union of the pinion line's and the
gear line's; ROSS models each line as its own ``Rotor`` (non-rotating, speed 0, no damping,
no gyroscopic terms), built by :mod:`gearjax.rigs.ross_bridge` from the rig file itself.

Settings matched rather than tolerances widened (details in :mod:`gearjax.rigs.ross_bridge`):
ROSS computes its own Timoshenko shear coefficient (Cowper here) and takes no override, so
our shafts get ROSS's value through the rig file's ``shear_coefficient`` (with our default,
Hutchinson's 0.925 against Cowper's 0.886 for solid steel shafts, the two differ by up to
0.77 % at 9.2 kHz); ROSS bearings have no tilting or torsional stiffness, so the motor
support's tilt and the resisting-load torsional spring are grounded in ROSS through a
seismic node (1e9 kg, 1e9 kg m^2; perturbation ~1e-9 relative). Axial and torsional dofs
exist in both codes (6 dof per node).

The issue's criterion is 0.5 % for every mode below 10 kHz; the two models being the same
discretisation, they agree to ~1e-8, which the second assertion guards.
"""

import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ross")

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from gearjax.rigs.rigfile import load_rig, parse_rig  # noqa: E402
from gearjax.rigs import build_model  # noqa: E402
from gearjax.rigs.registry import get_rig  # noqa: E402
from gearjax.rigs.ross_bridge import (  # noqa: E402
    ross_natural_frequencies_hz,
    ross_rotors,
    ross_shear_coefficient,
)
from gearjax.structure import modal_basis  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "baud_velex_spur.toml"
F_MAX_HZ = 10_000.0


def _ours(shear_coefficient):
    data = tomllib.loads(EXAMPLE.read_text())
    for shaft in data["shaft"]:
        shaft["shear_coefficient"] = shear_coefficient
    s = parse_rig(data, source=str(EXAMPLE)).structure()
    f = modal_basis(s.M, s.K, warn=False).frequencies_hz
    return s, f[(f > 1.0) & (f < F_MAX_HZ)]


@pytest.mark.slow
def test_rig_natural_frequencies_match_ross_below_10kHz():
    load_rig(EXAMPLE)  # validates the file the ROSS model reads
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rotors = ross_rotors(EXAMPLE, shear_method="cowper")
        f_ross = np.sort(np.concatenate([ross_natural_frequencies_hz(r) for r in rotors.values()]))
    f_ross = f_ross[f_ross < F_MAX_HZ]
    # every shaft of the rig is solid, so one ROSS coefficient serves all elements
    kappa = ross_shear_coefficient(0.05, 0.0, nu=0.3, method="cowper")
    assert kappa == pytest.approx(6 * 1.3 / (7 + 6 * 0.3))  # Cowper (1966), solid circle
    structure, f_ours = _ours(kappa)
    # the same elements as the built-in rig (only the shear coefficient differs)
    def elements(s):
        return sorted((e.kind, e.nodes, e.params) for e in s.elements)

    assert elements(structure) == elements(get_rig("baud-velex-spur").structure())
    assert set(rotors) == {"pinion", "gear"}
    assert f_ours.size == f_ross.size > 90
    rel = np.abs(f_ours / f_ross - 1.0)
    assert rel.max() < 5e-3  # the criterion
    assert rel.max() < 1e-6  # same discretisation: agreement to round-off and the seismic mass


@pytest.mark.slow
def test_geared_rotor_natural_frequencies_match_ross_multirotor():
    """With the mesh: the pinion and gear lines coupled by ROSS's own gear element
    (``ross.MultiRotor``, Stringer's coupling matrix, built by
    :func:`gearjax.rigs.ross_bridge.ross_geared_rotor`) at our mean mesh stiffness k_m, against
    the modes of our 3D model's (M, K + k_m V V^T) (perfect spur gears, averaged V, all
    modes). Measured 2026-11-22: 102 modes below 10 kHz, max relative difference 5.5e-9.
    This checks our pinion-gear element (direction, base-radius arms, signs) against an
    independent one, not only the shafts."""
    from gearjax.rigs.ross_bridge import ross_geared_rotor

    kappa = ross_shear_coefficient(0.05, 0.0, nu=0.3, method="cowper")
    data = tomllib.loads(EXAMPLE.read_text())
    for shaft in data["shaft"]:
        shaft["shear_coefficient"] = kappa
    model = build_model(parse_rig(data, source=str(EXAMPLE)), None,
                                   formulation="reference", mesh_vectors="mean")
    f_ours = np.sort(np.asarray(model.omega_r)[: model.n_modes]) / (2 * np.pi)
    f_ours = f_ours[(f_ours > 1.0) & (f_ours < F_MAX_HZ)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mr, _ = ross_geared_rotor(EXAMPLE, float(model.k_m))
        modal = mr.run_modal(speed=0.0, num_modes=mr.ndof, sparse=False)
    f_ross = np.sort(np.abs(np.asarray(modal.wn))) / (2 * np.pi)
    f_ross = f_ross[(f_ross > 1.0) & (f_ross < F_MAX_HZ)]
    assert f_ours.size == f_ross.size > 90
    rel = np.abs(f_ours / f_ross - 1.0)
    assert rel.max() < 1e-6  # same discretisation and mesh spring: round-off and the seismic mass


@pytest.mark.slow
def test_geared_rotor_periodic_mesh_force_matches_ross_matrices():
    """The time response, not only the modes: gearjax's simulated dynamic factor (reference
    formulation, perfect spur gears, averaged V, zeta 0.1, 900 rad/s near the main critical
    speed) against the periodic orbit of ROSS's own assembled MultiRotor -- its modes and
    mesh participations phi^T c, modal damping 0.1 on every mode, our k(theta) -- computed
    exactly by shooting (:func:`gearjax.rigs.ross_bridge.periodic_mesh_force`: RK4 aligned on the
    stiffness jumps, monodromy matrix), so neither gearjax's integrator nor ROSS's Newmark
    is involved on the ROSS side. Also checks that the mesh participations of the coupled
    modes agree (mode shapes seen by the mesh, not only frequencies). Measured 2026-11-23:
    DF 1.684078 (gearjax) against 1.684066 (orbit, 512 steps; 1.684070 converged), 7e-6;
    participations to 1e-8; about 1 min on 2 loaded cores."""
    import jax.numpy as jnp

    from gearjax import ToothModifications, quasi_static
    from gearjax.rigs.ross_bridge import periodic_mesh_force, ross_geared_rotor, ross_mesh_modes
    from gearjax.dynamics.simulate import simulate

    zeta, speed = 0.1, 900.0
    kappa = ross_shear_coefficient(0.05, 0.0, nu=0.3, method="cowper")
    data = tomllib.loads(EXAMPLE.read_text())
    for shaft in data["shaft"]:
        shaft["shear_coefficient"] = kappa
    rig = parse_rig(data, source=str(EXAMPLE))
    model = build_model(rig, None, formulation="reference", damping_ratio=zeta,
                                   mesh_vectors="mean")
    k_m, f_s = float(model.k_m), float(model.static_force_N)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mr, _ = ross_geared_rotor(EXAMPLE, k_m)
    om, v, _, _ = ross_mesh_modes(mr)

    # same modes as seen by the mesh: frequencies and squared participations, the
    # (near-)degenerate pairs of the axisymmetric rig summed (their split is arbitrary)
    om_g, v_g = np.asarray(model.omega_r), np.asarray(model.v_r)
    assert model.n_static == 0 and om_g.size == om.size

    def clusters(o, p):
        order = np.argsort(o)
        o, p = o[order], p[order] ** 2
        edges = np.flatnonzero(np.diff(o) > 1e-6 * o[1:]) + 1
        return (np.array([g.mean() for g in np.split(o, edges)]),
                np.array([g.sum() for g in np.split(p, edges)]))

    (o1, p1), (o2, p2) = clusters(om_g, v_g), clusters(om, v)
    assert o1.size == o2.size
    np.testing.assert_allclose(o1, o2, rtol=1e-7)
    np.testing.assert_allclose(p1, p2, rtol=1e-6, atol=1e-9 * p1.max())

    def k_of(theta):
        return np.asarray(quasi_static(model.mesh, ToothModifications.none(), jnp.asarray(theta),
                                       f_s).loaded_stiffness_N_per_m)

    _, force = periodic_mesh_force(om, v, zeta, k_m, f_s, k_of, model.jump_thetas,
                                   rig.pair.mesh_period_rad, speed, steps=512)
    res = simulate(model, jnp.asarray(speed))
    assert bool(res.converged)
    assert float(res.dynamic_factor) == pytest.approx(force.max(), rel=5e-5)
