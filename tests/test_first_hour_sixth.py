"""A new user's first hour, a sixth pass (issue 117, items 5 and 14): a refusal is one line, exit
2, made before anything is written; a command under mpiexec writes its files once."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers import TINY, cli_main, one_line

RUN = ("run", "tc2_steady", *TINY, "--days", "0.1")
SWEEP = ("sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "kgu35", "--dt", "5400,10800")


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("command", [RUN, SWEEP])
def test_a_key_varied_twice_is_refused(capsys, command):
    """Item 5: `--vary case.alpha=0,1 --vary case.alpha=0,2` ran the second values, the first
    dropped without a word."""
    twice = ("--members", "2", "--vary", "case.alpha=0,1", "--vary", "case.alpha=0,2")
    code, out, err = cli_main(capsys, *command, *twice, "--output", "v.nc" if command is RUN else "s")
    one_line(code, err, 2, "--vary 'case.alpha=0,1' and 'case.alpha=0,2': case.alpha is varied twice")
    assert out == "" and list(Path().iterdir()) == []
