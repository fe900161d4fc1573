"""``--te-contact``: which contact law the te and perturbation formulations of ``gearjax
sweep`` use (:class:`gearjax.gears.contact.TEContactLaw`; the reference formulation is
always cell by cell).

``mesh`` (default): the whole mesh in contact or separated, decided by its linear force
(:func:`gearjax.gears.contact.te_contact`). ``cells``: every cell in contact or separated,
from its quasi-static approach and the dynamic approach
(:func:`gearjax.gears.contact.te_cell_contact`); it needs the cells' gaps, so not with
``--te-file``. The case folder gains ``-cells`` and ``case.json``/``summary.json`` record
``te_contact`` (absent for ``mesh``: earlier runs stay resumable).
"""

from __future__ import annotations

from ..gears.contact import TEContactLaw
from .scenario import nlte_options_of

__all__ = ["add_te_contact", "te_contact_of", "model_options_of", "contact_record",
           "contact_suffix"]

_LAWS = {law.value: law for law in TEContactLaw}


def add_te_contact(p) -> None:
    """Add ``--te-contact {mesh,cells}`` to ``p``."""
    p.add_argument("--te-contact", default="mesh", metavar="LAW",
                   help="contact law of te and perturbation (Section 6.2): mesh (default: the "
                        "whole mesh on or off by its linear force) or cells (each cell on or "
                        "off by its own approach, as the reference; needs the cells' gaps, so "
                        "not with --te-file)")


def te_contact_of(args) -> TEContactLaw:
    """The :class:`TEContactLaw` of ``--te-contact``; ``ValueError`` (one line) for an
    unknown name or ``cells`` with ``--te-file``."""
    text = getattr(args, "te_contact", "mesh")
    law = _LAWS.get(text)
    if law is None:
        raise ValueError(f"--te-contact={text!r}: choose {' or '.join(_LAWS)} (default mesh)")
    if law is TEContactLaw.CELLS and getattr(args, "te_file", None):
        raise ValueError(f"--te-contact=cells: needs the cells' gaps, which --te-file="
                         f"{args.te_file} does not give (TE_S alone); use --te-contact mesh")
    return law


def model_options_of(args) -> dict:
    """:func:`gearjax.cli.scenario.nlte_options_of` and ``contact_law`` for
    :func:`gearjax.rigs.factory.build_model`."""
    return {**nlte_options_of(args), "contact_law": te_contact_of(args)}


def contact_record(args) -> dict:
    """``{"te_contact": "cells"}`` for ``case.json``/``summary.json``, ``{}`` for the
    default (checks ``--te-contact`` first)."""
    law = te_contact_of(args)
    return {} if law is TEContactLaw.MESH else {"te_contact": law.value}


def contact_suffix(args) -> str:
    """``-cells`` for the case folder name of a per-cell run, else empty."""
    return "".join(f"-{v}" for v in contact_record(args).values())
