"""Every code block of README.md is executed or checked here, so the front door cannot rot.

How each kind of block is exercised:

* ``python`` blocks run top to bottom in a fresh ``python`` subprocess, in a temporary
  folder, with this session's environment (float64, the shared compilation cache of
  ``tests/conftest.py``); a block that raises or exits non-zero fails the test.
* ``bash`` blocks are *not* run as they stand (they create virtual environments and
  install the package). They are checked instead:
  - the first block is the main job: it installs the package and runs ``gearjax sweep``;
    its ``gearjax`` command is parsed by the real argument parser;
  - the second block is the test command, which must appear verbatim in ``.ci/run``
    (CI runs exactly the README's command);
  - every other line starting with ``gearjax`` is parsed by the real argument parser
    (``gearjax.cli.main``), so every command and option it names exists and every value
    it gives is accepted. The commands themselves are run at reduced size by
    ``tests/test_cli*.py``.
* ``bibtex`` blocks must agree with the paper reference in ``CITATION.cff``.

The README's shape is checked too: at most 200 lines, no commit hash, no date, and every
relative link names a file of the checkout.
"""

from __future__ import annotations

import importlib
import os
import pathlib
import re
import shlex
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)


def blocks(kind: str | None = None) -> list[str]:
    """The fenced code blocks of README.md (of language ``kind``), in order."""
    found = [(lang, body) for lang, body in FENCE.findall(README.read_text())]
    return [body for lang, body in found if kind is None or lang == kind]


def gearjax_commands(text: str) -> list[list[str]]:
    """argv (without the program name) of every ``gearjax ...`` command in shell text:
    comments dropped, continuation lines joined, ``&&`` chains split."""
    text = text.replace("\\\n", " ")
    out = []
    for line in text.splitlines():
        for part in line.split("&&"):
            words = shlex.split(part, comments=True)
            if words and words[0] == "gearjax":
                out.append(words[1:])
    return out


def parse(argv: list[str]):
    """Parse with the command line's own parser; argparse's exit is a test failure."""
    cli = importlib.import_module("gearjax.cli.main")  # the package exports main()

    try:
        return cli._parser().parse_args(argv)
    except SystemExit as e:  # argparse reports an unknown option or bad value by exiting
        pytest.fail(f"'gearjax {' '.join(argv)}' is rejected by the argument parser ({e})")


def test_readme_shape():
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    assert not re.search(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b", text), "a commit hash in README.md"
    # the only date allowed is the citation's year
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", text), "a date in README.md"
    kinds = {lang for lang, _ in FENCE.findall(text)}
    assert kinds <= {"bash", "python", "bibtex"}, f"a code block nobody checks: {kinds}"


def test_readme_setup_commands():
    """The two first blocks: the main job and the test command CI runs verbatim."""
    main_job, tests = (b.strip() for b in blocks("bash")[:2])
    assert main_job == "python3 -m venv .venv && . .venv/bin/activate && pip install -q . && gearjax sweep"
    (argv,) = gearjax_commands(main_job)
    assert parse(argv).command == "sweep"
    assert tests.startswith("python3 -m venv .venv && . .venv/bin/activate && pip install -q -e '.[dev]'")
    assert tests in (ROOT / ".ci" / "run").read_text(), "CI must run the README's test command"


def test_readme_cli_lines_parse():
    shell = blocks("bash")[2:]
    commands = [argv for b in shell for argv in gearjax_commands(b)]
    assert len(commands) >= 5
    names = set()
    for argv in commands:
        names.add(parse(argv).command)
    assert {"info", "quasistatic", "sweep", "optimise", "paper"} <= names


def test_readme_bibtex_matches_citation_cff():
    (bib,) = blocks("bibtex")
    cff = (ROOT / "CITATION.cff").read_text()
    def bib_field(name):
        return re.search(rf"^\s*{name}\s*=\s*\{{(.*)\}},?$", bib, re.M).group(1)

    for field in ("title", "journal", "volume", "year", "doi"):
        assert bib_field(field) in cff, field
    first, last = bib_field("pages").split("--")
    assert f"start: {first}" in cff and f"end: {last}" in cff
    for surname in ("Velex", "Ajmi"):
        assert surname in bib and surname in cff


@pytest.mark.parametrize("index", range(len(blocks("python"))))
def test_readme_python_block_runs(index, tmp_path):
    code = blocks("python")[index]
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": os.pathsep.join(
        [str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]
    if "savefig" in code:  # the quick start's figure was written
        assert any(tmp_path.glob("*.png"))
    if "ev.grad" in code:  # the gradient was printed and is finite
        assert "gradient" in proc.stdout and "nan" not in proc.stdout.lower()


def test_readme_links_resolve():
    """Every relative link and image of README.md names a file or folder of the checkout
    (the README is read on GitHub and in the sdist, before any site is built)."""
    text = README.read_text()
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    local = [t.split("#")[0] for t in targets if "://" not in t and not t.startswith("#")]
    assert len(local) >= 10
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, missing
