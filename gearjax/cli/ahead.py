"""The reference sweep's program, and the next formulation's, compiled on threads.

The command line sweeps its formulations one after the other, and on a CPU most of a short
sweep is compilation, which runs on one thread and releases the GIL; tracing and the 3D
model builds are Python and hold it. So before the reference sweep of a 3D te/perturbation
sweep starts, the reference program is traced and compiles on a thread while the
te/perturbation model is built and its program traced (Python, on the main thread), then
that program compiles on a second thread while the reference one finishes compiling and
integrates; each sweep finds its executable in JAX's in-memory compilation cache. Results
are identical either way; the gain is measured in ``benchmarks/results/code_notes.md``
(section gearjax.cli.ahead)."""

from __future__ import annotations

import os
import threading
import time
from typing import NamedTuple

from ..dynamics.sweep import lower_sweep


def worth_compiling_ahead(args, forms, form: str, model) -> str | None:
    """The formulation whose program to compile while ``form`` (just built as ``model``)
    sweeps: the first te/perturbation formulation after the reference one, for a 3D
    independent transient or ``auto`` sweep of one process (where ``Auto`` solves that
    formulation in the frequency domain, only its model is built ahead: the program a
    frequency-domain sweep compiles depends on the model's split, :func:`compile_ahead`
    returns None); None otherwise, or with ``GEARJAX_COMPILE_AHEAD=0``."""
    import jax

    from ..models.base import LINEAR_FORMULATIONS

    if (os.environ.get("GEARJAX_COMPILE_AHEAD", "1") in ("0", "false", "False")
            or form != "reference" or args.model != "3d" or args.direction != "independent"
            or jax.process_count() > 1):
        return None
    if args.method not in ("transient", "auto"):
        return None  # Auto: the reference's transient; the linear one's build still overlaps
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


class Ahead(NamedTuple):
    """What :func:`build_and_compile_ahead` started: the threads compiling the current
    formulation's program (``own``) and the next one's (``nxt``), each None where none
    runs, and the seconds spent tracing ``own`` (the current formulation's time)."""

    own: threading.Thread | None = None
    nxt: threading.Thread | None = None
    own_trace_s: float = 0.0

    def join(self, mine: bool, linear: bool) -> None:
        """Before a sweep: wait for its program, compiled on a thread, so that the sweep
        finds it in JAX's cache instead of compiling it a second time (``mine``: the
        sweep of the formulation that started this; ``linear``: a te/perturbation one)."""
        for thread, wait in ((self.own, mine), (self.nxt, linear)):
            if thread is not None and wait:
                thread.join()


def build_and_compile_ahead(args, forms, form: str, model, build, todo_of, options,
                            early) -> Ahead:
    """Where :func:`worth_compiling_ahead` names a formulation and both it and ``form``
    have speeds to compute (``todo_of``): trace ``form``'s own sweep (``model``) and compile
    it on a thread, build the named formulation's model (``build``) meanwhile, keep it in
    ``early`` as ``{formulation: (model, build time in s)}`` and start compiling its sweep
    (``options(model)``: the later calls' keywords). Else an empty :class:`Ahead`."""
    nxt = worth_compiling_ahead(args, forms, form, model)
    if nxt is None or not (todo_of(nxt).size and todo_of(form).size):
        return Ahead()
    t0 = time.perf_counter()
    own = compile_ahead(model, todo_of(form), **options(model))
    traced = time.perf_counter() - t0
    t0 = time.perf_counter()
    built = build(nxt)
    early[nxt] = (built, time.perf_counter() - t0)
    return Ahead(own, compile_ahead(built, todo_of(nxt), **options(built)), traced)
