"""Files written whole or not at all.

`atomic_file` writes through a private temporary file in the target's folder (created with
O_EXCL by `tempfile.mkstemp`, so it never follows a planted symlink or overwrites someone
else's file), flushes and fsyncs it, and renames it over the target; on any exit before
that, Ctrl-C included, the temporary file is removed and the target is untouched
(`remove_pending` does it for a process ended at once, as `fitting.cli._interrupt` does).
The finished file gets the usual permissions (0666 less the umask), as a plain ``open``
would give it. Every file the library writes (`jaxfric.save_model`,
`jaxfric.export.to_c`, `jaxfric.export.to_mujoco`) and every output of the command line
goes through it.

`output_folder` does the same for a folder of outputs (a report, the demo): a folder it
had to make is removed again, with what was written into it, when the work fails or is
interrupted before the end; a folder that was there keeps its old files, each either old
or whole and new.
"""

import contextlib
import os
import shutil
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: Temporary files of the `atomic_file`s being written (for `remove_pending`).
_pending: set[str] = set()
#: Folders made by the `output_folder`s still being filled (for `remove_pending`).
_pending_folders: set[Path] = set()


@contextlib.contextmanager
def atomic_file(path, mode: str = "w"):
    """``with atomic_file(path) as f: f.write(...)``: `path` holds the whole new content
    afterwards, or is unchanged if anything fails or is interrupted before the end."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    _pending.add(tmp)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    finally:
        _pending.discard(tmp)


def write_text(path, text: str) -> Path:
    """`text` to `path`, atomically (`atomic_file`); returns the path."""
    with atomic_file(path) as f:
        f.write(text)
    return Path(path)


@contextlib.contextmanager
def output_folder(path):
    """``with output_folder(path) as folder: ...``: `folder` exists inside the block (made
    with its missing parents if need be). If the block fails or is interrupted, the folders
    made here are removed with everything in them; a folder that existed is left alone
    (its files are written by `atomic_file`, whole or not at all)."""
    folder = Path(path)
    made = folder
    while not made.parent.exists():  # the outermost folder that is missing
        made = made.parent
    new = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    if new:
        _pending_folders.add(made)
    try:
        yield folder
    except BaseException:
        if new:
            shutil.rmtree(made, ignore_errors=True)
        raise
    finally:
        _pending_folders.discard(made)


def remove_pending() -> None:
    """Remove the temporary files of the `atomic_file`s still being written, and the
    folders the `output_folder`s still being filled made: for a process about to end
    without unwinding. Targets are left as they were (or as just renamed, whole)."""
    for tmp in list(_pending):
        with contextlib.suppress(OSError):
            os.unlink(tmp)
    for folder in list(_pending_folders):
        shutil.rmtree(folder, ignore_errors=True)
