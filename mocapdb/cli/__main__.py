"""``python -m mocapdb.cli``: the ``mocapdb`` command."""
from mocapdb.cli import main

main()
