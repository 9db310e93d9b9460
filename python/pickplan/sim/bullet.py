"""PyBullet, imported and connected in one place.

PyBullet's C code prints a build banner when it is imported (and GUI clients print their OpenGL
details when they connect) straight to file descriptors 1 and 2, where Python's ``sys.stdout``
redirection does not reach. Every pickplan module gets the module from here (``pb``) and opens its
clients with ``connect``, so a user sees only pickplan's own output.

>>> from pickplan.sim.bullet import pb, connect
>>> client = connect()
>>> pb.disconnect(physicsClientId=client)
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Iterator


@contextlib.contextmanager
def quiet_c_output() -> Iterator[None]:
    """File descriptors 1 and 2 point to /dev/null while the block runs (output written by C code,
    which ``contextlib.redirect_stdout`` misses). Process-wide: keep the block short. Where the
    descriptors cannot be duplicated (closed, or a sandbox), the block runs as it is."""
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            stream.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:
        yield
        return
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)


with quiet_c_output():
    import pybullet as pb  # noqa: E402 - the banner goes to /dev/null


def connect(gui: bool = False) -> int:
    """A new PyBullet client (DIRECT, or GUI when ``gui``), opened without PyBullet's banner."""
    with quiet_c_output():
        return pb.connect(pb.GUI if gui else pb.DIRECT)


__all__ = ["pb", "connect", "quiet_c_output"]
