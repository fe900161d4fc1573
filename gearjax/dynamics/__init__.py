"""Solvers of the dynamic models in the angular variable theta = Omega1 t: transient
integration, periodic steady state, Floquet stability, speed sweeps. The functions
``simulate`` and ``sweep`` are re-exported by :mod:`gearjax` (their modules keep the
names ``gearjax.dynamics.simulate`` and ``gearjax.dynamics.sweep``)."""
