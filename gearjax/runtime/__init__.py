"""The host process: XLA flags, devices, the persistent compilation cache, progress meters,
the stall watchdog and the release of compiled code.

Everything here acts on the process (environment variables, threads, JAX's caches,
printing); the physics below this layer never does. ``import gearjax`` only enables
float64; the command line calls :func:`configure` (and the rest of this layer) itself, and
a notebook or script may call :func:`configure` before its first JAX computation.
"""

from __future__ import annotations

from typing import NamedTuple

from . import code_memory as code_memory
from . import watchdog as watchdog
from .cache import build_store as build_store
from .cache import compilation_cache_dir as compilation_cache_dir
from .cache import program_store as program_store
from .cache import store_dir as store_dir
from .cache import use_cacheable_checks as use_cacheable_checks
from .cache import use_compilation_cache as use_compilation_cache
from .code_memory import release_if_crowded as release_if_crowded
from .progress import HostProgressMeter as HostProgressMeter
from .progress import TextProgressMeter as TextProgressMeter
from .watchdog import stall_guard as stall_guard
from .xla import host_device_count as host_device_count
from .xla import jaxlib_minor as jaxlib_minor
from .xla import use_cpu_workarounds as use_cpu_workarounds
from .xla import use_host_devices as use_host_devices
from .xla import use_legacy_emitters as use_legacy_emitters

__all__ = ["configure", "Configuration", "TextProgressMeter", "HostProgressMeter",
           "stall_guard", "release_if_crowded", "compilation_cache_dir",
           "use_compilation_cache", "use_cacheable_checks", "store_dir", "program_store",
           "build_store", "use_cpu_workarounds",
           "use_legacy_emitters", "use_host_devices", "host_device_count", "jaxlib_minor"]


class Configuration(NamedTuple):
    """What :func:`configure` did: the XLA flags it added and the persistent compilation
    cache folder in use (None: none)."""

    xla_flags_added: tuple[str, ...]
    compilation_cache_dir: str | None


def configure(*, cpu_workarounds: bool = True, legacy_emitters: bool = False,
              host_devices: int | None = None,
              compilation_cache: bool | str = False) -> Configuration:
    """Set up this process for gearjax; call it before the first JAX computation (XLA
    reads its flags when JAX starts a backend).

    **Arguments:**

    - ``cpu_workarounds``: XLA:CPU flags that avoid a thread-pool deadlock of jaxlib 0.10's
      f64 dot fusions (:data:`gearjax.runtime.xla.CPU_WORKAROUND_FLAGS`); recommended on a
      CPU. Batched LAPACK solves have a deadlock of their own, which gearjax avoids in its
      solvers (:mod:`gearjax.linalg`).
    - ``legacy_emitters``: XLA's legacy CPU emitters, which compile faster (worth it where
      compilation outweighs the run: short sweeps, test suites).
    - ``host_devices``: ask XLA for this many CPU devices (a sweep given ``devices="all"``
      shares its speeds over them); None leaves XLA's one.
    - ``compilation_cache``: True for JAX's persistent compilation cache in
      :func:`compilation_cache_dir`, or a folder; False for none.

    A flag already named in ``XLA_FLAGS`` is never changed, and ``GEARJAX_XLA_DEFAULTS=0``
    keeps XLA's defaults for the workarounds and emitters.

    **Returns:** a :class:`Configuration`.

    **Raises:** ValueError for a bad ``GEARJAX_HOST_DEVICES``.
    """
    added: list[str] = []
    if cpu_workarounds:
        added += use_cpu_workarounds()
    if legacy_emitters:
        added += use_legacy_emitters()
    if host_devices is not None:
        added += use_host_devices(host_devices)
    folder = None
    if compilation_cache:
        folder = use_compilation_cache(None if compilation_cache is True
                                       else str(compilation_cache))
    return Configuration(tuple(added), folder)
