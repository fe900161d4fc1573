"""MkDocs hooks.

* The command-line reference is generated from gearjax's own argparse parser at build
  time, so it lists every command and option that exists, and nothing else:
  ``docs/reference/cli.md`` holds the marker ``<!-- gearjax-cli-reference -->``, replaced
  by ``gearjax --help`` and each ``gearjax COMMAND --help`` as text blocks.
* gearjax's docstrings cross-reference in Sphinx roles (``:func:`name```), which
  mkdocstrings renders as the role's text before the code; the rendered pages keep the
  code and drop the role (and the ``~`` that shortens a path in Sphinx).
"""

from __future__ import annotations

import importlib
import os
import re

MARKER = "<!-- gearjax-cli-reference -->"


def cli_reference() -> str:
    """Markdown of every command's ``--help``, in the parser's order."""
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal width: a fixed one here
    cli = importlib.import_module("gearjax.cli.main")  # the package exports main()
    parser = cli._parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    parts = ["## `gearjax`", "", "```text", parser.format_help().rstrip(), "```", ""]
    for name, p in sub.choices.items():
        parts += [f"## `gearjax {name}`", "", "```text", p.format_help().rstrip(), "```", ""]
    return "\n".join(parts)


def on_page_markdown(markdown, page, config, files):
    if MARKER in markdown:
        return markdown.replace(MARKER, cli_reference())
    return markdown


_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|obj|exc|const):<code>~?")


def on_page_content(html, page, config, files):
    return _ROLE.sub("<code>", html)
