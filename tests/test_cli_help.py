"""Every subcommand's --help says what it does (a description after the usage), and the experiment
commands name their paper: table1 by its title, seed002 by the opening of its note's abstract (the
note's text carries no title)."""
from __future__ import annotations

import pytest

from raytrace.cli import COMMANDS, PAPER, main


def _help(command, capsys) -> str:
    with pytest.raises(SystemExit) as done:
        main([command, "--help"])
    assert done.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_describes_itself(command, capsys):
    text = _help(command, capsys)
    description = text.split("\n\n")[1]  # after the usage, before the arguments
    assert not description.startswith(("options:", "positional arguments:")), text
    assert len(" ".join(description.split())) > 40, description


@pytest.mark.parametrize("command, names", [
    ("table1", PAPER),
    ("seed002", '"An analytical approach toward visualization of participating media"'),
])
def test_the_experiments_name_their_paper(command, names, capsys):
    description = " ".join(_help(command, capsys).split("\n\n")[1].split())
    assert names in description, description
