"""The controller on a real board: the board loop, and the drivers of each board.

:class:`~rovlink.board.server.BoardServer` runs :class:`rovlink.controller.Controller` at a
fixed rate on any board's devices and serves its serial lines; it stands on the controller and
the protocol core only. A board's drivers live in a subpackage (``rovlink.board.pi``) and are
imported only when that board is chosen, so their libraries (the ``pi`` extra) are needed on
that board only.
"""
