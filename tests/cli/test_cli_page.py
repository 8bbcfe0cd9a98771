"""The site's command-line page (docs/reference/cli.md) is sphinx-argparse's rendering of the
parser ``swe-sphere`` runs: every subcommand and every option of each is on it."""

import argparse
import re
from pathlib import Path

import pytest

from swe_sphere.cli.parser import parser

PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "cli.md"


def test_the_page_renders_the_parser_the_command_runs():
    text = PAGE.read_text()
    directive = re.search(r"```\{argparse\}\n(.*?)```", text, re.S).group(1)
    assert ":module: swe_sphere.cli.parser\n" in directive and ":func: parser\n" in directive
    assert ":prog: swe-sphere\n" in directive
    # nothing left out: no :path: to one subcommand, no :nosubcommands:, no :nodefault:
    assert not re.search(r":(path|nosubcommands|nodefault|nodescription):", directive)


def test_every_subcommand_and_option_is_on_the_page():
    sphinxarg = pytest.importorskip("sphinxarg.parser")  # the docs extra's
    p = parser()
    page = sphinxarg.parse_parser(p)
    (subparsers,) = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
    rendered = {child["name"]: child for child in page["children"]}
    assert list(rendered) == list(subparsers.choices)
    for name, sub in subparsers.choices.items():
        shown = {s for group in rendered[name]["action_groups"] for o in group["options"] for s in o["name"]}
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):  # -h: on every command, left off the page
                continue
            for flag in action.option_strings or [action.dest]:
                assert flag in shown, f"{name} {flag}"
