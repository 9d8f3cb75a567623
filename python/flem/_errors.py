"""Exceptions of the flem package (raised by the native module too)."""
from __future__ import annotations

from typing import Optional


class FlemError(RuntimeError):
    """A run that stopped with an error (divergence, output error, ...): the CLI's message."""

    def __init__(self, message: str, file: str = "", key: str = "") -> None:
        super().__init__(message)
        self.message = message


class SceneError(ValueError):
    """A scene that does not parse or validate: the message `flem check` prints (without its
    ``error:`` prefix), naming the file and the key; ``file`` and ``key`` as attributes."""

    def __init__(self, message: str, file: str = "", key: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.file = file
        self.key = key


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) during :func:`flem.run`: the run stopped after its current step and wrote
    a checkpoint and an ``*_interrupted.vtu`` snapshot into ``out``, as ``flem run`` does.
    Continue with ``flem.run(scene, out=out, resume=out)``. A ``KeyboardInterrupt``."""

    def __init__(self, message: str, out: str = "", checkpoint: Optional[str] = None) -> None:
        super().__init__(message)
        self.out = out
        self.checkpoint = checkpoint
