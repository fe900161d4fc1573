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
          "design", "plotting", "cli")
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
