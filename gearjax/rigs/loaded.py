"""The mean mesh stiffness the dynamic models use, for reports beside the geometric one.

Two means of the mesh stiffness are in use, and ``gearjax info`` gives both:

* **geometric** ``k_m`` (``mean_mesh_stiffness_N_per_m``): the mean over a mesh period of
  ``sum k_i`` over every cell inside the path of contact (:meth:`gearjax.gears.mesh.Mesh.
  stiffness_variation`), a property of the pair and the stiffness law alone; for the
  ``iso6336`` law it is ISO 6336-1's ``c_gamma_alpha b``.
* **loaded** ``k_m`` (``loaded_mean_mesh_stiffness_N_per_m``): the mean over a mesh period of
  the stiffness of the cells *loaded* in the quasi-static solution ``(sum k_i)^S``
  (Section 6.2) with the tooth modifications in use; tip relief unloads the cells near the
  tips, so it is lower. This is the ``k_m`` of Eqs. (16)-(20) and (33) in every dynamic model
  (:class:`gearjax.models.torsional.TorsionalModel`, :class:`gearjax.models.geared3d.
  Geared3DModel`): their damping, natural frequencies, mesh-energy shares and predicted
  critical speeds (``gearjax sweep``, ``gearjax campbell``) read it. Each model takes it
  from its own excitation table, so the sdof and 3D values agree to the tables' resolution
  (spur rig, short relief: 738.91 against 739.43 N/um, 7e-4).

Without tooth modifications every cell of a perfect involute pair is loaded and the two
means coincide (to the quadrature of the two period grids).
"""

from __future__ import annotations

from ..gears.modifications import ToothModifications
from .factory import build_model
from .rig import Rig

__all__ = ["loaded_stiffness_figures"]


def loaded_stiffness_figures(rig: Rig, mods: ToothModifications | None, law: str = "iso6336") -> dict:
    """The dynamics' (loaded) mean mesh stiffness of ``rig`` with ``mods`` under ``law``
    (N/m), and the sdof natural frequency and critical speed it gives (rad/s;
    ``omega_n^2 = k_m cos^2(beta_b) / m_eq``, Eq. (16), ``Omega = omega_n / z1``)."""
    model = build_model(rig, mods, model="torsional", formulation="te", law=law)
    w = float(model.natural_frequency_rad_s())
    return {"loaded_mean_mesh_stiffness_N_per_m": float(model.k_m),
            "loaded_torsional_natural_frequency_rad_s": w,
            "loaded_torsional_critical_speed_rad_s": w / rig.pair.z1}
