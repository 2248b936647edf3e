"""``python -m rovlink``: the same as the ``rovlink`` command."""

from rovlink.cli import main

main()
