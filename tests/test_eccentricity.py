"""Eccentricity on the command line (``--eccentricity E1[,E2]`` m, ``--eccentricity-phase``)
and the eccentricity terms of Eq. (14), against hand derivations.

Geometry (closed form): the centre of rigid gear k, eccentric by ``e_k`` with phase
``lambda_k``, moves on the line of action by ``e_k sin(phi_k - lambda_k)`` towards its mate
(``phi_1 = theta``, ``phi_2 = theta z1/z2`` the angles turned; the module convention of
:mod:`gearjax.gears.modifications`, excess ``e_k cos b_b sin(phi_k - lambda_k)`` along the
flank normal, i.e. ``e_k sin(phi_k - lambda_k)`` on the transverse base plane). Without
other errors every flank moves by that rigid shift, so the gaps are unchanged and the
no-load TE is the once-per-revolution sinusoid::

    NLTE(theta) = -e_1 sin(theta - lambda_1) - e_2 sin(theta z1/z2 - lambda_2)

(the flanks meet earlier), while ``TE_S - NLTE`` (the elastic approach) is the one of the
perfect gears.

Inertial terms (Eq. (14) with the gear speed of Eq. (4)): the mass centre of gear k at
``c_k = e_k (cos psi_k, sin psi_k)`` in (s, t), ``psi_1 = theta - lambda_1 - pi/2`` and
``psi_2 = lambda_2 - pi/2 - (Rb1 theta - NLTE) / Rb2`` (the gear turns backwards, Eq. (4)).
Its inertial load ``m_k c_k''`` (theta-derivatives, by central differences here) is
``NLTE'' E~ + NLTE' F~ + G~`` up to the ``NLTE'^2`` term that Eq. (14) neglects, with the
vectors at the rigid-body angle (exact where NLTE = 0, where it is checked).
"""

from __future__ import annotations

import argparse
import csv
import math

import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.cli.main import main
from gearjax.cli.scenario import eccentricity_of
from gearjax.errors import GearjaxError
from gearjax.structure.geared import Eccentricity

Z1, Z2 = 26, 157  # the Baud-Velex spur pair


def _csv(path):
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _run(tmp_path, name, *opts):
    path = tmp_path / f"{name}.csv"
    assert main(["quasistatic", "--relief", "none", "--positions", "8", "--csv", str(path),
                 "--json", *opts]) == 0
    return _csv(path)


@pytest.mark.parametrize("ecc,phase", [("20e-6", "0.3"), ("0,20e-6", "0,0.3")],
                         ids=["pinion", "gear"])
def test_quasistatic_nlte_is_the_once_per_revolution_sinusoid(tmp_path, capsys, ecc, phase):
    e = np.array([float(v) for v in ecc.split(",")] + [0.0])[:2]
    lam = np.array([float(v) for v in phase.split(",")] + [0.0])[:2]
    got = _run(tmp_path, "ecc", "--eccentricity", ecc, "--eccentricity-phase", phase)
    th = got["theta_rad"]
    # the span is a revolution of the eccentric body: z1 (pinion) or z2 (gear) mesh periods
    n_mesh = Z2 if e[1] > 0 else Z1
    assert th.max() == pytest.approx(2 * math.pi * n_mesh / Z1, rel=1e-2)
    want = -e[0] * np.sin(th - lam[0]) - e[1] * np.sin(th * Z1 / Z2 - lam[1])
    np.testing.assert_allclose(got["nlte_m"], want, rtol=0, atol=1e-12)
    # the elastic approach TE_S - NLTE is that of the perfect gears (one mesh period)
    perfect = _run(tmp_path, "perfect")

    def on_grid(d):  # the 8 grid angles per mesh period (not the two rows at each jump)
        k = d["theta_rad"] / (2 * math.pi / Z1 / 8)
        th, count = np.unique(d["theta_rad"], return_counts=True)
        single = np.isin(d["theta_rad"], th[count == 1])
        keep = (np.abs(k - np.round(k)) < 1e-6) & single
        return np.round(k[keep]).astype(int) % 8, (d["te_s_m"] - d["nlte_m"])[keep]

    k_p, x_p = on_grid(perfect)
    k_e, x_e = on_grid(got)
    assert k_e.size > 4 * n_mesh
    ref = dict(zip(k_p.tolist(), x_p.tolist()))
    np.testing.assert_allclose(x_e, [ref[k] for k in k_e.tolist()], rtol=1e-9)
    capsys.readouterr()


def test_eccentricity_local_vectors_against_the_mass_centre_acceleration():
    rb1, rb2 = 0.0626, 0.3785
    m = np.array([1.7, 60.0])
    e = np.array([15e-6, 25e-6])
    lam = np.array([0.4, -1.1])
    ecc = Eccentricity(jnp.asarray(m), jnp.asarray(e), jnp.asarray(lam))
    # NLTE = a (sin + cos - 1)(w theta): 0 at w theta = 2 pi k, where NLTE' = a w and NLTE'' =
    # -a w^2, so that the vectors at the nominal angle (Eq. (14)) are the exact ones there
    a, w = 2e-4, 50.0

    def centres(th):
        nl = a * (math.sin(w * th) + math.cos(w * th) - 1.0)
        p1 = th - lam[0] - math.pi / 2
        p2 = lam[1] - math.pi / 2 - (rb1 * th - nl) / rb2
        return np.array([e[0] * math.cos(p1), e[0] * math.sin(p1),
                         e[1] * math.cos(p2), e[1] * math.sin(p2)])

    def second(th, h):
        return (centres(th + h) - 2 * centres(th) + centres(th - h)) / h**2

    h = 2e-4
    for th in (2 * math.pi * k / w for k in (0, 6, 23)):
        # c'' by central differences with Richardson extrapolation (error O(h^4 w^4))
        acc = (4 * second(th, h / 2) - second(th, h)) / 3
        load = np.concatenate([m[0] * acc[:2], m[1] * acc[2:]])
        nl1, nl2 = a * w, -a * w**2
        e_loc, f_loc, g_loc = (np.asarray(v) for v in ecc.local_vectors(jnp.asarray(th), rb1, rb2))
        model = nl2 * e_loc + nl1 * f_loc + g_loc
        # the neglected NLTE'^2 term: -m2 e2 (NLTE'/Rb2)^2 (cos, sin) psi_2
        p2 = lam[1] - math.pi / 2 - rb1 * th / rb2
        neglected = -m[1] * e[1] * (nl1 / rb2) ** 2 * np.array([math.cos(p2), math.sin(p2)])
        # (v, w) of the pinion (dofs 1, 2) and of the gear (dofs 7, 8); the rest is zero
        got = model[[1, 2, 7, 8]]
        want = load - np.concatenate([np.zeros(2), neglected])
        for sl in (slice(0, 2), slice(2, 4)):  # pinion, gear: each to its own scale
            scale = np.max(np.abs(want[sl]))
            np.testing.assert_allclose(got[sl], want[sl], rtol=0, atol=1e-6 * scale)
        # the NLTE terms are not negligible at this amplitude: they are what is checked
        assert np.max(np.abs(nl2 * e_loc + nl1 * f_loc)) > 0.1 * np.max(np.abs(load[2:]))
        assert np.all(model[[0, 3, 4, 5, 6, 9, 10, 11]] == 0)
    # pinion e1 along the offset whose normal projection is the excess e1 sin(theta - lambda1)
    np.testing.assert_allclose(centres(0.9)[0], e[0] * math.sin(0.9 - lam[0]), rtol=1e-12)


@pytest.mark.parametrize("ecc,phase,msg", [
    ("-5e-6", None, ">= 0"), ("nan", None, "finite"), ("2e-3", None, "metres"),
    ("20", None, "20e-6"),  # issue 52: micrometres typed where metres are read
    ("1,2,3", None, "one or two"), ("abc", None, "one or two"), (None, "0.3", "needs"),
    ("5e-6", "x", "one or two")])
def test_bad_eccentricity_is_one_clear_error(ecc, phase, msg):
    args = argparse.Namespace(eccentricity=ecc, eccentricity_phase=phase)
    with pytest.raises(GearjaxError, match=msg):
        eccentricity_of(args)


def test_eccentricity_option_values_in_si():
    e, lam = eccentricity_of(argparse.Namespace(eccentricity="20e-6", eccentricity_phase=None))
    assert e.tolist() == [20e-6, 0.0] and lam.tolist() == [0.0, 0.0]
    e, lam = eccentricity_of(argparse.Namespace(eccentricity="0,12.5e-6", eccentricity_phase="0,1"))
    assert e.tolist() == [0.0, 12.5e-6] and lam.tolist() == [0.0, 1.0]
    assert main(["quasistatic", "--eccentricity", "-3"]) == 2
    assert main(["quasistatic", "--eccentricity", "20"]) == 2  # 20 m: micrometres typed


def test_eccentricity_option_is_named_as_the_source(tmp_path, capsys):
    # issue 52: the header called a command-line eccentricity a rig-file value
    rig = tmp_path / "rig.toml"
    from pathlib import Path

    example = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "baud_velex_spur.toml"
    rig.write_text(example.read_text())
    capsys.readouterr()
    assert main(["quasistatic", "--rig", str(rig), "--positions", "8", "--json",
                 "--eccentricity", "20e-6"]) == 0
    import json

    s = json.loads(capsys.readouterr().out)
    assert s["relief_source"] == "rig file [modifications] with --eccentricity"
    assert s["eccentricity_m"] == [20e-6, 0.0]
