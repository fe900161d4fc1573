"""XLA's flags for this process: the CPU workarounds, the legacy CPU emitters, the CPU device
count, and the jaxlib versions they were checked on.

XLA reads ``XLA_FLAGS`` once, when JAX starts a backend: every function here must run
before the first JAX computation of the process (a flag set later does not apply, yet
JAX's persistent-cache keys read ``XLA_FLAGS``, so that process's executables would be
stored under keys of flags they were not compiled with). A flag the caller's ``XLA_FLAGS``
already names is never changed; ``GEARJAX_XLA_DEFAULTS=0`` keeps XLA's defaults for the
workarounds and the emitters.
"""

from __future__ import annotations

import os
import warnings

__all__ = ["CPU_WORKAROUND_FLAGS", "SHARDED_CPU_JAXLIB", "FUSION_FLAG_JAXLIB", "jaxlib_minor",
           "add_flags", "use_cpu_workarounds", "use_legacy_emitters", "host_device_count",
           "use_host_devices", "warn_sharded_cpu"]

#: XLA:CPU flags that keep jaxlib 0.10's f64 dots out of YNNPACK fusions, which block an
#: intra-op pool worker while fanning out into the same pool (repeated 3D steady-state
#: evaluations hung there: ``benchmarks/results/soak_3d.md``); CPU backend only.
CPU_WORKAROUND_FLAGS = ("--xla_cpu_experimental_ynn_fusion_type=",
                        "--xla_cpu_multi_thread_eigen=false")

#: jaxlib (major, minor) whose legacy CPU emitters were measured to compile the command
#: line's compile-bound programs faster (``benchmarks/results/code_notes.md``); XLA aborts
#: the process on a flag it does not know, so no other version gets the flag.
FUSION_FLAG_JAXLIB = (0, 10)
FUSION_FLAG = "--xla_cpu_use_fusion_emitters"

#: Newest jaxlib whose XLA:CPU compiled the 3D sweep sharded over several CPU devices
#: (jaxlib 0.11.2 segfaulted there: ``benchmarks/results/accelerator_h100.md``).
SHARDED_CPU_JAXLIB = (0, 10)

DEVICE_FLAG = "--xla_force_host_platform_device_count"


def jaxlib_minor() -> tuple:
    """``(major, minor)`` of the installed jaxlib, ``()`` where unknown (read from the
    package metadata: no backend starts)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return tuple(int(x) for x in version("jaxlib").split(".")[:2])
    except (PackageNotFoundError, ValueError):
        return ()


def _defaults_kept() -> bool:
    return os.environ.get("GEARJAX_XLA_DEFAULTS", "1") == "0"


def add_flags(*flags: str) -> list[str]:
    """Append each ``--name=value`` of ``flags`` to ``XLA_FLAGS`` unless ``XLA_FLAGS``
    already names it; returns the flags added."""
    current = os.environ.get("XLA_FLAGS", "")
    add = [f for f in flags if f.split("=")[0] not in current]
    if add:
        os.environ["XLA_FLAGS"] = " ".join([current, *add]).strip()
    return add


def use_cpu_workarounds() -> list[str]:
    """:data:`CPU_WORKAROUND_FLAGS` into ``XLA_FLAGS`` (none with
    ``GEARJAX_XLA_DEFAULTS=0``); returns the flags added."""
    return [] if _defaults_kept() else add_flags(*CPU_WORKAROUND_FLAGS)


def use_legacy_emitters() -> list[str]:
    """``--xla_cpu_use_fusion_emitters=false`` (XLA's legacy CPU emitters, which compile
    faster) into ``XLA_FLAGS``, unless ``GEARJAX_XLA_DEFAULTS=0`` or jaxlib is not
    :data:`FUSION_FLAG_JAXLIB`. For a process whose programs are all compile-bound: the
    command line's compile-bound commands and the test session. Returns the flags added."""
    if _defaults_kept() or jaxlib_minor() != FUSION_FLAG_JAXLIB:
        return []
    return add_flags(f"{FUSION_FLAG}=false")


def host_device_count() -> int:
    """CPU devices to ask XLA for: one per usable core (each runs its share of a sweep's
    speeds on its own thread); ``GEARJAX_HOST_DEVICES`` when set (a whole number >= 1,
    1: no sharding); 1 by default on a jaxlib newer than :data:`SHARDED_CPU_JAXLIB`.

    Raises ValueError for a ``GEARJAX_HOST_DEVICES`` that is not a whole number >= 1."""
    setting = os.environ.get("GEARJAX_HOST_DEVICES", "").strip()
    if setting:
        if not (setting.isdigit() and int(setting) >= 1):
            raise ValueError(f"GEARJAX_HOST_DEVICES={setting!r}: must be a whole number of "
                             "CPU devices >= 1 (1: no sharding)")
        return int(setting)
    if jaxlib_minor() > SHARDED_CPU_JAXLIB:
        return 1
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def use_host_devices(n: int | None = None) -> list[str]:
    """Ask XLA for ``n`` CPU devices (default :func:`host_device_count`); nothing for one
    device or where ``XLA_FLAGS`` already sets the count. Returns the flags added."""
    n = host_device_count() if n is None else int(n)
    return add_flags(f"{DEVICE_FLAG}={n}") if n > 1 else []


def warn_sharded_cpu(devices) -> None:
    """Warn (RuntimeWarning) before a sweep sharded over several CPU ``devices`` compiles on
    a jaxlib newer than :data:`SHARDED_CPU_JAXLIB`, whose XLA:CPU segfaulted there."""
    if len(devices) > 1 and devices[0].platform == "cpu" and jaxlib_minor() > SHARDED_CPU_JAXLIB:
        warnings.warn(
            f"sweep over {len(devices)} CPU devices on jaxlib "
            f"{'.'.join(map(str, jaxlib_minor()))}: jaxlib 0.11.2's XLA:CPU segfaulted "
            "compiling the 3D sweep sharded over CPU devices (docs: Known limitations); "
            "one device avoids it", RuntimeWarning, stacklevel=3)
