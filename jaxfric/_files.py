"""Reading measurement files safely: CSV streamed row by row, NPZ checked before it is read.

`read_file` refuses, with one `DataError` line and before reading a byte of data, what is
not a measurement file: a missing path, a folder, a device (``/dev/zero``), a FIFO or socket
(which would block or never end), a file we may not read, and a file beyond
`MAX_FILE_BYTES`. A CSV is read line by line into float arrays (8 bytes a value), so the
memory stays proportional to the numbers kept, never to the text; rows beyond `MAX_SAMPLES`
stop the read. An NPZ is opened as the zip archive it is: each member's header (dtype and
shape) is checked before its data is decompressed, so an object array (pickled Python
objects, never loaded) or a member that would decompress to more than `MAX_SAMPLES` values
(a small file that inflates to gigabytes) is refused; a ``.npy`` renamed ``.npz`` is named
as such.

Errors about a cell name its place as ``FILE:LINE:`` (the 1-based line of the file, as
compilers do, so that an editor jumps to it) besides the column and the data row.

A column whose first value is text (a date, a label) is not a measurement: it is skipped
with a note, unless it is one of the standard columns (then its cell is an error naming the
row). Trailing separators (``1,2,3,``) are accepted; a header of more than `MAX_COLUMNS`
cells (millions of separators, a damaged file) is refused before it is split.

Text is UTF-8; a header cell that is not (a unit such as ``µm`` or ``°`` written by a
Windows or Latin-1 program), or a cell quoted in a message, is read as Latin-1, so
``x[µm]`` means micrometres whichever of the two the file was saved in.
"""

import array
import bisect
import csv
import itertools
import os
import re
import stat
import zipfile
import zlib
from pathlib import Path

import numpy as np


#: Largest measurement file read, bytes (1 GiB).
MAX_FILE_BYTES = 1 << 30
#: Most samples (rows) in one column.
MAX_SAMPLES = 10_000_000
#: Most cells in a header line: a measurement has a handful of columns (a robot file of
#: seven joints about fifty); far more is a damaged file, refused before it is split.
MAX_COLUMNS = 1000

_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z_0-9]*)\s*(?:\[\s*([^\]]*?)\s*\])?\s*$")


class DataError(ValueError):
    """A measurement cannot be used; the message names the source, column and row
    (`jaxfric.data.DataError`, the one error type of the loader)."""


def _error(message: str) -> DataError:
    return DataError(message)


def check_path(path: Path) -> int:
    """Size in bytes of `path` if it is a regular file we may read, within the limit;
    otherwise a one-line `DataError`. Nothing is read."""
    source = str(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise _error(f"{source}: no such file") from None
    except PermissionError:
        raise _error(f"{source}: permission denied (cannot look at the file)") from None
    except OSError as e:
        raise _error(f"{source}: cannot be read ({e.strerror or e})") from None
    if stat.S_ISDIR(st.st_mode):
        raise _error(f"{source}: is a folder, not a data file")
    if not stat.S_ISREG(st.st_mode):
        what = ("a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
                else "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode)
                else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise _error(f"{source}: is {what}, not a data file; save the data to a file first")
    if st.st_size > MAX_FILE_BYTES:
        raise _error(f"{source}: {st.st_size / 2**20:.0f} MiB is beyond the limit of "
                     f"{MAX_FILE_BYTES / 2**20:.0f} MiB for one measurement "
                     "(jaxfric.data.MAX_FILE_BYTES); split or decimate it")
    return st.st_size


def _open(path: Path, mode: str, **kw):
    try:
        return open(path, mode, **kw)
    except PermissionError:
        raise _error(f"{path}: permission denied (cannot read the file)") from None
    except OSError as e:
        raise _error(f"{path}: cannot be read ({e.strerror or e})") from None


class LineMap:
    """The file line of each data row of a CSV file, kept as the few breaks where blank or
    comment lines sit between rows (memory independent of the number of rows)."""

    def __init__(self):
        self.current = 0  # the line of the last line handed to the CSV reader
        self._rows: list[int] = []
        self._lines: list[int] = []

    def track(self, f):
        """The lines of `f` that hold data (not blank, not comments), noting their number."""
        for number, ln in enumerate(f, 1):
            if ln.strip() and not ln.lstrip().startswith("#"):
                self.current = number
                yield ln

    def note(self, row: int) -> None:
        """Data row `row` (1-based) was read from line `current`."""
        if not self._rows or self.line(row) != self.current:
            self._rows.append(row)
            self._lines.append(self.current)

    def line(self, row: int) -> int:
        """The 1-based file line of data row `row` (1-based)."""
        k = bisect.bisect_right(self._rows, row) - 1
        return self._lines[k] + row - self._rows[k] if k >= 0 else 0


def parse_header(source: str, names: list[str]) -> list[tuple[str, str | None]]:
    """``[(column, unit or None)]`` from header cells like ``x`` or ``x[mm]``."""
    parsed = []
    for i, raw in enumerate(names):
        m = _HEADER.match(raw)
        if m is None:
            cell = raw if len(raw) <= 40 else raw[:40] + "..."
            raise _error(
                f"{source}: header cell {i + 1} ({cell!r}) is not a column name like 'x' or "
                "'x[mm]'"
            )
        parsed.append((m.group(1), m.group(2) or None))
    seen = set()
    for name, _ in parsed:
        if name in seen:
            raise _error(f"{source}: column {name!r} appears twice in the header")
        seen.add(name)
    return parsed


def is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _latin1(cell: str) -> str:
    """A header cell read as UTF-8 with the bytes that are not UTF-8 kept as surrogates
    (``surrogateescape``), decoded again as Latin-1 when it has any."""
    try:
        raw = cell.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:
        return cell
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _count_cells(first: str) -> int:
    """The number of cells of a header line, counted without splitting it."""
    counts = [first.count(sep) for sep in (",", ";", "\t")]
    return max(counts) + 1 if max(counts) else len(first.split())


def _splitter(first: str):
    """A function line -> cells for the separator of the header line: the most frequent of
    ``,``, ``;``, tab; whitespace if none."""
    counts = {sep: first.count(sep) for sep in (",", ";", "\t")}
    sep = max(counts, key=counts.get)
    if counts[sep] == 0:
        return lambda lines: (ln.split() for ln in lines)
    return lambda lines: csv.reader(lines, delimiter=sep)


def _strip_trailing(cells: list[str], ncol: int) -> list[str]:
    while len(cells) > ncol and not cells[-1].strip():
        cells = cells[:-1]
    return cells


def read_csv(path: Path, standard: frozenset) -> tuple[list, dict, list[str], LineMap]:
    """``([(column, unit)], {column: float64 array}, notes, lines)`` of a delimited text
    file, streamed; text columns outside `standard` are skipped with a note; ``lines.line(r)``
    is the file line of data row ``r``."""
    source = str(path)
    check_path(path)
    _refuse_binary(path)
    try:
        with _open(path, "r", encoding="utf-8-sig", errors="surrogateescape",
                   newline="") as f:
            return _read_text(source, f, standard)
    except csv.Error as e:
        raise _error(f"{source}: not a readable CSV file ({e})") from None
    except OSError as e:
        raise _error(f"{source}: cannot be read ({e.strerror or e})") from None


def _read_text(source, f, standard):
    where = LineMap()
    lines = where.track(f)
    first = next(lines, None)
    if first is None:
        raise _error(f"{source}: the file is empty")
    cells = _count_cells(first)
    if cells > MAX_COLUMNS:
        raise _error(f"{source}:{where.current}: the header has {cells} cells, more than "
                     f"the {MAX_COLUMNS} a measurement file may have "
                     "(jaxfric.data.MAX_COLUMNS): a damaged file? Remove the empty ones")
    rows = _splitter(first)(itertools.chain([first], lines))
    header = [_latin1(h.strip()) for h in next(rows)]
    while header and not header[-1]:
        header.pop()  # a trailing separator
    if header and all(is_number(h) for h in header if h):
        raise _error(
            f"{source}: no header row; the first line must name the columns, e.g. "
            "'t,x,F' (units in brackets: 't[s],x[mm],F[N]')"
        )
    parsed = parse_header(source, header)
    return (*_read_body(source, parsed, rows, standard, where), where)


def _refuse_binary(path: Path) -> None:
    """A text reader given a binary file would print its bytes in the error: name it."""
    with _open(path, "rb") as f:
        head = f.read(4096)
    if head[:2] == b"PK":
        raise _error(f"{path}: is a zip archive, not a text (CSV) file; an .npz file must "
                     "be named .npz")
    if b"\x00" in head or head[:6] == b"\x93NUMPY":
        raise _error(f"{path}: is binary data, not a text (CSV) file")


def _read_body(source, parsed, rows, standard, where: LineMap):
    ncol = len(parsed)
    first = next(rows, None)
    if first is None:
        raise _error(f"{source}: a header but no data rows")
    first = _strip_trailing([c.strip() for c in first], ncol)
    if len(first) != ncol:
        raise _error(f"{source}:{where.current}: row 1: {len(first)} cells, the header "
                     f"has {ncol}")
    keep, notes = [], []
    for c, (name, _) in enumerate(parsed):
        if is_number(first[c]) or name in standard:
            keep.append(c)
        else:
            text = _latin1(first[c][:20])
            notes.append(f"column {name!r} is text ({text!r} in row 1): ignored")
    values = [array.array("d") for _ in keep]
    for r, row in enumerate(itertools.chain([first], rows)):
        where.note(r + 1)
        row = _strip_trailing(row, ncol)
        if len(row) != ncol:
            raise _error(f"{source}:{where.current}: row {r + 1}: {len(row)} cells, the "
                         f"header has {ncol}")
        if r >= MAX_SAMPLES:
            raise _error(f"{source}: more than {MAX_SAMPLES} rows, the limit for one "
                         "measurement (jaxfric.data.MAX_SAMPLES); split or decimate it")
        for k, c in enumerate(keep):
            try:
                values[k].append(float(row[c]))
            except ValueError:
                cell = _latin1(row[c].strip())
                raise _error(f"{source}:{where.current}: column {parsed[c][0]!r}, "
                             f"row {r + 1}: {cell!r} is not a number") from None
    kept = [parsed[c] for c in keep]
    columns = {name: np.frombuffer(vals, dtype=np.float64).copy()
               for (name, _), vals in zip(kept, values)}
    return kept, columns, notes


def header_names(path: Path) -> list[str]:
    """The column names of a file's header (units stripped), reading nothing else."""
    check_path(path)
    if path.suffix.lower() == ".npz":
        try:
            with zipfile.ZipFile(path) as z:
                cells = [n[:-4] for n in z.namelist() if n.endswith(".npy")]
        except (zipfile.BadZipFile, OSError):
            return []
    else:
        _refuse_binary(path)
        with _open(path, "r", encoding="utf-8-sig", errors="replace", newline="") as f:
            first = ""
            while not first.strip() or first.lstrip().startswith("#"):
                first = f.readline(1 << 20)  # a header is short; never read a file whole
                if not first:
                    break
        cells = next(iter(_splitter(first)([first])), []) if first else []
    return [m.group(1) for c in cells if (m := _HEADER.match(c.strip()))]


def _member_header(f, source: str, key: str):
    try:
        version = np.lib.format.read_magic(f)
        read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                else np.lib.format.read_array_header_2_0)
        return read(f)
    except ValueError as e:
        raise _error(f"{source}: member {key!r} is not a NumPy array ({e})") from None


def read_npz(path: Path, standard: frozenset) -> tuple[list, dict, list[str], None]:
    """Like `read_csv` for an ``.npz`` archive (``np.savez``; no lines, so ``None`` for the
    line map); arrays are checked before they are read."""
    source = str(path)
    check_path(path)
    with _open(path, "rb") as f:
        magic = f.read(6)
        if magic == b"\x93NUMPY":
            raise _error(f"{source}: is a single .npy array, not an .npz archive of named "
                         "columns; save with np.savez(path, t=..., x=..., F=...)")
        if magic[:2] != b"PK":
            raise _error(f"{source}: not an .npz file (no zip archive inside)")
        try:
            return (*_read_zip(source, zipfile.ZipFile(f), standard), None)
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError) as e:
            raise _error(f"{source}: damaged .npz file ({e})") from None


def _read_zip(source, archive, standard):
    members = [i for i in archive.infolist() if i.filename.endswith(".npy")]
    if not members:
        raise _error(f"{source}: the file is empty (no arrays)")
    parsed = parse_header(source, [i.filename[:-4] for i in members])
    kept, columns, notes = [], {}, []
    for (name, unit), info in zip(parsed, members):
        with archive.open(info) as f:
            shape, _, dtype = _member_header(f, source, info.filename[:-4])
        size = int(np.prod(shape))
        if dtype.hasobject:
            raise _error(f"{source}: column {name!r} holds Python objects (dtype "
                         "object), not numbers; save it as a float array")
        if sum(1 for s in shape if s != 1) > 1:
            raise _error(f"{source}: column {name!r} must be 1-D, got shape {shape}")
        if size > MAX_SAMPLES:
            raise _error(f"{source}: column {name!r} has {size} values, beyond the limit "
                         f"of {MAX_SAMPLES} (jaxfric.data.MAX_SAMPLES)")
        if not (np.issubdtype(dtype, np.number) or dtype == np.bool_):
            if name in standard:
                raise _error(f"{source}: column {name!r}: not numeric (dtype {dtype})")
            notes.append(f"column {name!r} is not numeric (dtype {dtype}): ignored")
            continue
        with archive.open(info) as f:
            try:
                arr = np.lib.format.read_array(f, allow_pickle=False)
            except ValueError as e:
                raise _error(f"{source}: column {name!r} cannot be read ({e})") from None
        kept.append((name, unit))
        columns[name] = np.asarray(arr, dtype=np.float64).reshape(-1)
    return kept, columns, notes
