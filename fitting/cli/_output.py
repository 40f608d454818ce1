"""Writing results safely: outputs checked before the work starts, files written whole or
not at all.

`check_file` and `check_folder` run before a command does any fitting, so a wrong path
fails in a second with one line instead of after a minute of work. `check_clashes` refuses,
before any work too, an output that would replace one of the command's inputs (the same
file by resolved path or by inode, a hard or symbolic link included, or an input a report
folder would write over) or another of its outputs. `atomic_file` writes
through a private temporary file in the target's folder (created with O_EXCL by
`tempfile.mkstemp`, so it never follows a planted symlink or overwrites someone else's
file), flushes and fsyncs it, and renames it over the target; on any exit before that,
Ctrl-C and SIGTERM included (see `fitting.cli.main`), the temporary file is removed and
the target is untouched (`remove_pending` does it for a process ended at once by
`fitting.cli._interrupt`). `output_folder` does the same for a report's folder: one it
made is removed again if the work does not finish. They live in `jaxfric._atomic`, which
the library's own writers use too.
"""

import fnmatch
import json
import math
import os
from pathlib import Path

from jaxfric._atomic import atomic_file, output_folder, remove_pending  # noqa: F401 (re-exported)
from jaxfric.data import DataError


def _unreachable(option: str, path: Path, error: OSError) -> DataError:
    """A path we may not even look at (a folder on the way we may not enter)."""
    reason = (error.strerror or str(error)).lower()
    return DataError(f"{option} {path}: cannot write there ({reason}: {error.filename})")


def check_file(path, option: str) -> Path:
    """`path` can be written as a file: not a folder, in a folder that exists and that we
    may write in. Raises `DataError` naming the `option` (e.g. ``"--json"``)."""
    try:
        return _check_file(Path(path), option)
    except OSError as e:
        raise _unreachable(option, Path(path), e) from None


def check_folder(path, option: str) -> Path:
    """`path` is a folder we can write in, or can be made in a writable parent folder
    (it is not made here). Raises `DataError` naming the `option`."""
    try:
        return _check_folder(Path(path), option)
    except OSError as e:
        raise _unreachable(option, Path(path), e) from None


def _check_file(target: Path, option: str) -> Path:
    if target.is_dir():
        raise DataError(f"{option} {target}: is a folder; give a file name")
    if target.exists() and not target.is_file():
        # a device (/dev/null), FIFO or socket: the atomic rename would replace it
        raise DataError(f"{option} {target}: is not a regular file (a device, FIFO or "
                        "socket); give a file name")
    folder = target.parent
    if not folder.is_dir():
        raise DataError(f"{option} {target}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise DataError(f"{option} {target}: cannot write in {folder} (permission denied)")
    if target.exists() and not os.access(target, os.W_OK):
        raise DataError(f"{option} {target}: the file exists and is not writable")
    return target


def _check_folder(folder: Path, option: str) -> Path:
    if folder.exists() and not folder.is_dir():
        raise DataError(f"{option} {folder}: is a file, not a folder")
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise DataError(f"{option} {folder}: cannot write in {existing} (permission denied)")
    return folder


def _same(a: Path, b: Path) -> bool:
    """`a` and `b` are one file: the same resolved path, or the same inode (a hard link)."""
    try:
        if a.exists() and b.exists() and os.path.samefile(a, b):
            return True
    except OSError:
        pass
    return a.resolve() == b.resolve()


def _hits(out: Path, patterns: tuple, other: Path) -> str | None:
    """What output `out` writes over `other`: ``"itself"`` for a file output, the name
    pattern for a folder writing `patterns` (with ``/`` for a subfolder, such as
    ``joint_*/report.html``), or ``None``."""
    if not patterns:
        return "itself" if _same(out, other) else None
    for pattern in patterns:
        parts = pattern.split("/")
        if len(other.parents) < len(parts):
            continue
        tail = other.parts[-len(parts):]
        if (len(tail) == len(parts) and all(fnmatch.fnmatch(n, p) for n, p in zip(tail, parts))
                and _same(out, other.parents[len(parts) - 1])):
            return pattern
    return None


def check_clashes(inputs, outputs) -> None:
    """No output replaces an input or another output. `inputs`: ``[(option, path)]``;
    `outputs`: ``[(option, path, patterns)]``, `patterns` empty for a file, else the names
    (glob patterns) a folder output writes into its folder. Raises `DataError` naming both."""
    outs = [(o, Path(p), pats) for o, p, pats in outputs if p]
    for option, out, pats in outs:
        for what, source in inputs:
            hit = _hits(out, pats, Path(source)) if source else None
            if hit:
                where = "" if hit == "itself" else f" (it writes {hit} there)"
                raise DataError(f"{option} {out}{where} would overwrite the input {what} "
                                f"{source}; write the output elsewhere")
    for i, (option, out, pats) in enumerate(outs):
        for other_option, other, other_pats in outs[i + 1:]:
            if pats and not other_pats and _hits(out, pats, other):
                raise DataError(f"{other_option} {other} is a file that {option} {out} "
                                "writes too: give each output its own path")
            if other_pats and not pats and _hits(other, other_pats, out):
                raise DataError(f"{option} {out} is a file that {other_option} {other} "
                                "writes too: give each output its own path")
            if _same(out, other):
                raise DataError(f"{option} {out} and {other_option} {other} are the same "
                                "output: give each its own path")


def _finite_or_null(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_or_null(v) for v in obj]
    return obj


def write_json(path, obj) -> None:
    """`obj` as RFC 8259 JSON, atomically. JSON has no NaN or Infinity: a value that is
    not finite (an undefined error, a parameter at its limit) is written as null."""
    text = json.dumps(_finite_or_null(obj), indent=2, allow_nan=False) + "\n"
    with atomic_file(path) as f:
        f.write(text)


def save_figure(fig, path, dpi: int) -> None:
    """A matplotlib figure as PNG, atomically."""
    with atomic_file(path, "wb") as f:
        fig.savefig(f, dpi=dpi, format="png")
