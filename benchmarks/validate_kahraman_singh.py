"""Backlash validation (gearjax issue 49): the Kahraman & Singh (1991) dimensionless gear pair
through a TE file, against an independent SciPy integration with event location.

The case (``tests/oscillators.py::KahramanSingh``)::

    x'' + 2 zeta x' + K(tau) g(x) = F_m + sum_j F_te,j (j W)^2 cos(j W tau)
    zeta 0.05, b = 1, F_m 0.1, K = 1 - 0.2 cos W tau - 0.1 cos 2 W tau - 0.05 cos 3 W tau

case A with the issue's ``F_te = 0.01 / 0.004 / 0.002`` (no-impact and single-sided
regimes) and case B with twenty times that forcing (``0.2 / 0.08 / 0.04``, which reaches the
back flanks: double-sided impacts), mapped to a gear pair (m = 0.23 kg, k_m = 3.8e8 N/m,
clearance 0.1 mm, z1 = 16) and fed to gearjax's sdof te formulation through ``--te-file``'s
reader (``tests/oscillators.py::ks_te_file``, ``ks_gear_model``).

Compared, up and down in speed: SciPy brute-force transient sweeps (DOP853, rtol 1e-11, the
contact switches x = 0 and x = -b located as events and the integration restarted there),
gearjax brute-force transient sweeps (same transient lengths, same start) and gearjax's
natural-parameter continuation (:func:`gearjax.dynamics.continuation.continuation_sweep`);
then the error of gearjax's metrics against SciPy's on periodic orbits of each regime at
the default tolerance and tighter ones.

Usage::

    PYTHONPATH=. python benchmarks/validate_kahraman_singh.py [--out docs/validation]

writes ``kahraman-singh.csv``, ``kahraman-singh.png`` and ``kahraman-singh.txt`` (the
tables of ``docs/validation.md``, Markdown) into ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

import jax.numpy as jnp  # noqa: E402

from oscillators import (KS_LENGTH_M, KS_STIFFNESS_N_PER_M, KahramanSingh,  # noqa: E402
                         impact_regime, ks_gear_model, ks_gearjax_sweep, ks_speed_rad_s,
                         ks_state, ks_te_file)

CASES = {  # name: (F_te, dimensionless speeds)
    "A": ((0.01, 0.004, 0.002), np.round(np.arange(0.40, 1.6001, 0.05), 3)),
    "B": ((0.2, 0.08, 0.04), np.round(np.arange(0.60, 1.1001, 0.05), 3)),
}
START = (0.1, 0.0)  # the first speed's start (x, x'), both brute-force sweeps
REGIME_OF = {(False, False): "none", (True, False): "single", (True, True): "double"}


def regime_g(r) -> str:
    return REGIME_OF[(bool(r["contact_loss"]), bool(r["back_contact"]))]


def jumps(rows, key="regime", threshold=0.2):
    """Neighbouring speed pairs (in the sweep's order) where the regime changes or the max
    force changes by more than ``threshold`` of the smaller."""
    out = []
    for a, b in zip(rows[:-1], rows[1:]):
        big = abs(a["f_max"] - b["f_max"]) > threshold * min(a["f_max"], b["f_max"])
        if a[key] != b[key] or big:
            out.append((a["w"], b["w"]))
    return out


def continuation(model, ws, direction):
    from gearjax.dynamics.continuation import continuation_sweep

    res = continuation_sweep(model, ks_speed_rad_s(model, ws), direction)
    f_ref = KS_STIFFNESS_N_PER_M * KS_LENGTH_M
    order = np.argsort(ws) if direction == "up" else np.argsort(ws)[::-1]
    return [dict(w=float(ws[i]), f_max=float(res.max_mesh_force_N[i]) / f_ref,
                 f_min=float(res.min_mesh_force_N[i]) / f_ref,
                 contact_loss=bool(res.contact_loss[i]), back_contact=bool(res.back_contact[i]),
                 stable=bool(res.stats["stable"][i])) for i in order]


def accuracy(ks, model, ws, rtols):
    """max |f_gearjax - f_scipy| (over max and min force, dimensionless) on SciPy's periodic
    orbits at ``ws``, per gearjax rtol (atol rtol/100)."""
    from gearjax.dynamics.simulate import simulate

    out = {}
    for w in ws:
        y, _, _, _ = ks.integrate(w, np.asarray(START), 0.0,
                                  3 * ks.transient_periods(w) * 2 * np.pi / w)
        ref = ks.measure(w, y)
        y0 = jnp.asarray(ks_state(ks, model, y))
        om = float(ks_speed_rad_s(model, w))
        for rt in rtols:
            r = simulate(model, om, n_transient_periods=0, y0=y0, rtol=rt, atol=rt / 100)
            f = KS_STIFFNESS_N_PER_M * KS_LENGTH_M
            err = max(abs(float(r.max_mesh_force_N) / f - ref["f_max"]),
                      abs(float(r.min_mesh_force_N) / f - ref["f_min"]))
            out[(float(w), rt)] = (impact_regime(ref["regimes"]), err, int(r.n_steps))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join("docs", "validation"))
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    rows, md, accuracy_rows = [], [], {}
    curves = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, (f_te, ws) in CASES.items():
            ks = KahramanSingh(f_te=f_te)
            path = os.path.join(tmp, f"ks{name}.csv")
            ks_te_file(path, ks)
            model = ks_gear_model(ks, path)
            for direction in ("up", "down"):
                seq = ws if direction == "up" else ws[::-1]
                sp = ks.sweep(seq, START)
                for r in sp:
                    r["regime"] = impact_regime(r["regimes"])
                gj = ks_gearjax_sweep(ks, model, seq, START)
                co = continuation(model, seq, direction)
                for r in gj + co:
                    r["regime"] = regime_g(r)
                curves[(name, direction)] = (sp, gj, co)
                for a, b, c in zip(sp, gj, co):
                    rows.append(dict(case=name, direction=direction, W=a["w"],
                                     speed_rad_s=float(ks_speed_rad_s(model, a["w"])),
                                     scipy_regime=a["regime"], scipy_f_max=a["f_max"],
                                     scipy_f_min=a["f_min"], transient_regime=b["regime"],
                                     transient_f_max=b["f_max"], transient_f_min=b["f_min"],
                                     continuation_regime=c["regime"],
                                     continuation_f_max=c["f_max"],
                                     continuation_f_min=c["f_min"],
                                     continuation_stable=c["stable"]))
                md.append((name, direction, jumps(sp), jumps(gj), jumps(co)))
            acc_ws = [0.9, 1.5] if name == "A" else [0.6, 1.0]
            accuracy_rows[name] = accuracy(ks, model, acc_ws, (1e-7, 1e-9, 1e-11))
    with open(os.path.join(args.out, "kahraman-singh.csv"), "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
        wr.writeheader()
        wr.writerows(rows)
    _figure(curves, os.path.join(args.out, "kahraman-singh.png"))
    text = _markdown(rows, md, accuracy_rows)
    with open(os.path.join(args.out, "kahraman-singh.txt"), "w") as fh:
        fh.write(text)
    print(text)
    return 0


def _markdown(rows, md, accuracy_rows) -> str:
    out = ["| case | sweep | jumps, SciPy | jumps, gearjax transient | jumps, gearjax continuation |",
           "|---|---|---|---|---|"]
    fmt = lambda js: ", ".join(f"{a:.2f}→{b:.2f}" for a, b in js) or "none"  # noqa: E731
    for name, direction, a, b, c in md:
        out.append(f"| {name} | {direction} | {fmt(a)} | {fmt(b)} | {fmt(c)} |")
    out += ["", "| case | sweep | W | regime SciPy / transient / continuation | "
            "max F SciPy | max F transient | max F continuation | min F SciPy | min F transient |",
            "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['case']} | {r['direction']} | {r['W']:.2f} | {r['scipy_regime']} / "
                   f"{r['transient_regime']} / {r['continuation_regime']} | "
                   f"{r['scipy_f_max']:.6f} | {r['transient_f_max']:.6f} | "
                   f"{r['continuation_f_max']:.6f} | {r['scipy_f_min']:.6f} | "
                   f"{r['transient_f_min']:.6f} |")
    out += ["", "| case | W | regime | gearjax rtol | max abs. error of max/min F (of k_m L) "
            "| steps |", "|---|---|---|---|---|---|"]
    for name in CASES:
        for (w, rt), (reg, err, steps) in accuracy_rows[name].items():
            out.append(f"| {name} | {w:.2f} | {reg} | {rt:g} | {err:.1e} | {steps} |")
    return "\n".join(out) + "\n"


def _figure(curves, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(CASES), figsize=(11, 4.2), constrained_layout=True)
    marks = {"none": "o", "single": "s", "double": "X"}
    for ax, name in zip(np.atleast_1d(axes), CASES):
        for direction, color in (("up", "tab:blue"), ("down", "tab:red")):
            sp, gj, co = curves[(name, direction)]
            w = [r["w"] for r in sp]
            for key, ls in (("f_max", "-"), ("f_min", "--")):
                ax.plot(w, [r[key] for r in sp], ls, color=color, lw=1.0,
                        label=f"SciPy {direction}, {key[2:]} force")
                for r in gj:
                    ax.plot(r["w"], r[key], marks[r["regime"]], color=color, mfc="none", ms=7)
                for r in co:
                    ax.plot(r["w"], r[key], ".", color="k", ms=3)
        for reg, m in marks.items():
            ax.plot([], [], m, color="0.3", mfc="none", label=f"gearjax transient: {reg} impacts"
                    if reg != "none" else "gearjax transient: no impact")
        ax.plot([], [], ".", color="k", label="gearjax continuation")
        ax.axhline(0.0, color="0.6", lw=0.6)
        f_te = CASES[name][0]
        ax.set_title(f"case {name}: F_te = {f_te[0]:g} / {f_te[1]:g} / {f_te[2]:g}")
        ax.set_xlabel("W = mesh frequency / natural frequency")
        ax.set_ylabel("mesh force K(tau) g(x) (of k_m b)")
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
