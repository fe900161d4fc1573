"""The one model factory: :func:`build_model` turns a rig and its tooth modifications into
a dynamic model, the sdof torsional model (Eqs. (16), (20), (47a)) or the 3D model of its
shaft lines (Eqs. (14), (42), (48a)). The command line, the design objectives, the
notebooks and the benchmarks build their models here, so the rig's defaults (torque,
motor node, encoder positions, structure) are applied in one place.
"""

from __future__ import annotations

import jax

from ..errors import ModelError
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..models.geared3d import Geared3DModel
from ..models.torsional import NLTE_REACTIONS, TorsionalModel
from .rig import Rig

__all__ = ["MODELS", "NLTE_REACTION_3D", "build_model"]

MODELS = ("3d", "torsional")
# why the 3D model refuses nlte_reaction="pinion" (the command line says the same)
NLTE_REACTION_3D = ("the 3D model puts the NLTE'' reaction torque at its torque node (the "
                    "rig's motor: 'drive', Eq. (14)); 'pinion' is a torsional-model option")

def build_model(
    rig: Rig,
    mods: ToothModifications | None = None,
    *,
    model: str = "3d",
    law: str = "iso6336",
    cells_per_line: int | None = None,
    mesh: Mesh | None = None,
    encoder_position: int = 1,
    max_frequency_hz: float | None = None,
    nlte_reaction: str = "drive",
    te_table=None,
    moving_events: bool = True,
    **kwargs,
) -> TorsionalModel | Geared3DModel:
    """The dynamic model of ``rig`` with tooth modifications ``mods`` (default none).

    The torsional build is traceable in ``mods`` and its array options (``jit``, ``vmap``,
    ``jax.jacfwd`` of "build, simulate, take a metric"); the 3D build is not
    (:class:`ModelError` for traced ``mods``: differentiate
    ``model.with_modifications(mods)`` of a model built at a concrete design instead).

    Parameters
    ----------
    rig : a built-in rig or a rig file (:func:`gearjax.rigs.registry.get_rig`).
    model : ``"3d"`` (the rig's structure with the pinion-gear element,
        :meth:`Geared3DModel.build`) or ``"torsional"`` (sdof, default inertias,
        :meth:`TorsionalModel.build`).
    law, cells_per_line : mesh stiffness law and cells per contact line of the mesh built
        from ``rig.pair``; ``mesh`` instead: a ready mesh of that pair.
    encoder_position : 3D: the rig's encoder position (Fig. 7) defining TE and DTE
        (``encoder_nodes=`` overrides it); the torsional model has none and ignores it.
    max_frequency_hz : 3D: modal cut-off (Hz) of the reduced model, None: all modes
        (:func:`gearjax.models.geared3d.default_max_frequency_hz` gives the rule used by the
        command line); must stay None for the torsional model.
    nlte_reaction : where the NLTE'' reaction torque acts (:mod:`gearjax.models.torsional`):
        ``"drive"`` (default, every model and command) or, torsional model only,
        ``"pinion"`` (Eqs. (15)-(16)); the 3D model puts it at its torque node (Eq. (14)).
    te_table : a :class:`gearjax.excitation.te_file.TETable` (a TE file, paper Section
        6.2) driving the te/perturbation formulations (torsional:
        :meth:`TorsionalModel.with_te`; 3D: ``Geared3DModel.build(te_table=)``, TE_S read at
        the model's encoders).
    moving_events : 3D te/perturbation: False builds the table without the angle map that
        moves its switching angles with the design (forward sweeps need none; the build
        compiles faster); the torsional model keeps its map (it costs little).
    kwargs : go to the model's ``build`` (``formulation``, ``damping_ratio``,
        ``nlte_terms``, ``max_frequency_hz``, ...). Defaults taken from the rig:
        ``pinion_torque_Nm`` (C_m0, N m), ``backlash_m`` (the clearance between the back
        flanks, m; None: none, :mod:`gearjax.gears.backlash`) and, 3D, ``torque_node``
        (the motor node) and ``encoder_nodes``.
    """
    if model not in MODELS:
        raise ModelError("model", model, f"must be one of {MODELS}")
    if mesh is None:
        mesh = Mesh.build(rig.pair, law, cells_per_line=cells_per_line,
                          pinion_torque_Nm=rig.pinion_torque_Nm)
    kwargs.setdefault("pinion_torque_Nm", rig.pinion_torque_Nm)
    kwargs.setdefault("backlash_m", rig.backlash_m)
    if model == "torsional":
        if max_frequency_hz is not None:
            raise ModelError("max_frequency_hz", max_frequency_hz,
                             "the torsional model has no modal cut-off")
        sdof = TorsionalModel.build(mesh, mods, nlte_reaction=nlte_reaction, **kwargs)
        return sdof if te_table is None else sdof.with_te(te_table, kwargs.get("nlte_terms"))
    if mods is not None and any(isinstance(a, jax.core.Tracer) for a in jax.tree_util.tree_leaves(mods)):
        raise ModelError("mods", "traced", "the 3D build is not traceable (its modal basis "
                         "is computed in NumPy): build at a concrete design and differentiate "
                         "model.with_modifications(mods), as gearjax.design.DynamicObjective "
                         "does (the torsional build is traceable)")
    if nlte_reaction not in NLTE_REACTIONS:
        raise ModelError("nlte_reaction", nlte_reaction, f"must be one of {NLTE_REACTIONS}")
    if nlte_reaction != "drive":
        raise ModelError("nlte_reaction", nlte_reaction, NLTE_REACTION_3D)
    kwargs.setdefault("torque_node", rig.torque_node)
    if "encoder_nodes" not in kwargs:
        kwargs["encoder_nodes"] = rig.encoder_nodes(encoder_position)
    return Geared3DModel.build(rig.structure(), mesh, mods, max_frequency_hz=max_frequency_hz,
                               te_table=te_table, moving_events=moving_events, **kwargs)

