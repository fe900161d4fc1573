"""Which devices a command-line sweep runs on: the processes of a ``jax.distributed`` run
(``--distributed``) and the devices of one process that a transient sweep shares its
speeds over (:func:`gearjax.runtime.host_device_count` CPU devices, or several GPUs)."""

from __future__ import annotations

__all__ = ["init_distributed", "sweep_devices", "device_count"]


def sweep_devices(method: str):
    """Devices of one process that a transient sweep shares its speeds over: ``"all"``
    where the default backend has several (the CPU devices of
    :func:`gearjax.runtime.host_device_count`, or several GPUs), else None; None for the
    frequency-domain and steady-state methods (one device); warns where sharding over CPU
    devices is known to crash (:func:`gearjax.runtime.xla.warn_sharded_cpu`). Several processes
    (``--distributed``) share every device by themselves."""
    import jax

    from ..runtime.xla import warn_sharded_cpu

    if method not in ("auto", "transient") or jax.process_count() > 1:
        return None
    if jax.device_count() == 1:
        return None
    warn_sharded_cpu(jax.devices())
    return "all"


def device_count(devices) -> int:
    """How many devices a sweep given ``devices`` (None or ``"all"``) runs on."""
    import jax

    return 1 if devices is None else len(jax.devices())


def init_distributed(args) -> bool:
    """Join a ``jax.distributed`` run when asked; returns whether this process leads
    (prints and writes). Must run before any JAX computation."""
    explicit = (args.coordinator, args.num_processes, args.process_id)
    if not args.distributed and all(v is None for v in explicit):
        return True
    if args.coordinator is not None and (args.num_processes is None or args.process_id is None):
        raise ValueError("--coordinator needs --num-processes and --process-id (or use "
                         "--distributed alone on a cluster JAX detects)")
    if args.num_processes is not None and args.num_processes < 1:
        raise ValueError(f"--num-processes={args.num_processes}: must be >= 1")
    if args.process_id is not None and args.num_processes is not None and not (
            0 <= args.process_id < args.num_processes):
        raise ValueError(f"--process-id={args.process_id}: must be in 0..{args.num_processes - 1}")
    import jax

    jax.distributed.initialize(coordinator_address=args.coordinator,
                               num_processes=args.num_processes, process_id=args.process_id)
    return jax.process_index() == 0
