"""The one rule for every file a campaign writes, the same as `nudyn`'s
for its own (cli/src/output.rs): a new path or a regular file is replaced
whole, by a temporary file beside it that is synced and then renamed over
it; anything else (a device such as /dev/null, a FIFO, a socket, a
directory) is refused, never renamed over. A symbolic link is followed:
the file it points to is replaced, and the link stays.

One campaign at a time writes into a folder: `locked` holds an exclusive
lock on OUT/.nudyn-campaign.lock for the run, and refuses a folder another
run holds."""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path


class OutputError(OSError):
    """A path a campaign would write is there and is not a regular file."""


KINDS = [(stat.S_ISCHR, "character device"), (stat.S_ISBLK, "block device"), (stat.S_ISFIFO, "FIFO"),
         (stat.S_ISSOCK, "socket"), (stat.S_ISDIR, "directory")]


def replaceable(path: Path) -> Path:
    """The file `path` names, if it may be replaced: `path` itself when it
    is new or a regular file, the file a symbolic link points to when that
    is a regular file."""
    path = Path(path)
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return path
    target = path
    if stat.S_ISLNK(mode):
        # A link to nothing is refused too (FileNotFoundError): where it would be created is not obvious.
        target = path.resolve(strict=True)
        mode = os.stat(target).st_mode
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in KINDS if test(mode)), "special file")
        raise OutputError(f"{path} is a {kind}, not a regular file: nudyn writes only regular files and new paths")
    return target


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """Writes `path` by the rule above: `write(temporary)` fills the
    temporary file, which is synced, made readable by all (0644; mkstemp's
    file is 0600) and renamed over the file `path` names, checked again
    just before."""
    target = replaceable(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    descriptor, name = tempfile.mkstemp(dir=target.parent, prefix=".nudyn-", suffix=".partial")
    os.close(descriptor)
    temporary = Path(name)
    try:
        write(temporary)
        with open(temporary, "rb") as file:
            os.fsync(file.fileno())
        os.chmod(temporary, 0o644)
        # Whatever took the path's place while the file was written is not renamed over either.
        if replaceable(path) != target:
            raise OutputError(f"{path} changed while it was written")
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


# The lock file in OUT; it stays after the run (removing it would let a
# waiting run lock the removed file while a third locks a new one).
LOCK = ".nudyn-campaign.lock"


@contextlib.contextmanager
def locked(out: Path) -> Iterator[None]:
    """Holds the exclusive lock of the folder `out` (which exists) for the
    block; an OutputError naming the folder if another run holds it."""
    path = Path(out) / LOCK
    try:
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as error:
        raise OutputError(f"--out {out}: cannot create its lock file {path}: {error.strerror or error}") from None
    try:
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OutputError(f"--out {out}: another nudyn-campaign is writing into this folder (it holds {path}): "
                              "wait for it to end, or choose another --out") from None
        yield
    finally:
        # Closing the descriptor releases the lock.
        os.close(descriptor)
