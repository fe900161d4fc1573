"""The documentation site: built in strict mode, complete, and its examples alive.

* ``mkdocs build --strict`` runs from the repository root into a temporary folder (a few
  seconds: notebooks are rendered with their stored outputs, not executed; they are
  executed by ``tests/test_notebooks.py``). Strict mode fails on a broken link, a missing
  page in the nav, an unresolved API cross-reference or a docstring mkdocstrings cannot
  parse.
* The command-line reference is generated from the argument parser at build time
  (``docs/hooks.py``); the built page is checked to hold every command and option.
* The Python API reference (``docs/reference/api.md``) documents exactly the public names
  re-exported by ``gearjax/__init__.py``, and ``docs/reference/design.md`` every name of
  ``gearjax.design.__all__``.
* Every ``python`` block of the pages listed in :data:`RUN_PAGES` runs, page by page, in a
  fresh subprocess whose working folder holds ``examples/`` (as a user's checkout does);
  the ``gearjax quasistatic`` lines of their ``bash`` blocks run first (the TE-file page
  reads the CSV they write). Every other ``gearjax ...`` line of every page is parsed by
  the command line's own parser: the commands themselves run at reduced size in
  ``tests/test_cli*.py``.
* Pages other than the Performance page and the generated ``docs/paper/`` carry no commit
  hash and no date (measurements live in ``benchmarks/results/``).
"""

from __future__ import annotations

import ast
import importlib
import os
import pathlib
import re
import shlex
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)
PAGES = sorted(p for p in DOCS.rglob("*.md") if "paper" not in p.relative_to(DOCS).parts)
RUN_PAGES = ["getting-started.md", "tutorials/own-rig.md", "tutorials/te-file.md"]
MKDOCS_TIMEOUT_S = 300


def _blocks(page: pathlib.Path, kind: str) -> list[str]:
    return [body for lang, body in FENCE.findall(page.read_text()) if lang == kind]


def _gearjax_lines(text: str) -> list[list[str]]:
    out = []
    for line in text.replace("\\\n", " ").splitlines():
        for part in line.split("&&"):
            words = shlex.split(part, comments=True)
            if words and words[0] == "gearjax":
                out.append(words[1:])
    return out


def _parser():
    return importlib.import_module("gearjax.cli.main")._parser()  # the package exports main()


def _env():
    return {**os.environ, "MPLBACKEND": "Agg", "NO_MKDOCS_2_WARNING": "1",
            "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
                          cwd=ROOT, env=_env(), capture_output=True, text=True,
                          timeout=MKDOCS_TIMEOUT_S)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-6000:]
    return out


def test_docs_build_strict(site):
    for page in ("index.html", "getting-started/index.html", "reference/api/index.html",
                 "reference/cli/index.html", "tutorials/tip_relief_design/index.html",
                 "paper/index.html", "validation/index.html"):
        assert (site / page).is_file(), page


def test_cli_reference_lists_every_command_and_option(site):
    import html

    text = html.unescape((site / "reference" / "cli" / "index.html").read_text())
    parser = _parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        assert f"gearjax {name}" in text, name
        for action in p._actions:
            for flag in action.option_strings:
                assert flag in text, (name, flag)


def _reexported(init: pathlib.Path) -> set[str]:
    """Names re-exported as ``from .x import Y as Y`` (the package's public API)."""
    names = set()
    for node in ast.parse(init.read_text()).body:
        if isinstance(node, ast.ImportFrom) and node.level >= 1:
            names |= {a.name for a in node.names if a.asname == a.name}
    return names


def _documented(page: pathlib.Path, prefix: str) -> set[str]:
    return set(re.findall(rf"^::: {re.escape(prefix)}\.(\w+)\s*$", page.read_text(), re.M))


def test_api_reference_covers_every_public_name():
    public = _reexported(ROOT / "gearjax" / "__init__.py")
    assert len(public) > 30
    documented = _documented(DOCS / "reference" / "api.md", "gearjax")
    assert public - documented == set(), "public names missing from docs/reference/api.md"
    assert documented - public == set(), "docs/reference/api.md documents non-public names"


def test_design_reference_covers_design_all():
    import gearjax.design

    documented = _documented(DOCS / "reference" / "design.md", "gearjax.design")
    missing = set(gearjax.design.__all__) - documented - {"DesignError"}  # in api.md
    assert missing == set(), missing


def test_every_shell_command_in_the_docs_parses():
    parser = _parser()
    seen = 0
    for page in PAGES:
        for block in _blocks(page, "bash"):
            for argv in _gearjax_lines(block):
                seen += 1
                try:
                    parser.parse_args(argv)
                except SystemExit as e:
                    pytest.fail(f"{page.name}: 'gearjax {' '.join(argv)}' is rejected ({e})")
    assert seen >= 8


@pytest.mark.parametrize("page", RUN_PAGES)
def test_docs_python_blocks_run(page, tmp_path):
    path = DOCS / page
    code = "\n\n".join(_blocks(path, "python"))
    assert code, f"{page} has no python block"
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    from gearjax.cli.main import main

    for block in _blocks(path, "bash"):
        for argv in _gearjax_lines(block):
            if argv[0] == "quasistatic":  # seconds; writes the files the Python reads
                cwd = os.getcwd()
                try:
                    os.chdir(tmp_path)
                    assert main(argv) == 0
                finally:
                    os.chdir(cwd)
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=_env(),
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]


@pytest.mark.parametrize("page", [p for p in PAGES if p.name != "performance.md"],
                         ids=lambda p: str(p.relative_to(DOCS)))
def test_no_history_in_the_docs(page):
    text = page.read_text()
    assert not re.search(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b", text), "a commit hash"
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", text), "a date"
