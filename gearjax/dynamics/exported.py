"""Compiled programs kept between runs: a store that a solver hands its jitted functions
to (:meth:`AbstractProgramStore.call`), so that a later process calls the same program
without tracing it again, and keeps the values of deterministic preparations that cost
more to compute than to load (:meth:`AbstractProgramStore.value`: the frequency domain's
split and plan of a model).

:class:`ProgramStore` exports each program with ``jax.export`` (StableHLO, JAX's stable
serialisation) at the first call with a given key and keeps it in its folder
(:mod:`gearjax.dynamics.stored`'s entries). The key digests what the traced program
depends on: gearjax's code, its dependencies' versions (:func:`~gearjax.dynamics.stored.
code_digest`), the function (bytecode and closure), the static part of its arguments (a
model's formulation, which terms exist, the solver's options), the dtypes, shapes, weak
types and shardings of their arrays (the chunk of speeds), JAX's platform and the JAX
options that change tracing. A later call with that key deserialises the program and calls
it inside ``jax.jit``: only XLA's compilation is left, which JAX's persistent compilation
cache serves where one is set. Results are those of the jitted function (the same
program). :class:`NoProgramStore` (the default) calls the jitted function itself.

* The program is the one called in the run that exports it too, so the run that fills the
  store also fills JAX's compilation cache with the executables the next run asks for.
* :meth:`AbstractProgramStore.value` keys a value by the *content* of the arguments (every
  array's bytes), the same code and options, JAX's optimisation setting and the store's
  ``context`` (what else changes compiled values: the command line passes ``XLA_FLAGS``).
* A program that ``jax.export`` refuses -- one holding a host callback, such as equinox's
  runtime checks in their default ``raise`` mode (the command line makes them NaN:
  :func:`gearjax.runtime.use_cacheable_checks`) -- is called as traced, not stored.
* Arguments the key cannot describe (:class:`~gearjax.dynamics.stored.Undigestable`), a
  multi-process sweep (each process would need the same entry) and a store entry that is
  stale, corrupt or unreadable are handled as without the store (the entry is overwritten).
"""

from __future__ import annotations

import abc
import os
import pickle

import equinox as eqx
import jax

from .stored import Undigestable, code_digest, digest, read_entry, write_entry

__all__ = ["AbstractProgramStore", "NoProgramStore", "ProgramStore"]


class AbstractProgramStore(abc.ABC):
    """Where a solver's jitted programs come from (module docstring)."""

    @abc.abstractmethod
    def call(self, jitted, *args):
        """``jitted(*args)``: ``jitted`` an ``equinox.filter_jit`` function (arrays traced,
        every other argument static)."""

    @abc.abstractmethod
    def value(self, jitted, *args):
        """``jitted(*args)`` for a deterministic program whose value may come from an
        earlier run's identical call (same code, options and argument content)."""

    @abc.abstractmethod
    def lower(self, jitted, *args):
        """The ``jax.stages.Lowered`` program that :meth:`call` with these arguments
        runs; its ``compile()`` fills JAX's caches for that call."""


class NoProgramStore(AbstractProgramStore):
    """The jitted function itself, traced in every process: the library's default."""

    def call(self, jitted, *args):
        return jitted(*args)

    def value(self, jitted, *args):
        return jitted(*args)

    def lower(self, jitted, *args):
        return jitted.lower(*args)

    def __repr__(self) -> str:
        return "NoProgramStore()"


class _Program:
    """A flat program (``run``: array leaves in, array leaves out) on ``n_devices``
    devices and how its outputs are put back together (``out_static``: their non-array
    part; ``out_skeleton``: their array part with 0 for every leaf)."""

    __slots__ = ("run", "n_devices", "out_static", "out_tree")

    def __init__(self, run, n_devices, out_static, out_skeleton):
        self.run, self.n_devices, self.out_static = run, n_devices, out_static
        self.out_tree = jax.tree_util.tree_structure(out_skeleton)

    def __call__(self, leaves):
        out = self.run(*leaves)
        if jax.local_device_count() > 1:
            out = [_uncommitted(x) for x in out]
        return eqx.combine(jax.tree_util.tree_unflatten(self.out_tree, out), self.out_static)


def _uncommitted(x):
    """``x`` free to move to other devices, as a jitted function's outputs of uncommitted
    inputs are: JAX commits an exported program's outputs to its device, which a later
    program on several devices (a sharded sweep taking a plan) refuses. Through the host,
    as JAX's own pickling restores arrays (dtype and weak type kept)."""
    if isinstance(x, jax.Array) and x.committed and len(x.sharding.device_set) == 1:
        return pickle.loads(pickle.dumps(x, protocol=pickle.HIGHEST_PROTOCOL))
    return x


class ProgramStore(AbstractProgramStore):
    """Programs exported with ``jax.export`` into ``folder`` (module docstring), and values
    of deterministic programs; each program is loaded or exported once per store object
    and key. Files: ``folder/<key>.bin``. ``context``: what else changes the values that
    compiled programs compute (e.g. the process's XLA flags), part of the values' keys."""

    __slots__ = ("folder", "context", "_programs", "_keys")

    def __init__(self, folder: str | os.PathLike, context: str = ""):
        self.folder = os.fspath(folder)
        self.context = str(context)
        self._programs: dict = {}
        self._keys: dict = {}  # identity of a call's arguments -> its key (_inputs)

    def __repr__(self) -> str:
        return f"ProgramStore({self.folder!r})"

    def value(self, jitted, *args):
        fn = jitted.__wrapped__
        try:
            inputs = {"value of": f"{fn.__module__}.{fn.__qualname__}", "code": code_digest(),
                      "arguments": digest((fn, args)), "platform": jax.default_backend(),
                      "jax": _jax_options(), "context": self.context,
                      "optimised": not jax.config.read("jax_disable_most_optimizations")}
        except Undigestable:
            return self.call(jitted, *args)
        payload = read_entry(self.folder, inputs)
        if payload is not None:
            try:
                return pickle.loads(payload)
            except Exception:  # unreadable: computed again, the entry overwritten
                pass
        out = self.call(jitted, *args)
        try:
            payload = pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # a value that does not pickle: not kept
            return out
        write_entry(self.folder, inputs, payload)
        return out

    def call(self, jitted, *args):
        found = self._program(jitted, args)
        if found is None:
            return jitted(*args)
        program, leaves = found
        return program(leaves)

    def lower(self, jitted, *args):
        found = self._program(jitted, args)
        if found is None:
            return jitted.lower(*args)
        program, leaves = found
        return program.run.lower(*leaves)

    def _program(self, jitted, args):
        """``(program, array leaves of args)``, or None where ``args`` cannot be keyed."""
        fn = jitted.__wrapped__
        dyn, static = eqx.partition(args, eqx.is_array)
        leaves, treedef = jax.tree_util.tree_flatten(dyn)
        try:
            inputs = self._inputs(fn, args, leaves)
        except Undigestable:
            return None
        key = repr(sorted(inputs.items()))
        program = self._programs.get(key)
        if program is None:
            program = self._load(inputs) or self._export(fn, treedef, static, leaves, inputs)
            if program is None:
                return None
            self._programs[key] = program
        if program.n_devices > 1 and not any(
                len(x.sharding.device_set) == program.n_devices for x in leaves
                if isinstance(x, jax.Array)):
            return None  # its devices are those of its arguments: it has none here
        return program, leaves

    def _inputs(self, fn, args, leaves) -> dict:
        """What keys the program of ``fn`` at ``args`` (module docstring). Digesting the
        arguments walks the whole model, so a call whose arguments are the same objects
        and arrays of the same types as an earlier call's (a sweep's chunks: the same
        model and solver, another chunk of speeds) reuses that call's key; the objects
        are held with it (their identity stays theirs), the last :data:`_KEYS_KEPT`.
        Raises :class:`~gearjax.dynamics.stored.Undigestable`."""
        ident = _identity(fn, args, leaves)
        if ident is not None and ident in self._keys:
            return self._keys[ident][0]
        inputs = {"function": f"{fn.__module__}.{fn.__qualname__}",
                  "code": code_digest(), "arguments": digest((fn, args), arrays="aval"),
                  "platform": jax.default_backend(), "jax": _jax_options()}
        if ident is not None:
            if len(self._keys) >= _KEYS_KEPT:
                self._keys.pop(next(iter(self._keys)))
            self._keys[ident] = (inputs, (fn, args))
        return inputs

    def _load(self, inputs) -> _Program | None:
        payload = read_entry(self.folder, inputs)
        if payload is None:
            return None
        try:
            entry = pickle.loads(payload)
            exported = jax.export.deserialize(bytearray(entry["exported"]))
            return _Program(_jitted_call(exported), exported.nr_devices, *entry["out"])
        except Exception:  # unreadable: exported again, the entry overwritten
            return None

    def _export(self, fn, treedef, static, leaves, inputs) -> _Program | None:
        out_parts = []

        def flat(*xs):
            out = fn(*eqx.combine(jax.tree_util.tree_unflatten(treedef, list(xs)), static))
            out_dyn, out_static = eqx.partition(out, eqx.is_array)
            out_leaves, out_tree = jax.tree_util.tree_flatten(out_dyn)
            out_parts[:] = [out_static, jax.tree_util.tree_unflatten(out_tree, [0] * len(
                out_leaves))]
            return out_leaves

        flat.__name__ = flat.__qualname__ = fn.__name__  # the program's (and cache file's) name
        traced = jax.jit(flat)
        try:
            exported = jax.export.export(traced)(*leaves)
            blob = exported.serialize()
        except Exception:  # the jitted function raises it again, or it is not exportable
            # (a host callback): then called as traced (JAX keeps the trace), not stored
            return _Program(traced, 0, *out_parts) if out_parts else None
        try:
            payload = pickle.dumps({"exported": bytes(blob), "out": tuple(out_parts)},
                                   protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # an output whose static part does not pickle
            return _Program(traced, 0, *out_parts)
        write_entry(self.folder, inputs, payload)
        # the deserialised program, as a later run calls it: one executable for both
        return _Program(_jitted_call(jax.export.deserialize(blob)), exported.nr_devices,
                        *out_parts)


_KEYS_KEPT = 32
_SCALARS = (bool, int, float, complex, str, type(None))


def _identity(fn, args, leaves):
    """A hashable identity of a call: the function, each argument (an equinox module or
    function by identity, a scalar by value, an array by its type), the array leaves'
    dtypes, shapes, weak types and shardings, JAX's platform and options; None where an
    argument is anything else (a container, mutable or rebuilt per call: digested)."""
    parts = []
    for a in args:
        if isinstance(a, (eqx.Module, type(fn))):
            parts.append(("id", id(a)))
        elif isinstance(a, _SCALARS):
            parts.append((type(a).__name__, a))
        elif eqx.is_array(a):
            parts.append(("array",))
        else:
            return None
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return None  # under a trace: not a program to store (the digest refuses it)
    avals = tuple((type(x).__name__, x.shape, str(x.dtype), x.weak_type, x.sharding)
                  if isinstance(x, jax.Array) else (type(x).__name__, x.shape, str(x.dtype))
                  for x in leaves)
    return (id(fn), tuple(parts), avals, jax.default_backend(),
            tuple(sorted(_jax_options().items())))


def _jitted_call(exported):
    """``exported.call`` jitted under the exported function's name."""
    call = exported.call

    def run(*xs):
        return call(*xs)

    run.__name__ = run.__qualname__ = exported.fun_name
    return jax.jit(run)


def _jax_options() -> dict:
    """The JAX options that change a traced program."""
    c = jax.config
    return {"x64": bool(c.jax_enable_x64), "matmul": str(c.jax_default_matmul_precision),
            "promotion": str(c.jax_numpy_dtype_promotion)}
