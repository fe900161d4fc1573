"""The next formulation's sweep program compiled while the reference sweep runs.

The command line sweeps its formulations one after the other, and on a CPU most of a short
sweep is compilation (README main job: 15 of its 32 s XLA compile, 6 s tracing), which runs
on one thread and releases the GIL. Built and traced before the reference sweep starts,
the 3D te/perturbation model's program compiles on a second thread while the reference
program compiles and integrates; its sweep then finds the executable in JAX's in-memory
compilation cache (README main job, 2 cores, empty caches, measured alternately
2026-11-25: the command 30.6-32.5 s against 34.4-35.1 s without, the reference sweep ~2 s
slower and the te one ~8 s quicker; tracing on the thread as well gained only half as
much, the two traces contending for the GIL)."""

from __future__ import annotations

import os
import threading
import time

from ..dynamics.sweep import auto_method, lower_sweep


def worth_compiling_ahead(args, forms, form: str, model) -> str | None:
    """The formulation whose program to compile while ``form`` (just built as ``model``)
    sweeps: the first te/perturbation formulation after the reference one, for a 3D
    independent transient sweep of one process; None otherwise, or with
    ``GEARJAX_COMPILE_AHEAD=0``."""
    import jax

    from ..models.base import LINEAR_FORMULATIONS

    if (os.environ.get("GEARJAX_COMPILE_AHEAD", "1") in ("0", "false", "False")
            or form != "reference" or args.model != "3d" or args.direction != "independent"
            or jax.process_count() > 1):
        return None
    if args.method not in ("transient", "auto") or (
            args.method == "auto" and auto_method(model) != "transient"):
        return None
    later = [f for f in forms[forms.index(form) + 1:] if f in LINEAR_FORMULATIONS]
    return later[0] if later else None


def compile_ahead(model, speeds, **sweep_kwargs) -> threading.Thread | None:
    """Trace ``sweep(model, speeds, **sweep_kwargs)``'s program here (Python: it would
    hold the GIL against the reference sweep's own tracing) and compile it on a thread
    (the arguments exactly those of the later call); None where it cannot be traced. A
    failure is left for that call to report. Not a daemon thread: an interrupted command
    exits once the compilation ends (seconds), as XLA aborts the process if it is torn
    down under a running compile."""
    try:
        lowered = lower_sweep(model, speeds, **sweep_kwargs)
    except Exception:  # the sweep itself raises it, with the command line's message
        return None

    def run():
        try:
            lowered.compile()
        except Exception:  # as above
            pass

    thread = threading.Thread(target=run, name="gearjax-compile-ahead")
    thread.start()
    return thread


def build_and_compile_ahead(args, forms, form: str, model, build, todo_of, options, early):
    """Where :func:`worth_compiling_ahead` names a formulation and both it and ``form``
    have speeds to compute (``todo_of``): build its model (``build``), keep it in
    ``early`` as ``{formulation: (model, build time in s)}`` and start compiling its sweep
    (``options(model)``: the later call's keywords). Returns the thread, or None."""
    nxt = worth_compiling_ahead(args, forms, form, model)
    if nxt is None or not (todo_of(nxt).size and todo_of(form).size):
        return None
    t0 = time.perf_counter()
    built = build(nxt)
    early[nxt] = (built, time.perf_counter() - t0)
    return compile_ahead(built, todo_of(nxt), **options(built))
