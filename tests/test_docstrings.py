"""Docstrings and comments are contracts (ARCHITECTURE "Rules of the house"): they say what
is computed, in which units, under which assumptions and what is raised. Measurements live
in ``benchmarks/results/``, history in commit messages, so no docstring or comment in
``gearjax/`` carries a commit hash, an ISO date or a wall-clock timing, and module
docstrings stay short unless they state theory.

Docstrings are read with ``ast`` and comments with ``tokenize``, so the test needs no import
of gearjax.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "gearjax"

# a commit hash (7 to 40 hex digits with at least one digit and one letter), an ISO date,
# a wall-clock timing ("12 s", "3.5 min", "40ms")
FORBIDDEN = re.compile(
    r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b"
    r"|\b20\d\d-[01]\d-[0-3]\d\b"
    r"|\b\d+(?:\.\d+)?\s?(?:ms|min|s)\b"
)

MAX_MODULE_DOCSTRING_LINES = 40
# modules whose docstring states theory and may be longer (module: reason); keep it short
THEORY_DOCSTRINGS = {
    "gearjax.dynamics.harmonic": "derives the rank-one Hill equation (1)-(2) and its exact jumps",
    "gearjax.gears.weber": "states Weber-Banaschek, O'Donnell/Sainsot and Hertz compliances",
    "gearjax.gears.iso6336": "states ISO 6336-1 method B's equations and the accuracy defaults",
    "gearjax.models.geared3d": "states the 3D equations (14), (42), (48a), outputs, state",
    "gearjax.models.torsional": "states the sdof equations (16), (20), (47a), NLTE substitution",
    "gearjax.rigs.baud_velex": "the rig's data and the assumptions the paper does not print",
    "gearjax.rigs.rigfile": "the rig-file schema, the format's only specification",
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _sources() -> list[tuple[Path, str]]:
    return [(p, p.read_text()) for p in sorted(PKG.rglob("*.py"))]


def _docstrings(tree: ast.Module):
    """(first line, text) of the module, class and function docstrings."""
    nodes = [tree] + [n for n in ast.walk(tree)
                      if isinstance(n, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))]
    for node in nodes:
        if (node.body and isinstance(node.body[0], ast.Expr)
                and isinstance(node.body[0].value, ast.Constant)
                and isinstance(node.body[0].value.value, str)):
            yield node.body[0].lineno, node.body[0].value.value


def _comments(source: str):
    """(line, text) of every comment."""
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            yield tok.start[0], tok.string


def _hits(path: Path, source: str) -> list[str]:
    rel = path.relative_to(PKG.parent)
    out = []
    texts = list(_docstrings(ast.parse(source, filename=str(path)))) + list(_comments(source))
    for line, text in texts:
        for m in FORBIDDEN.finditer(text):
            out.append(f"{rel}:{line + text.count(chr(10), 0, m.start())}: {m.group(0)!r}")
    return sorted(out, key=lambda s: (s.split(":")[0], int(s.split(":")[1])))


def test_no_hash_date_or_timing_in_docstrings_and_comments():
    hits = [h for path, source in _sources() for h in _hits(path, source)]
    assert not hits, (f"{len(hits)} commit hashes, dates or timings in gearjax/ docstrings or "
                      "comments (measurements go to benchmarks/results/, history to commit "
                      "messages):\n" + "\n".join(hits))


def test_module_docstrings_are_short_unless_they_state_theory():
    modules = {_module_name(p): s for p, s in _sources()}
    unknown = sorted(set(THEORY_DOCSTRINGS) - set(modules))
    assert not unknown, f"allow-listed modules that do not exist: {unknown}"
    long, short = [], []
    for mod, source in modules.items():
        doc = ast.get_docstring(ast.parse(source), clean=False)
        n = len(doc.splitlines()) if doc else 0
        if n > MAX_MODULE_DOCSTRING_LINES and mod not in THEORY_DOCSTRINGS:
            long.append(f"{mod}: {n} lines")
        if n <= MAX_MODULE_DOCSTRING_LINES and mod in THEORY_DOCSTRINGS:
            short.append(mod)
    assert not short, f"allow-listed modules now within the limit (drop them): {short}"
    assert not long, (f"module docstrings over {MAX_MODULE_DOCSTRING_LINES} lines that do "
                      "not state theory (cut them to their contract):\n" + "\n".join(long))
