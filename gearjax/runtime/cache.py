"""JAX's persistent compilation cache for this process, equinox's runtime checks in a
form that cache can store, and gearjax's own stores beside it: the sweep programs exported
with ``jax.export`` (:class:`gearjax.dynamics.exported.ProgramStore`, folder ``programs``)
and the built models (:class:`gearjax.dynamics.stored.BuildStore`, folder ``models``), so
that a second run neither traces its programs nor builds its models again.

JAX does not store an executable that holds a host callback in its persistent cache, and
equinox's ``error_if`` (diffrax checks its ``SaveAt`` times with it in every ``simulate``
program) is one, unless equinox raises its errors as NaN (``EQX_ON_ERROR=nan``). gearjax
builds those times itself; a NaN from any such check fails the finite checks of every
metric (``solver_ok`` False).
"""

from __future__ import annotations

import os

__all__ = ["compilation_cache_dir", "use_compilation_cache", "use_cacheable_checks",
           "store_dir", "program_store", "build_store"]


def compilation_cache_dir() -> str | None:
    """Folder of the persistent compilation cache: ``$JAX_COMPILATION_CACHE_DIR`` when set
    (JAX reads it itself), else ``$XDG_CACHE_HOME/gearjax/jax`` (default
    ``~/.cache/gearjax/jax``); None with ``GEARJAX_COMPILATION_CACHE=0``."""
    if os.environ.get("GEARJAX_COMPILATION_CACHE", "1") in ("0", "false", "False"):
        return None
    if os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return os.environ["JAX_COMPILATION_CACHE_DIR"]
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "gearjax", "jax")


def use_cacheable_checks() -> bool:
    """equinox's runtime checks as NaN instead of a host callback for the rest of this
    process, as ``EQX_ON_ERROR=nan`` in the environment would (equinox reads it at its
    import, so this sets equinox's module setting directly); a caller's own
    ``EQX_ON_ERROR`` stays. Returns whether it changed the setting."""
    if "EQX_ON_ERROR" in os.environ:
        return False
    from equinox import _errors  # the module global error_if reads at every call

    _errors.EQX_ON_ERROR = "nan"
    return True


def use_compilation_cache(path: str | None = None) -> str | None:
    """JAX's persistent compilation cache in ``path`` (default
    :func:`compilation_cache_dir`); a folder the caller already gave JAX stays. Returns the
    folder in use, or None where there is none."""
    import jax

    if jax.config.jax_compilation_cache_dir:  # a caller's own choice stays
        return jax.config.jax_compilation_cache_dir
    path = compilation_cache_dir() if path is None else path
    if path is not None:
        jax.config.update("jax_compilation_cache_dir", path)
    return path


def store_dir(kind: str) -> str | None:
    """Folder of gearjax's store ``kind`` (``"programs"`` or ``"models"``): a sub-folder of
    :func:`compilation_cache_dir` (JAX's cache reads only its own files there), so the
    same settings choose, move and disable all three; None with
    ``GEARJAX_COMPILATION_CACHE=0``."""
    if kind not in ("programs", "models"):
        raise ValueError(f"kind={kind!r}: 'programs' or 'models'")
    folder = compilation_cache_dir()
    return None if folder is None else os.path.join(folder, kind)


def program_store():
    """The sweep programs' store of :func:`store_dir` (a
    :class:`gearjax.dynamics.exported.ProgramStore` whose values are keyed by this
    process's ``XLA_FLAGS`` too), or a :class:`~gearjax.dynamics.exported.NoProgramStore`
    where the stores are off."""
    from ..dynamics.exported import NoProgramStore, ProgramStore

    folder = store_dir("programs")
    return (NoProgramStore() if folder is None
            else ProgramStore(folder, context=os.environ.get("XLA_FLAGS", "")))


def build_store():
    """The built models' store of :func:`store_dir` (a
    :class:`gearjax.dynamics.stored.BuildStore`), or a
    :class:`~gearjax.dynamics.stored.NoBuildStore` where the stores are off."""
    from ..dynamics.stored import BuildStore, NoBuildStore

    folder = store_dir("models")
    return NoBuildStore() if folder is None else BuildStore(folder)
