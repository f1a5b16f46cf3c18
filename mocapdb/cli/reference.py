"""docs/CLI.md, the command-line reference, written from the commands' own ``--help``.

One source for every option: the help text the commands print. The
reference is regenerated, never edited (``python -m mocapdb.cli.reference >
docs/CLI.md``); tests/test_docs.py fails when it differs from what the
installed commands say. Help is rendered at a fixed width so the file does not
depend on the terminal that wrote it.
"""
from __future__ import annotations

import click

from mocapdb.cli import main

#: columns of the rendered help (click wraps to the terminal otherwise)
WIDTH = 100


def _help(command: click.Command, name: str, parent: click.Context) -> str:
    ctx = click.Context(command, info_name=name, parent=parent, terminal_width=WIDTH, max_content_width=WIDTH)
    return command.get_help(ctx)


def cli_reference() -> str:
    """The Markdown reference of ``mocapdb`` and each of its commands, in alphabetical order."""
    # the group's own settings (-h as well as --help): click keeps the help option it first made on the
    # command, so a context without them would print what an earlier invocation happened to leave
    root = click.Context(main, info_name="mocapdb", terminal_width=WIDTH, max_content_width=WIDTH,
                         **main.context_settings)
    out = ["# Command-line reference", "",
           "Generated from `mocapdb --help` and each command's `--help` by `python -m mocapdb.cli.reference`",
           "(a test keeps it current). The [user guide](USER_GUIDE.md) says what the commands are for.", "",
           "```text", main.get_help(root), "```", ""]
    for name in sorted(main.commands):
        command = main.commands[name]
        if command.hidden:
            continue
        out += [f"## mocapdb {name}", "", "```text", _help(command, name, root), "```", ""]
    return "\n".join(out)


if __name__ == "__main__":
    click.echo(cli_reference(), nl=False)
