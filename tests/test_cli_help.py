"""Every ``gearjax COMMAND --help`` ends with examples, and every example is a command line
the parser accepts (so an option renamed or removed cannot leave a stale example).

Examples are parsed, not run: the commands themselves are run at reduced size by
``tests/test_cli*.py``. An example line is ``gearjax ...`` followed, after two or more
spaces, by what it does; an indented line continues the description of the line above.
"""

from __future__ import annotations

import importlib
import re
import shlex

import pytest

cli = importlib.import_module("gearjax.cli.main")  # the package exports main()


def _commands():
    parser = cli._parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices


COMMANDS = sorted(_commands())


def _examples(help_text: str) -> list[list[str]]:
    """argv of each example in the closing ``examples:`` block of a help text."""
    head, sep, block = help_text.rpartition("\nexamples:\n")
    assert sep, "no 'examples:' block"
    argvs = []
    for line in block.splitlines():
        line = line.strip()
        if line.startswith("gearjax "):
            command = re.split(r"\s{2,}", line)[0]
            argvs.append(shlex.split(command)[1:])
    return argvs


@pytest.mark.parametrize("name", COMMANDS)
def test_help_ends_with_examples_that_parse(name):
    parser = cli._parser()
    text = _commands()[name].format_help()
    examples = _examples(text)
    assert 1 <= len(examples) <= 3, examples
    assert text.rstrip().splitlines()[-1].strip(), "the examples close the help text"
    for argv in examples:
        try:
            args = parser.parse_args(argv)
        except SystemExit as e:  # argparse reports a bad example by exiting
            pytest.fail(f"example 'gearjax {' '.join(argv)}' is rejected ({e})")
        assert args.command == name


def test_top_level_help_examples_parse():
    parser = cli._parser()
    for argv in _examples(parser.format_help()):
        parser.parse_args(argv)


def test_one_line_descriptions_are_still_wrapped():
    """A command's one-paragraph description is wrapped to the terminal, not one long line
    (only the laid-out examples keep their line breaks)."""
    text = _commands()["paper"].format_help()
    description = text.split("\n\n")[1]
    assert max(len(line) for line in description.splitlines()) <= 100
