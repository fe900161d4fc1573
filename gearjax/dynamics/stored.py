"""Results kept on disk between runs, keyed by the content of what produced them: the
digest of Python objects (:func:`digest`), of the code that computes them
(:func:`code_digest`), the entry files of a store folder (:func:`read_entry`,
:func:`write_entry`) and :class:`BuildStore`, which keeps built models (any picklable value
of a pure function of its arguments). The compiled programs of a sweep have their own
store built on these entries (:mod:`gearjax.dynamics.exported`).

* An entry is found by the SHA-256 of its *inputs* (a JSON-able dict: the code digest,
  the function, the digest of its arguments, the platform). Its file repeats the inputs in
  a header and the payload's length and SHA-256: an entry whose header differs (a stale or
  colliding key), that is truncated, corrupt or unreadable is ignored and overwritten by
  the caller, never used, never an error to the user.
* Files are written atomically (a temporary file in the folder, then a rename): a reader
  never sees half an entry, and concurrent writers of one entry leave one whole copy.
* The digest of an object walks its content (dataclasses and equinox modules field by
  field, containers, arrays by dtype, shape and bytes, functions by module, name, bytecode,
  defaults and closure); an object it cannot describe deterministically (a ``repr`` with a
  memory address, a tracer) raises :class:`Undigestable`, and the stores then compute
  without storing. Functions' globals are not followed: gearjax's own code is in
  :func:`code_digest`, a caller's module-level helpers are not.
* A store folder holds pickles and serialised programs, which run code when loaded: keep
  it as private as the compilation cache of JAX beside it.
"""

from __future__ import annotations

import abc
import dataclasses
import enum
import functools
import hashlib
import json
import os
import pickle
import sys
import tempfile
import types
from importlib import metadata
from pathlib import Path

import jax
import numpy as np

__all__ = ["Undigestable", "digest", "code_digest", "entry_path", "read_entry",
           "write_entry", "AbstractBuildStore", "NoBuildStore", "BuildStore"]

_MAGIC = b"gearjax-store 1\n"
# the packages whose code a stored build or program depends on besides gearjax's own
_PACKAGES = ("jax", "jaxlib", "equinox", "diffrax", "lineax", "optax", "numpy")


class Undigestable(TypeError):
    """An object :func:`digest` cannot describe by its content (the stores then compute
    without storing)."""


def digest(obj, *, arrays: str = "content") -> str:
    """SHA-256 (hex) of the content of ``obj`` (module docstring). ``arrays``:
    ``"content"`` digests every array by its bytes; ``"aval"`` digests the arrays of
    pytree (non-static) fields by dtype, shape, weak type and sharding only -- what a
    traced program sees of them -- and those of static fields by their bytes.

    Raises :class:`Undigestable` for an object it cannot describe."""
    if arrays not in ("content", "aval"):
        raise ValueError(f"arrays={arrays!r}: 'content' or 'aval'")
    h = hashlib.sha256()
    _feed(h, obj, arrays == "content", set())
    return h.hexdigest()


def _put(h, *parts) -> None:
    for p in parts:
        b = p if isinstance(p, bytes) else str(p).encode()
        h.update(len(b).to_bytes(8, "little"))
        h.update(b)


def _qualname(x) -> str:
    return f"{getattr(x, '__module__', '?')}.{getattr(x, '__qualname__', type(x).__name__)}"


def _feed(h, x, content: bool, active: set) -> None:
    if x is None or x is Ellipsis or isinstance(x, (bool, int, float, complex, str, bytes)):
        _put(h, type(x).__name__, x if isinstance(x, bytes) else repr(x))
        return
    if isinstance(x, np.generic):
        _put(h, "np.generic", x.dtype.str, x.tobytes())
        return
    if isinstance(x, jax.core.Tracer):
        raise Undigestable("a traced value")
    if isinstance(x, jax.Array):
        sharding = x.sharding
        where = "one device" if len(sharding.device_set) == 1 else repr(sharding)
        _put(h, "jax.Array", x.dtype.str, x.shape, x.weak_type, where)
        if content:
            _put(h, np.ascontiguousarray(jax.device_get(x)).tobytes())
        return
    if isinstance(x, np.ndarray):
        if x.dtype.hasobject:
            raise Undigestable("an object array")
        _put(h, "np.ndarray", x.dtype.str, x.shape)
        if content:
            _put(h, np.ascontiguousarray(x).tobytes())
        return
    if isinstance(x, enum.Enum):
        _put(h, "enum", _qualname(type(x)), x.name)
        return
    if isinstance(x, type):
        _put(h, "type", _qualname(x))
        return
    if isinstance(x, jax.Device):
        _put(h, "device", x.platform, x.id, x.device_kind)
        return
    if isinstance(x, jax.sharding.Mesh):
        _put(h, "mesh", x.axis_names, x.devices.shape)
        for d in x.devices.flat:
            _feed(h, d, content, active)
        return
    if id(x) in active:
        raise Undigestable("a cycle")
    active.add(id(x))
    try:
        _feed_composite(h, x, content, active)
    finally:
        active.discard(id(x))


def _feed_composite(h, x, content: bool, active: set) -> None:
    if isinstance(x, (tuple, list)):
        _put(h, type(x).__name__ if type(x) in (tuple, list) else _qualname(type(x)), len(x))
        for v in x:
            _feed(h, v, content, active)
    elif isinstance(x, (set, frozenset)):  # in an order that does not depend on hashing
        parts = []
        for v in x:
            sub = hashlib.sha256()
            _feed(sub, v, content, active)
            parts.append(sub.hexdigest())
        _put(h, type(x).__name__, *sorted(parts))
    elif isinstance(x, dict):
        _put(h, "dict", len(x))
        for k in sorted(x, key=repr):
            _feed(h, k, True, active)
            _feed(h, x[k], content, active)
    elif isinstance(x, functools.partial):
        _put(h, "partial")
        _feed(h, (x.func, x.args, x.keywords), True, active)
    elif isinstance(x, types.MethodType):
        _put(h, "method")
        _feed(h, (x.__func__, x.__self__), content, active)
    elif isinstance(x, types.FunctionType):
        cells = tuple(c.cell_contents for c in (x.__closure__ or ()))
        _put(h, "function", _qualname(x))
        _feed_code(h, x.__code__)
        _feed(h, (x.__defaults__, x.__kwdefaults__, cells), True, active)
    elif isinstance(x, (types.BuiltinFunctionType, np.ufunc)):
        _put(h, "builtin", _qualname(x), getattr(x, "__name__", ""))
    elif dataclasses.is_dataclass(x):
        _put(h, "dataclass", _qualname(type(x)))
        for f in dataclasses.fields(x):
            _put(h, f.name)
            _feed(h, getattr(x, f.name), content or bool(f.metadata.get("static")), active)
    else:
        raise Undigestable(f"an object of type {_qualname(type(x))}")


def _feed_code(h, code: types.CodeType) -> None:
    _put(h, "code", code.co_code, code.co_names, code.co_varnames)
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            _feed_code(h, c)
        else:
            _feed(h, c, True, set())


@functools.cache
def code_digest() -> str:
    """SHA-256 (hex) of the code a stored result depends on: every ``gearjax/**/*.py``
    file (path and bytes), gearjax's version and those of Python, JAX, jaxlib, equinox,
    diffrax, lineax, optax and NumPy. Read once per process."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        _put(h, path.relative_to(root).as_posix(), path.read_bytes())
    for name in ("gearjax", *_PACKAGES):
        try:
            _put(h, name, metadata.version(name))
        except metadata.PackageNotFoundError:
            _put(h, name, "-")
    _put(h, sys.version)
    return h.hexdigest()


def entry_path(folder, inputs: dict) -> Path:
    """The file of the entry whose inputs are ``inputs`` (a JSON-able dict) in ``folder``."""
    text = json.dumps(inputs, sort_keys=True)
    return Path(folder) / f"{hashlib.sha256(text.encode()).hexdigest()[:40]}.bin"


def read_entry(folder, inputs: dict) -> bytes | None:
    """The payload of the entry of ``inputs`` in ``folder``, or None where there is none
    or it is not exactly that entry (another header, truncated, corrupt, unreadable)."""
    try:
        data = entry_path(folder, inputs).read_bytes()
        if not data.startswith(_MAGIC):
            return None
        end = data.index(b"\n", len(_MAGIC))
        header = json.loads(data[len(_MAGIC):end])
        payload = data[end + 1:]
    except (OSError, ValueError):
        return None
    if (header.get("inputs") != json.loads(json.dumps(inputs))
            or header.get("bytes") != len(payload)
            or header.get("sha256") != hashlib.sha256(payload).hexdigest()):
        return None
    return payload


def write_entry(folder, inputs: dict, payload: bytes) -> bool:
    """Write the entry of ``inputs`` with ``payload`` into ``folder`` (created where
    missing), atomically; returns whether it was written (an unwritable folder or a full
    disk is not an error: the entry is simply not kept)."""
    header = json.dumps({"inputs": inputs, "bytes": len(payload),
                         "sha256": hashlib.sha256(payload).hexdigest()}, sort_keys=True)
    path = entry_path(folder, inputs)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".bin")
        with os.fdopen(fd, "wb") as fh:
            fh.write(_MAGIC + header.encode() + b"\n" + payload)
        os.replace(tmp, path)
        return True
    except OSError:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        return False


class AbstractBuildStore(abc.ABC):
    """Where a command's built models come from: computed, or kept from an earlier run."""

    @abc.abstractmethod
    def build(self, fn, *args, **kwargs):
        """``fn(*args, **kwargs)`` (a pure function); raises what ``fn`` raises."""


class NoBuildStore(AbstractBuildStore):
    """Every value computed: the library's default, and the command line's with the
    stores off."""

    def build(self, fn, *args, **kwargs):
        return fn(*args, **kwargs)

    def __repr__(self) -> str:
        return "NoBuildStore()"


class BuildStore(AbstractBuildStore):
    """Values of pure functions (models from :func:`gearjax.rigs.factory.build_model`)
    kept as pickles in ``folder``, keyed by the function and the content of its arguments
    (:func:`digest`), :func:`code_digest`, JAX's platform and float64 setting. JAX
    arrays come back as JAX arrays (NumPy bytes in the pickle, dtype and weak type kept).
    """

    __slots__ = ("folder",)

    def __init__(self, folder: str | os.PathLike):
        self.folder = os.fspath(folder)

    def __repr__(self) -> str:
        return f"BuildStore({self.folder!r})"

    def build(self, fn, *args, **kwargs):
        """``fn(*args, **kwargs)``, from the store where it holds this call's entry, else
        computed and stored (a result that does not pickle, or arguments that
        :func:`digest` cannot describe, are computed and not stored). Raises what ``fn``
        raises."""
        try:
            inputs = {"function": _qualname(fn), "code": code_digest(),
                      "arguments": digest((fn, args, kwargs)), "platform": jax.default_backend(),
                      "x64": bool(jax.config.jax_enable_x64)}
        except Undigestable:
            return fn(*args, **kwargs)
        payload = read_entry(self.folder, inputs)
        if payload is not None:
            try:
                return pickle.loads(payload)
            except Exception:  # a class that moved or changed: rebuild and overwrite
                pass
        value = fn(*args, **kwargs)
        try:
            blob = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # e.g. a lambda inside: kept in memory only
            return value
        write_entry(self.folder, inputs, blob)
        return value
