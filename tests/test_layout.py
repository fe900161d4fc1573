"""The package layout keeps its promises (docs/development.md, "Architecture"): imports flow one way
down the layers, no import cycles, no private name imported across modules, no model
probed with hasattr/getattr, and no module grows into a monolith.

The imports are read from the source with ``ast`` (function-level imports included: a lazy
import is still a dependency), so the test needs no import of gearjax.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "gearjax"

# layers from the top of the data flow down to the command line; a module may import its
# own layer and the layers before it, never a later one
LAYERS = ("errors", "linalg", "gears", "structure", "excitation", "models", "dynamics", "rigs",
          "design", "runtime", "plotting", "cli")
# the layers that may act on the host process (print, read the environment, start threads,
# clear JAX's caches, set another package's state); the physics below them never does
HOST_LAYERS = ("runtime", "plotting", "cli")
MAX_LINES = 700


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def _resolve(module: str, is_package: bool, level: int, name: str | None) -> str:
    if level == 0:
        return name or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _imports(modules: dict[str, Path]):
    """(importer, imported module, imported names, line) for every gearjax import."""
    out = []
    for mod, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(mod, is_pkg, node.level, node.module)
                if not target.startswith("gearjax"):
                    continue
                names = [a.name for a in node.names]
                # "from . import x" / "from .pkg import sub": x may be a module
                subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in modules]
                if subs:
                    out += [(mod, s, [], node.lineno) for s in subs]
                    names = [n for n in names if f"{target}.{n}" not in modules]
                    if not names:
                        continue
                out.append((mod, target, names, node.lineno))
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith("gearjax"):
                        out.append((mod, a.name, [], node.lineno))
    return out


def _layer(module: str) -> int | None:
    parts = module.split(".")
    if len(parts) < 2:
        return None  # the package root re-exports everything
    return LAYERS.index(parts[1]) if parts[1] in LAYERS else -1


def test_every_module_belongs_to_a_layer():
    unknown = sorted(m for m in _modules() if _layer(m) == -1)
    assert not unknown, f"modules outside the declared layers {LAYERS}: {unknown}"


def test_no_import_from_a_later_layer():
    bad = []
    for mod, target, _, line in _imports(_modules()):
        lm, lt = _layer(mod), _layer(target)
        if lm is None or lt is None:
            continue
        if lt > lm:
            bad.append(f"{mod}:{line} imports {target} ({LAYERS[lm]} -> {LAYERS[lt]})")
    assert not bad, "upward imports:\n" + "\n".join(bad)


def test_no_import_cycle():
    modules = _modules()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for mod, target, _, _ in _imports(modules):
        # a package import runs its __init__: depend on the package module itself
        while target not in modules and "." in target:
            target = target.rsplit(".", 1)[0]
        if target in modules and target != mod and _layer(mod) is not None \
                and _layer(target) is not None:
            graph[mod].add(target)
    state: dict[str, int] = {}
    cycles = []

    def visit(m, stack):
        state[m] = 1
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                cycles.append(" -> ".join(stack[stack.index(t):] + [t]))
            elif t not in state:
                visit(t, stack)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_no_private_name_imported_across_modules():
    bad = [f"{mod}:{line} imports {n} from {target}"
           for mod, target, names, line in _imports(_modules())
           for n in names if n.startswith("_") and not n.startswith("__")]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("probe", ["hasattr", "getattr"])
def test_solvers_do_not_probe_models(probe):
    """Solvers ask a model only what :class:`gearjax.models.base.AbstractGearModel`
    declares: no ``hasattr(model, ...)`` / ``getattr(model, ...)``."""
    bad = []
    for mod, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id == probe and node.args
                    and isinstance(node.args[0], (ast.Name, ast.Attribute))):
                arg = ast.unparse(node.args[0])
                if arg == "model" or arg.endswith(".model") or arg.startswith("model."):
                    bad.append(f"{mod}:{node.lineno} {ast.unparse(node)}")
    assert not bad, "\n".join(bad)


def test_no_monolith():
    long = {m: len(p.read_text().splitlines()) for m, p in _modules().items()}
    long = {m: n for m, n in long.items() if n > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines (split by concept): {long}"


# what acts on the process: printing, the environment, threads, JAX's caches, another
# package's private state, ending the process
_SIDE_EFFECTS = {
    "print": lambda n: isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
    and n.func.id == "print",
    "os.environ / os.getenv": lambda n: isinstance(n, ast.Attribute) and n.attr in (
        "environ", "getenv", "putenv") and ast.unparse(n.value) == "os",
    "threading": lambda n: isinstance(n, (ast.Import, ast.ImportFrom)) and any(
        a.name.split(".")[0] == "threading" for a in n.names) or (
        isinstance(n, ast.ImportFrom) and (n.module or "").split(".")[0] == "threading"),
    "clear_caches": lambda n: isinstance(n, ast.Attribute) and n.attr == "clear_caches",
    "equinox._errors": lambda n: isinstance(n, ast.ImportFrom) and (
        n.module == "equinox._errors" or (n.module == "equinox"
                                          and any(a.name == "_errors" for a in n.names))),
    "os._exit / sys.exit": lambda n: isinstance(n, ast.Attribute) and ast.unparse(n) in (
        "os._exit", "sys.exit"),
}


def _library_trees():
    """(module, syntax tree) of every module below the host layers (:data:`HOST_LAYERS`)."""
    for mod, path in _modules().items():
        parts = mod.split(".")
        if len(parts) < 2 or parts[1] not in HOST_LAYERS:
            yield mod, ast.parse(path.read_text())


def test_library_has_no_side_effects():
    """Below the host layers (:data:`HOST_LAYERS`) no module prints, reads or writes the
    environment, starts threads, clears JAX's caches, touches equinox's private state or
    ends the process (issue 47): those belong to :mod:`gearjax.runtime` and the command
    line; the library reports progress through the meter it is given."""
    bad = []
    for mod, tree in _library_trees():
        for node in ast.walk(tree):
            for what, hit in _SIDE_EFFECTS.items():
                if hit(node):
                    bad.append(f"{mod}:{node.lineno} {what}")
    assert not bad, "side effects below the host layers:\n" + "\n".join(sorted(set(bad)))


def test_the_side_effect_check_sees_them():
    """The check above finds each kind it names (it could otherwise pass on nothing)."""
    src = ("import os, sys, threading\nfrom equinox import _errors\nprint(1)\n"
           "os.environ.get('X')\njax.clear_caches()\nos._exit(3)\n")
    found = {what for node in ast.walk(ast.parse(src))
             for what, hit in _SIDE_EFFECTS.items() if hit(node)}
    assert found == set(_SIDE_EFFECTS)


def test_importing_gearjax_leaves_the_process_alone():
    """``import gearjax`` changes no environment variable (XLA_FLAGS included) and starts
    no thread: the host layer acts only when called (:func:`gearjax.runtime.configure`)."""
    import subprocess
    import sys

    code = ("import os, threading; env = dict(os.environ); n = threading.active_count(); "
            "import gearjax; assert dict(os.environ) == env, "
            "{k for k in set(env) | set(os.environ) if env.get(k) != os.environ.get(k)}; "
            "assert threading.active_count() == n; "
            "import jax; assert jax.config.jax_enable_x64")
    for flags in (None, "", "--xla_cpu_foo=1"):
        env = {k: v for k, v in __import__("os").environ.items() if k != "XLA_FLAGS"}
        if flags is not None:
            env["XLA_FLAGS"] = flags
        run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=120)
        assert run.returncode == 0, run.stderr[-1500:]


def test_every_environment_variable_is_documented():
    """Every ``GEARJAX_*`` variable the package or the notebooks read has a row in
    docs/environment.md (issue 47: one table, each with a reason)."""
    import re

    root = PKG.parent
    names = set()
    for path in [*PKG.rglob("*.py"), *(root / "notebooks").glob("*.ipynb")]:
        names |= set(re.findall(r"GEARJAX_[A-Z_]+[A-Z]", path.read_text()))
    doc = (root / "docs" / "environment.md").read_text()
    rows = set(re.findall(r"^\| `(GEARJAX_[A-Z_]+)", doc, flags=re.M))
    assert names and names <= rows, f"undocumented: {sorted(names - rows)}"


def test_one_diffeqsolve_call_site():
    """Every integration goes through :func:`gearjax.dynamics.integrate.integrate` (issue 46):
    one ``diffeqsolve`` call in the package, under the jump-aware step-size controller."""
    calls = [f"{mod}:{node.lineno}" for mod, path in _modules().items()
             for node in ast.walk(ast.parse(path.read_text()))
             if isinstance(node, ast.Call) and ast.unparse(node.func).endswith("diffeqsolve")]
    assert len(calls) == 1 and calls[0].startswith("gearjax.dynamics.integrate:"), calls
    controllers = [f"{mod}:{node.lineno}" for mod, path in _modules().items()
                   for node in ast.walk(ast.parse(path.read_text()))
                   if isinstance(node, ast.Call)
                   and ast.unparse(node.func).endswith("PIDController")]
    assert all(c.startswith("gearjax.dynamics.integrate:") for c in controllers), controllers


_SWEEPS = ("sweep", "steady_sweep", "harmonic_sweep", "continuation_sweep")


def test_no_solver_chosen_by_a_string_below_the_command_line():
    """The periodic solvers are objects (:mod:`gearjax.dynamics.solvers`, issue 46): below
    the host layers no function takes a ``method`` argument (the design objectives take a
    solver too), and the speed sweeps (:data:`_SWEEPS`) neither take ``**kwargs`` nor are
    called through such a tunnel: options are fields of the solver objects."""
    bad = []
    for mod, tree in _library_trees():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                names = [a.arg for a in node.args.args + node.args.kwonlyargs]
                # ROSS's own keyword for its shear-coefficient formula, mirrored: no solver
                mirrored = (mod, node.name) == ("gearjax.rigs.ross_bridge",
                                                "ross_shear_coefficient")
                if "method" in names and not mirrored:
                    bad.append(f"{mod}:{node.lineno} {node.name}(method=...)")
                if node.name in _SWEEPS and node.args.kwarg:
                    bad.append(f"{mod}:{node.lineno} {node.name}(**{node.args.kwarg.arg})")
            if isinstance(node, ast.Call) and ast.unparse(node.func) in _SWEEPS and any(
                    k.arg is None for k in node.keywords):
                bad.append(f"{mod}:{node.lineno} {ast.unparse(node.func)}(**...)")
    assert not bad, "\n".join(bad)


def test_the_model_interface_signals_no_capability_by_none():
    """What a solver may ask of a model is declared, never signalled by a method that
    returns None: the modal capabilities live on ``AbstractModalModel`` (abstract there),
    so the solvers ask ``isinstance``, not ``is None``."""
    tree = ast.parse((PKG / "models" / "base.py").read_text())
    found = []
    for cls in (n for n in tree.body if isinstance(n, ast.ClassDef)
                and n.name in ("AbstractGearModel", "AbstractModalModel")):
        for fn in (n for n in cls.body if isinstance(n, ast.FunctionDef)):
            for node in ast.walk(fn):
                if (isinstance(node, ast.Return) and isinstance(node.value, ast.Constant)
                        and node.value.value is None):
                    found.append(f"{cls.name}.{fn.name}")
    assert not found, found
    # and no solver asks a model for a capability by comparing with None
    dyn = [p for p in (PKG / "dynamics").glob("*.py")]
    asks = [f"{p.name}:{n.lineno}" for p in dyn for n in ast.walk(ast.parse(p.read_text()))
            if isinstance(n, ast.Compare) and isinstance(n.left, ast.Call)
            and isinstance(n.left.func, ast.Attribute)
            and isinstance(n.left.func.value, ast.Name) and n.left.func.value.id == "model"
            and any(isinstance(c, ast.Constant) and c.value is None for c in n.comparators)]
    assert not asks, asks


def test_one_sweep_result_type():
    """Every speed sweep returns a :class:`gearjax.dynamics.results.SweepResult` (issue 46):
    no class subclasses it (a subclass's extra fields would be dropped by ``take`` and
    ``merge_results``); solver-specific per-speed diagnostics go to its ``stats``."""
    subclasses = [f"{mod}:{node.lineno} {node.name}" for mod, path in _modules().items()
                  for node in ast.walk(ast.parse(path.read_text()))
                  if isinstance(node, ast.ClassDef)
                  and any(ast.unparse(b).split(".")[-1] == "SweepResult" for b in node.bases)]
    assert not subclasses, subclasses
