"""Output paths of the command line, checked (and their folders created) before any
computation, so that a bad ``--out``, ``--csv`` or ``--plot`` fails at once with one line
instead of a traceback after minutes of computing.

Every problem raises :class:`gearjax.errors.GearjaxError` ``(option, path, reason)``.
"""

from __future__ import annotations

import os
import tempfile

from ..errors import GearjaxError

__all__ = ["check_output_file", "prepare_output_dir", "FIGURE_SUFFIXES", "available_memory_bytes"]

# figure formats matplotlib writes; a name without one of them would get ".png" appended
# by matplotlib (``--plot /tmp`` would write ``/tmp.png``), so it is refused instead
FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff",
                   ".webp")


def _file_ancestor(path: str) -> str | None:
    """The first existing ancestor of ``path`` that is not a folder (``--out a.txt/b``)."""
    head = os.path.dirname(os.path.abspath(path))
    while head and not os.path.exists(head):
        parent = os.path.dirname(head)
        if parent == head:
            break
        head = parent
    return head if head and os.path.exists(head) and not os.path.isdir(head) else None


def _make_dirs(option: str, path: str, folder: str) -> None:
    bad = _file_ancestor(os.path.join(folder, "x"))
    if bad is not None:
        raise GearjaxError(option, path, f"{bad!r} is a file, not a folder")
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise GearjaxError(option, path, f"cannot create the folder {folder!r} "
                                         f"({exc.strerror or exc})") from None


def _probe(option: str, path: str, folder: str) -> None:
    """Write (and remove) a scratch file in ``folder``: the only test that also works for
    root, read-only mounts and pseudo file systems such as /proc."""
    try:
        fd, name = tempfile.mkstemp(prefix=".gearjax-probe-", dir=folder)
    except OSError as exc:
        raise GearjaxError(option, path, f"cannot write into {folder!r} "
                                         f"({exc.strerror or exc})") from None
    os.close(fd)
    os.remove(name)


def check_output_file(option: str, path: str, *, figure: bool = False) -> str:
    """Check that ``path`` can be written (creating its missing parent folders); returns it.

    ``figure``: the name must end in a figure format (:data:`FIGURE_SUFFIXES`)."""
    if os.path.isdir(path):
        raise GearjaxError(option, path, "is a folder; give a file name"
                                         + (", e.g. te.png" if figure else ", e.g. te.csv"))
    if figure and os.path.splitext(path)[1].lower() not in FIGURE_SUFFIXES:
        raise GearjaxError(option, path, "needs a figure file name ending in "
                                         f"{', '.join(FIGURE_SUFFIXES[:3])}, ...")
    folder = os.path.dirname(os.path.abspath(path))
    _make_dirs(option, path, folder)
    _probe(option, path, folder)
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise GearjaxError(option, path, "the file exists and is not writable")
    return path


def prepare_output_dir(option: str, path: str, *, results: tuple[str, ...] = (),
                       resume: bool = False, overwrite: bool = False) -> str:
    """Create the output folder ``path`` and check it is writable; returns it.

    ``results``: names of the files a run writes there. If some exist, the folder holds an
    earlier run: refused unless ``resume`` (keep them, the caller continues) or
    ``overwrite`` (those files, and only those, are removed). Other files are never
    touched."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise GearjaxError(option, path, "is a file, not a folder")
    _make_dirs(option, path, path)
    _probe(option, path, path)
    found = [n for n in results if os.path.exists(os.path.join(path, n))]
    if found and not (resume or overwrite):
        raise GearjaxError(option, path, f"holds the results of an earlier run ({', '.join(found)}); "
                                         "give --resume to continue it, --overwrite to replace it, "
                                         "or another --out folder")
    if found and overwrite and not resume:
        for n in found:
            os.remove(os.path.join(path, n))
    return path


def available_memory_bytes() -> int | None:
    """Memory available now (bytes; Linux ``MemAvailable``), None where unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None
