"""The ``mocapdb`` command line: one command per function of :mod:`mocapdb.api`, same names and options
(and ``serve``, :func:`mocapdb.server.serve`).

Every command opens the database, calls its API function and prints the
result; nothing is computed here. Every error is one line ``Error: …`` with
exit status 1 (sqlite-utils style); progress bars are drawn here and nowhere
else (on a terminal, unless ``--silent``). The modules mirror those of
:mod:`mocapdb.api`: :mod:`~mocapdb.cli.database`, :mod:`~mocapdb.cli.annotating`,
:mod:`~mocapdb.cli.learning`, :mod:`~mocapdb.cli.outputs`, :mod:`~mocapdb.cli.browsing`; :mod:`~mocapdb.cli.group`
holds the group and what every command shares, :mod:`~mocapdb.cli.options` the
shared options, :mod:`~mocapdb.cli.output` the printing. The CLI imports only
:mod:`mocapdb.api`, :mod:`mocapdb.server` (the web server, a face on the API beside this one, which
the CLI starts) and :mod:`mocapdb.errors` from the library.
"""
from mocapdb.cli.group import main
# importing the command modules registers their commands with the group
from mocapdb.cli import annotating, browsing, database, learning, outputs  # noqa: F401

__all__ = ["main"]
