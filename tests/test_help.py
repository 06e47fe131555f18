"""What the command line tells a user: help text on every option, examples that parse, --version."""

from __future__ import annotations

import shlex
import subprocess
import sys

import pytest

import lunarviz
from lunarviz.cli import EXAMPLES, build_parser


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "lunarviz", *args], capture_output=True, text=True)


def test_version():
    r = _cli("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"lunarviz {lunarviz.__version__}"


@pytest.mark.parametrize("command", sorted(EXAMPLES))
def test_every_option_has_help_and_the_examples_parse(command):
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    for action in sub._actions:
        if action.option_strings and action.dest != "help":
            assert action.help, f"lunarviz {command} {action.option_strings[0]} has no help text"
    assert sub.epilog and "examples:" in sub.epilog
    for example in EXAMPLES[command]:
        argv = shlex.split(example)
        assert argv[:2] == ["lunarviz", command]
        parser.parse_args(argv[1:])  # raises on a flag the command does not have


def test_sweep_help_shows_defaults_and_units():
    text = _cli("sweep", "--help").stdout
    assert "(default: 1)" in text  # --runs
    assert "paper's 50,000" in text  # --rays: a default that --rtol may replace, said in words
    assert "[deg]" in text and "examples:" in text
