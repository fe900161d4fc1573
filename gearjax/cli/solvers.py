"""The command line's names of the periodic solvers (``--method``) and the solver objects
they stand for (:mod:`gearjax.dynamics.solvers`): sweeps, stability and design objectives."""

from __future__ import annotations

from ..errors import DesignError

__all__ = ["METHODS", "STABILITY_METHODS", "DESIGN_METHODS", "periodic_start_options",
           "solver_for", "design_solver"]

# gearjax stability --method: the monodromy everywhere (steady), or the small-gain bound
# first and the monodromy where it does not prove stability (harmonic:
# gearjax.dynamics.harmonic.small_gain_bounds)
STABILITY_METHODS = ("auto", "steady", "harmonic")


def periodic_start_options(model) -> dict:
    """simulate() options for a model whose initial state is already the periodic steady
    state (:attr:`Geared3DModel.periodic_start`: Eq. (48a) solved harmonic by harmonic):
    no transient, start exactly there."""
    if not model.periodic_start:
        return {}
    return {"n_transient_periods": 0, "start": "initial"}


# sweep --method: the periodic solvers of a speed sweep
METHODS = ("auto", "transient", "steady", "harmonic")


def solver_for(method: str, model, rtol: float | None, tolerances: dict):
    """The periodic solver of ``--method`` for ``model`` at ``--rtol`` (``tolerances``: its
    transient options, :func:`gearjax.dynamics.sweep.tolerance_options`): ``auto``
    :class:`~gearjax.dynamics.sweep.Auto`; ``transient``; ``steady`` shooting, the speeds it
    does not solve by the transient; ``harmonic`` the frequency domain, likewise."""
    from ..dynamics.harmonic_sweep import HarmonicBalance
    from ..dynamics.solvers import Fallback
    from ..dynamics.steady import Shooting
    from ..dynamics.sweep import Auto, Transient

    if method == "auto":
        return Auto(rtol=rtol)
    transient = Transient(**tolerances, **periodic_start_options(model))
    if method == "transient":
        return transient
    if method == "steady":
        return Fallback(Shooting.for_transient(transient), transient)
    if method == "harmonic":
        return Fallback(HarmonicBalance(rtol=tolerances.get("rtol", 1e-6)), transient)
    raise ValueError(f"--method={method!r}: choose from {', '.join(METHODS)}")


# --method of the dynamic objectives: the command line's names of their one-speed solvers
DESIGN_METHODS = ("auto", "transient", "steady")


def design_solver(method: str, rtol: float | None):
    """The one-speed solver of ``--method`` at ``--rtol``: ``auto`` :class:`~gearjax.Auto`
    (the transient), ``transient`` the transient, ``steady`` the shooting, each at the
    accuracy ``--rtol`` asks (:func:`gearjax.dynamics.sweep.tolerance_options`, read by
    the shooting as ``sweep --method steady`` reads it:
    :meth:`gearjax.dynamics.steady.Shooting.for_transient`). Raises :class:`DesignError`
    for an ``--rtol`` outside [1e-13, 1e-2]."""
    from ..dynamics.simulate import SimulationError
    from ..dynamics.steady import Shooting
    from ..dynamics.sweep import Auto, Transient, tolerance_options

    try:
        options = tolerance_options(rtol)
    except SimulationError:
        raise DesignError(f"--rtol={rtol!r}: must lie in [1e-13, 1e-2]") from None
    if method == "auto":
        return Auto(rtol=rtol)
    if method == "transient":
        return Transient(**options)
    return Shooting.for_transient(Transient(**options))
