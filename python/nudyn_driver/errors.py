"""The error type of nudyn_driver."""

from __future__ import annotations

from collections.abc import Sequence


class DriverError(Exception):
    """nudyn or one of its FMUs cannot be driven as asked: a missing binary,
    a command that fails, a variable or item the FMU does not have."""


class CommandError(DriverError):
    """A command exited with a non-zero status. Its stderr is kept whole:
    nudyn's messages name what they refuse (the MJCF element and line)."""

    def __init__(self, command: Sequence[str], returncode: int, stderr: str):
        self.command = list(command)
        self.returncode = returncode
        self.stderr = stderr
        super().__init__(f"`{' '.join(self.command)}` failed:\n{stderr.strip()}")


class SystemFileError(DriverError):
    """A file that is not a readable `nudyn system` archive: the message
    names the file, the entry and what is wrong."""
