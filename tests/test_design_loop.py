"""Designs as data (issue 51): the traced output grid against the NumPy one, padded jump sets
inert, one program for every relief (the notebook loop), the traced build against the host
build, implicit shooting gradients against central differences, the robust orbit set, and
the Harris map against the optimiser."""

from __future__ import annotations

import collections
import types
import math

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.design import (DynamicObjective, OrbitSet, ReliefSpace, harris_map,
                            optimise)
from gearjax.dynamics import grid as grids
from gearjax.dynamics.integrate import PeriodicJumpController
from gearjax.dynamics.metrics import jump_clusters, output_grid
from gearjax.dynamics.orders import mesh_order_amplitudes, order_matrix
from gearjax.dynamics.simulate import simulate
from gearjax.dynamics.steady import Shooting
from gearjax.dynamics.sweep import sweep
from gearjax.excitation.jumps import JumpSet
from gearjax.gears.mesh import Mesh
from gearjax.gears.modifications import ToothModifications
from gearjax.models.torsional import TorsionalModel
from gearjax.rigs.registry import get_rig

RIG = get_rig("baud-velex-spur")


@pytest.fixture(scope="module")
def mesh_iso():
    return Mesh.build(RIG.pair, "iso6336")


def _random_jumps(rng, period, n):
    """Sorted distinct angles in [0, period), two of them a cluster (1e-4 apart) and one
    at 0 (the grid's wrap)."""
    j = np.sort(rng.uniform(0.05, 0.95, n - 3)) * period
    return np.sort(np.concatenate([[0.0], j, [j[1] + 1e-4 * period, 0.99 * period]]))


@pytest.mark.parametrize("bound_extra", [0, 5])
def test_traced_grid_equals_the_numpy_grid(bound_extra):
    """The output grid built in the program from a padded jump set
    (:mod:`gearjax.dynamics.grid`) has exactly the points of
    :func:`gearjax.dynamics.metrics.output_grid` (valid first, padding after), the jump
    clusters of :func:`jump_clusters` and the mesh orders of :func:`order_matrix` (an
    independent construction: the DFT matrix with its jump corrections), whatever the
    padding."""
    rng = np.random.default_rng(3)
    period, n_samples = 1.0, 32
    angles = _random_jumps(rng, period, 9)
    js = JumpSet.from_angles(angles, period, bound=angles.size + bound_extra)
    ref = output_grid(period, n_samples, angles, 1)
    pg = grids.period_grid(period, n_samples, js)
    nv = int(pg.n_valid)
    assert nv == ref.offsets.size
    np.testing.assert_array_equal(np.asarray(pg.offsets)[:nv], ref.offsets)
    np.testing.assert_array_equal(np.asarray(pg.mid), np.nonzero(ref.samples)[0])
    cl = grids.jump_clusters(pg, period, n_samples, js)
    rc = jump_clusters(ref, period, angles)
    n_c = int(cl.count)
    assert n_c == rc.after.size
    np.testing.assert_array_equal(np.asarray(cl.before)[:n_c], rc.before)
    np.testing.assert_array_equal(np.asarray(cl.after)[:n_c], rc.after)
    # a signal with jumps at every angle and smooth harmonics: orders equal to 1e-12
    t = np.asarray(pg.offsets)
    steps = (np.mod(t[:, None] - angles[None, :], period) < 0.5 * period).sum(axis=1)
    vals = np.stack([np.cos(2 * math.pi * 3 * t) + 0.1 * steps, np.sin(2 * math.pi * t)], 1)
    got = np.asarray(grids.order_amplitudes(pg, js, period, period, n_samples,
                                            vals[None], 5))
    want = np.asarray(mesh_order_amplitudes(order_matrix(period, period, n_samples, angles),
                                            vals[None, :nv]))
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


def test_padding_changes_no_jump_of_the_controller():
    """The jump-aware step-size controller finds the same next jump in a padded jump set
    (the last angle repeated) as in the unpadded one, at every position of a period."""
    rng = np.random.default_rng(5)
    period = 2.0
    angles = _random_jumps(rng, period, 7)
    pid = diffrax.PIDController(rtol=1e-7, atol=1e-9)
    plain = PeriodicJumpController(pid, jnp.asarray(angles), period)
    padded = PeriodicJumpController(
        pid, JumpSet.from_angles(angles, period, bound=angles.size + 6).thetas, period)
    ts = jnp.asarray(np.concatenate([rng.uniform(-3, 7, 400), angles, angles + period,
                                     np.nextafter(angles, -np.inf)]))
    a = jax.vmap(plain._next_jump)(ts)
    b = jax.vmap(padded._next_jump)(ts)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def _count_compilations():
    counts = collections.Counter()

    def listen(event, duration, **kw):
        counts[event] += 1

    jax.monitoring.register_event_duration_secs_listener(listen)
    return counts


def test_notebook_loop_compiles_once(mesh_iso):
    """A notebook's loop, build_model(relief A) -> sweep -> build_model(relief B) -> sweep:
    the second build and sweep trace and compile nothing, though B has another number of
    switching events (5 against 6) and NLTE where A has none (nlte_terms resolved in the
    program), and B's results are those of a fresh process's (independent: the same
    physics, built and compiled for B alone, would differ only by round-off)."""
    speeds = np.array([300.0, 700.0])
    a = TorsionalModel.build(mesh_iso, ToothModifications.tip_relief(13.3e-6, 0.2),
                             formulation="te")
    ra = sweep(a, speeds)
    counts = _count_compilations()
    b = TorsionalModel.build(mesh_iso, ToothModifications.tip_relief(10e-6, 0.35),
                             formulation="te")
    rb = sweep(b, speeds)
    traced = counts["/jax/core/compile/jaxpr_trace_duration"]
    compiled = counts["/jax/core/compile/backend_compile_duration"]
    assert (traced, compiled) == (0, 0)
    assert len(a.jump_thetas) == 6 and len(b.jump_thetas) == 5
    assert not a.nlte_terms and b.nlte_terms
    assert np.all(ra.converged) and np.all(rb.converged)
    assert not np.allclose(ra.max_mesh_force_N, rb.max_mesh_force_N, rtol=1e-3)


def test_traced_build_names_the_host_build_events(mesh_iso):
    """The build traced inside a program (vmapped over designs) finds the jump angles,
    their kinds and cells and the table of the host build (NumPy classification) at every
    design: two rules written apart, one result."""
    designs = np.array([[13.3e-6, 0.2], [20e-6, 0.21], [10e-6, 0.35], [30e-6, 0.6]])

    @jax.jit
    def traced(xs):
        def one(x):
            m = TorsionalModel.build(mesh_iso, ToothModifications.tip_relief(x[0], x[1]),
                                     formulation="te")
            return m.jumps, m.table.values, m.structure_ok
        return jax.vmap(one)(xs)

    jumps, values, ok = traced(jnp.asarray(designs))
    for i, x in enumerate(designs):
        host = TorsionalModel.build(mesh_iso, ToothModifications.tip_relief(*x),
                                    formulation="te")
        n = int(jumps.count[i])
        assert bool(ok[i]) and n == len(host.jump_thetas)
        # two programs: the angles agree to round-off, the events exactly
        np.testing.assert_allclose(np.asarray(jumps.thetas[i])[:n], host.jump_thetas,
                                   rtol=0, atol=1e-13)
        assert tuple(np.asarray(jumps.kinds[i])[:n].tolist()) == host.jump_kinds
        np.testing.assert_allclose(np.asarray(values[i]), np.asarray(host.table.values),
                                   rtol=1e-12, atol=1e-30)


N_ANGLES = 7  # the switching angles of the relief below


def test_traced_build_differentiates_like_the_mapped_model(mesh_iso):
    """jax.jacfwd of "build the model from the relief, take its mean stiffness and its
    switching angles" (the build traced) equals the derivative of the model built at the
    design and mapped by with_modifications (the angle map's implicit derivative), and both
    equal the central differences of host builds."""
    # (an extent of 0.5 would put the pinion's and the gear's relief starts at one angle)
    x0, h = np.array([13.3e-6, 0.45]), np.array([2e-9, 2e-5])

    def built(x):
        m = TorsionalModel.build(mesh_iso, ToothModifications.tip_relief(x[0], x[1]),
                                 formulation="te")
        return jnp.concatenate([m.k_m[None], m.jump_angles_rad()[:N_ANGLES]])

    base = TorsionalModel.build(mesh_iso, ToothModifications.tip_relief(*x0), formulation="te")

    def mapped(x):
        m = base.with_modifications(ToothModifications.tip_relief(x[0], x[1]))
        return jnp.concatenate([m.k_m[None], m.jump_angles_rad()[:N_ANGLES]])

    d_built = np.asarray(jax.jit(jax.jacfwd(built))(jnp.asarray(x0)))
    d_mapped = np.asarray(jax.jacfwd(mapped)(jnp.asarray(x0)))
    np.testing.assert_allclose(d_built, d_mapped, rtol=1e-9, atol=1e-12 * np.abs(d_mapped).max())
    for i in range(2):  # the switching angles (k_m's difference quotient also carries the
        e = np.zeros(2)  # change of the table's knots between the two builds)
        e[i] = h[i]
        fd = (np.asarray(built(x0 + e))[1:] - np.asarray(built(x0 - e))[1:]) / (2 * h[i])
        scale = np.abs(fd).max()
        assert scale > 0
        np.testing.assert_allclose(d_built[1:, i], fd, rtol=1e-4, atol=1e-6 * scale)


def test_robust_orbit_set_takes_the_high_orbit(mesh_iso):
    """Table 1 long relief, zeta 0.03, 694 rad/s: the transient from the quasi-static state
    settles on the low orbit, the one from the separated start (displacements mirrored) on
    a high, contact-losing one; both are periodic with the excitation (converged, so
    attractors: stable orbits) and the robust objective is the larger; the quasi-static
    objective alone is the low one (what a sweep shows, checked by ``sweep``)."""
    speeds = [694.2857142857143]
    x = np.array([13.3e-6, 0.5])
    both = DynamicObjective(mesh_iso, ReliefSpace(), speeds, "peak-force", formulation="te",
                            orbits=("quasi-static", "separated"))
    ev = both(x, grad=False)
    low, high = ev.per_orbit
    assert ev.structure_ok and high > 1.3 * low
    assert ev.exact == pytest.approx(high, rel=1e-12)
    assert both.orbits == OrbitSet(("quasi-static", "separated"))
    model = both.model
    res = sweep(model, speeds)
    assert bool(res.converged[0])
    assert float(res.max_mesh_force_N[0]) == pytest.approx(low, rel=1e-6)
    start = np.asarray(model.deflected_start(speeds[0], -1.0))
    high_run = jax.jit(lambda y0: simulate(model, speeds[0], y0=y0))(jnp.asarray(start))
    assert bool(high_run.converged) and bool(high_run.contact_loss)
    # another program (not vmapped over starts): the same orbit to the integration's noise
    assert float(high_run.max_mesh_force_N) == pytest.approx(high, rel=1e-6)


@pytest.mark.slow  # two shooting programs compiled
def test_implicit_shooting_gradient_against_central_differences(mesh_iso):
    """The shooting objective differentiated by the implicit function theorem (through
    one period and the monodromy at the orbit) equals the derivative through the Newton
    iterations and the central differences of the objective's values (sdof te, contact
    kept, zeta 0.1)."""
    speeds = [300.0, 600.0]
    x = np.array([13.3e-6, 0.35])
    kw = dict(formulation="te", damping_ratio=0.1, solver=Shooting())
    imp = DynamicObjective(mesh_iso, ReliefSpace(), speeds, "peak-force", implicit=True, **kw)
    ref = DynamicObjective(mesh_iso, ReliefSpace(), speeds, "peak-force", implicit=False, **kw)
    g_imp, g_ref = imp(x).grad, ref(x).grad
    np.testing.assert_allclose(g_imp, g_ref, rtol=1e-6)
    for i, h in enumerate((2e-9, 2e-5)):
        e = np.zeros(2)
        e[i] = h
        fd = (imp(x + e, grad=False).smooth - imp(x - e, grad=False).smooth) / (2 * h)
        assert g_imp[i] == pytest.approx(fd, rel=1e-4)


@pytest.mark.slow  # the lockstep program, two optimisations and a refined map
def test_harris_map_agrees_with_the_optimiser(mesh_iso):
    """The Harris map evaluates the optimiser's objective (the same program, every design
    on a model of its own structure): refined around the optimiser's optimum it reads the
    optimiser's value there (to the models' round-off); refined twice around its own best
    points only, its minimum lies within 2 % of the value the optimiser reaches from it
    (the map resolves the valley the optimiser settles in; sdof te, zeta 0.1, 2 speeds)."""
    obj = DynamicObjective(mesh_iso, ReliefSpace(), [500.0, 800.0], "peak-force",
                           formulation="te", damping_ratio=0.1)
    amps, exts = np.linspace(2e-6, 38e-6, 5), np.linspace(0.1, 0.75, 5)
    res = optimise(obj, [20e-6, 0.5], max_iter=10, learning_rate=0.1)
    near = harris_map(obj, amps, exts, refine=1, n_best=1, around=[res.x])
    assert near.value_at(res.x) == pytest.approx(res.exact, rel=1e-6)
    own = harris_map(obj, amps, exts, refine=2, n_best=2)
    x_map, v_map = own.best()
    polished = optimise(obj, x_map, max_iter=15, learning_rate=0.05)
    assert polished.exact <= v_map * (1 + 1e-6)
    assert v_map - polished.exact <= 0.02 * polished.exact


def test_map_refines_each_valley_once_and_reads_evaluated_designs(mesh_iso):
    """A refinement centre within half the patch spacing of an earlier one takes no patch of
    its own (the first ``around`` design always does); the map reads an evaluated design's
    own value and a design between the points of a patch by bilinear interpolation of the
    objective at the four around it (quasi-static te-rms: a cheap objective)."""
    from gearjax.design import QuasiStaticObjective

    obj = QuasiStaticObjective(mesh_iso, ReliefSpace(), kind="te-rms", n_positions=64)
    amps, exts = np.linspace(4e-6, 24e-6, 5), np.linspace(0.2, 0.6, 5)
    da, de = amps[1] - amps[0], exts[1] - exts[0]
    opt = np.array([11.3e-6, 0.37])
    near = opt + np.array([0.2 * da, -0.2 * de])  # 0.4 of the patch spacing: no patch
    far = opt + np.array([1.5 * da, 0.0])  # three patch spacings away: its own patch
    hmap = harris_map(obj, amps, exts, refine=1, n_best=1, around=[opt, near, far])
    centres = [np.array([np.median(p.amplitudes_m), np.median(p.extents)]) for p in hmap.patches]
    assert len(hmap.patches) in (2, 3)  # opt, far, and the best grid point unless near one
    np.testing.assert_allclose(centres[0], opt, rtol=1e-12)
    np.testing.assert_allclose(centres[1], far, rtol=1e-12)
    value = lambda a, e: obj(np.array([a, e]), grad=False).exact  # noqa: E731
    assert hmap.value_at(opt) == value(*opt)  # evaluated: its own value
    assert hmap.value_at(far) == value(*far)
    (a0, a1), (e0, e1) = (opt[0], opt[0] + da / 2), (opt[1] - de / 2, opt[1])
    u, v = (near[0] - a0) / (a1 - a0), (near[1] - e0) / (e1 - e0)
    assert (u, v) == pytest.approx((0.4, 0.6))
    bilinear = ((1 - u) * (1 - v) * value(a0, e0) + u * (1 - v) * value(a1, e0)
                + (1 - u) * v * value(a0, e1) + u * v * value(a1, e1))
    assert hmap.value_at(near) == pytest.approx(bilinear, rel=1e-9)


def test_multi_start_runs_starts_in_lockstep_only_off_the_cpu(mesh_iso, monkeypatch):
    """``multi_start`` of a dynamic objective: one start after the other on a CPU (a start
    that has stopped is not evaluated again), in lockstep where asked (the accelerator's
    default); the lockstep is not entered for a single start."""
    import importlib

    from gearjax.design import multi_start

    opt_mod = importlib.import_module("gearjax.design.optimise")  # the package's name is the function

    calls = collections.Counter()

    def fake_single(objective, x0, **kw):
        calls["single"] += 1
        return types.SimpleNamespace(exact=float(np.sum(x0)), x=x0)

    def fake_lockstep(objective, starts, **kw):
        calls["lockstep"] += 1
        return [types.SimpleNamespace(exact=float(np.sum(x)), x=x) for x in starts]

    monkeypatch.setattr(opt_mod, "optimise", fake_single)
    monkeypatch.setattr(opt_mod, "optimise_lockstep", fake_lockstep)
    obj = DynamicObjective(mesh_iso, ReliefSpace(), [700.0], "peak-force")
    starts = np.array([[10e-6, 0.3], [20e-6, 0.5]])
    best, runs = multi_start(obj, starts)
    assert jax.default_backend() == "cpu" and calls == {"single": 2}
    assert best.exact == min(r.exact for r in runs)
    multi_start(obj, starts, lockstep=True)
    assert calls == {"single": 2, "lockstep": 1}
    multi_start(obj, starts[:1], lockstep=True)
    assert calls == {"single": 3, "lockstep": 1}


@pytest.mark.slow  # two lockstep programs compiled
def test_lockstep_values_program_gives_the_gradient_programs_values(mesh_iso):
    """``batch(grad=False)`` (the values-only rows program an accelerator's map runs)
    gives the value-and-gradient program's values at every row, and no gradient: to the
    integration's accuracy (rtol 1e-7; the two programs round differently, and the
    adaptive steps carry that into the extrema: benchmarks/results/design_loop.md), as the
    Harris map test compares the map with the optimiser."""
    obj = DynamicObjective(mesh_iso, ReliefSpace(), [700.0, 800.0], "peak-force",
                           formulation="te", orbits=("quasi-static", "separated"))
    xs = np.array([[10e-6, 0.3], [20e-6, 0.5], [14e-6, 0.31]])
    with_grad, values = obj.batch(xs, grad=True), obj.batch(xs, grad=False)
    for a, b in zip(with_grad, values):
        assert b.grad is None and a.grad is not None
        assert b.exact == pytest.approx(a.exact, rel=1e-6)
        assert b.smooth == pytest.approx(a.smooth, rel=1e-6)
        np.testing.assert_allclose(b.per_orbit, a.per_orbit, rtol=1e-6)
