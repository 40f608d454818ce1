"""The tribometer record of `examples/tribometer.py`: reading it (`load`), preparing it for
the fits (sign, ramp-up and unloading, `prepare`), thinning it (`thin`), its strokes and
its presliding / sliding regimes."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from jaxfric.motion import travel_since_reversal, velocity


# ---- data -------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Record:
    """A tribometer record in SI units.

    - `t` (s), `x` (m), `F` (N), `normal` (N): 1-D float64 arrays. After `prepare`, `F`
      follows the models' convention (sign of ``v``).
    - `source`: the file; `rows`: its data rows; `kept`: ``(first, stop)`` rows kept
      (0-based, ``stop`` exclusive).
    - `sign_correlation`: corr(sign v, F) of the file's own ``F`` on moving samples;
      `sign_flipped`: whether `prepare` negated ``F``.
    - `normal_plateau` (N): median load of the loaded part; `normal_tol`: relative
      distance from it within which samples were kept; `split`: index of the first
      validation sample (``len(t)`` if there is none).
    """

    t: np.ndarray
    x: np.ndarray
    F: np.ndarray
    normal: np.ndarray
    source: str
    rows: int
    kept: tuple[int, int]
    sign_correlation: float
    sign_flipped: bool = False
    normal_plateau: float = float("nan")
    normal_tol: float = float("nan")
    split: int = 0


def _sign_correlation(t, x, F) -> float:
    v = velocity(t, x)
    moving = v != 0
    if moving.sum() < 3 or np.std(F[moving]) == 0:
        return float("nan")
    return float(np.corrcoef(np.sign(v[moving]), F[moving])[0, 1])


def load(path: str | Path) -> Record:
    """Read a tribometer CSV (header ``t, x, F, normal``, SI units) as it is in the file.

    Raises `FileNotFoundError` if `path` is not a file, and `ValueError` for a missing
    column, fewer than 10 rows, a non-finite value or a time column that does not increase
    (naming the 1-based data row).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"tribometer data not found: {path}")
    table = np.genfromtxt(path, delimiter=",", names=True, dtype=np.float64)
    names = table.dtype.names or ()
    missing = [c for c in ("t", "x", "F", "normal") if c not in names]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}; the header has {list(names)}")
    cols = {c: np.atleast_1d(np.asarray(table[c], dtype=np.float64))
            for c in ("t", "x", "F", "normal")}
    n = cols["t"].shape[0]
    if n < 10:
        raise ValueError(f"{path}: need at least 10 rows, got {n}")
    for c, a in cols.items():
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{path}: column {c} is empty or not a number at data row "
                             f"{int(np.argmax(~np.isfinite(a))) + 1}")
    if np.any(np.diff(cols["t"]) <= 0):
        row = int(np.argmax(np.diff(cols["t"]) <= 0)) + 2
        raise ValueError(f"{path}: t does not increase at data row {row}")
    return Record(**cols, source=str(path), rows=n, kept=(0, n),
                  sign_correlation=_sign_correlation(cols["t"], cols["x"], cols["F"]))


def prepare(record: Record, *, fit_fraction: float = 0.7, normal_tol: float = 0.01,
            flip: bool | None = None) -> Record:
    """Sign convention, normal-load trimming and the fit/validation split (module
    docstring) of a `load`-ed record.

    `flip`: ``None`` decides from the sign correlation, ``True``/``False`` force it.
    `fit_fraction` in (0, 1]: the fitted fraction of the kept record's duration.
    `normal_tol`: relative distance from the load plateau still counted as settled.
    """
    if not 0.0 < fit_fraction <= 1.0:
        raise ValueError(f"fit_fraction must be in (0, 1], got {fit_fraction}")
    n = record.normal
    plateau = float(np.median(n[n > 0.5 * np.max(n)]))
    ok = np.abs(n - plateau) <= normal_tol * abs(plateau)
    first = int(np.argmax(ok))
    stop = n.shape[0] - int(np.argmax(ok[::-1]))
    if stop - first < 10:
        raise ValueError(f"{record.source}: fewer than 10 samples at the normal-load plateau")
    keep = slice(first, stop)
    t, x, F = record.t[keep], record.x[keep], record.F[keep]
    flipped = bool(record.sign_correlation < 0) if flip is None else bool(flip)
    if flipped:
        F = -F
    if fit_fraction >= 1.0:
        split = t.shape[0]
    else:
        split = int(np.searchsorted(t, t[0] + fit_fraction * (t[-1] - t[0]), side="right"))
    return dataclasses.replace(
        record, t=t, x=x, F=F, normal=record.normal[keep],
        kept=(record.kept[0] + first, record.kept[0] + stop), sign_flipped=flipped,
        normal_plateau=plateau, normal_tol=normal_tol, split=split,
    )


def thin(t, x, F, stride: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices, forces and weights of the samples given to the solver (module docstring).

    A dwell is a maximal run of samples at one position (``x[n] == x[n-1]``; the sample at
    which the motion stops belongs to it). A dwell of more than two samples is kept as its
    first and last samples, each with the dwell's mean force and weight ``len/2``: exact
    for every model. With ``stride > 1``, only every `stride`-th moving sample of a stroke
    is kept besides, with weight `stride` (approximate, for quick mode).

    **Returns:** ``(index, F_kept, weights)``, NumPy arrays.
    """
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    t, x, F = (np.asarray(a, dtype=np.float64) for a in (t, x, F))
    n = t.shape[0]
    still = np.concatenate([[False], np.diff(x) == 0])
    keep = np.ones(n, bool)
    force = F.copy()
    weight = np.ones(n)
    # Runs of equal `still`: [start, stop) where it switches.
    edges = np.flatnonzero(np.diff(still.astype(np.int8))) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, n]):
        if still[a] and b - a > 2:
            keep[a + 1:b - 1] = False
            force[[a, b - 1]] = np.mean(F[a:b])
            weight[[a, b - 1]] = (b - a) / 2.0
        elif not still[a] and stride > 1:
            drop = np.arange(a, b)[(np.arange(b - a) % stride) != stride - 1]
            keep[drop] = False
            weight[a:b] = stride
            keep[b - 1] = True  # the last moving sample before a dwell
    keep[0] = True  # the models start from their zero state here
    index = np.flatnonzero(keep)
    return index, force[index], weight[index]


def strokes(x, min_fraction: float = 0.5) -> list[tuple[int, int]]:
    """``(start, stop)`` sample ranges of the strokes of `x` (m): runs of motion between
    dwells whose travel exceeds `min_fraction` of the full travel. ``start`` is the last
    sample at rest before the motion, ``stop`` the first sample at rest after it."""
    x = np.asarray(x)
    moving = np.concatenate([[False], np.diff(x) != 0])
    edges = np.diff(np.concatenate([[0], moving.astype(np.int8), [0]]))
    begins, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    # Merge runs split by a sample or two without a position change (quantisation).
    runs = []
    for a, b in zip(begins, ends):
        if runs and a - runs[-1][1] <= 2 and np.sign(x[a] - x[a - 1]) == np.sign(
                x[runs[-1][1] - 1] - x[runs[-1][0] - 1]):
            runs[-1] = (runs[-1][0], b)
        else:
            runs.append((a, b))
    span = np.ptp(x)
    return [(max(a - 1, 0), min(b, x.size - 1)) for a, b in runs
            if abs(x[b - 1] - x[a - 1]) > min_fraction * span]


def reversal_travel(x, F, level: float = 0.9) -> float:
    """Travel (m) after the start of a stroke at which the force has covered `level` of
    its change over the stroke (from the sample before the motion to the mean of the
    stroke's last 20 %): the median over the `strokes` of `x`. NaN without strokes."""
    x, F = np.asarray(x, dtype=np.float64), np.asarray(F, dtype=np.float64)
    out = []
    for a, b in strokes(x):
        change = np.mean(F[b - max((b - a) // 5, 1):b]) - F[a]
        if change == 0:
            continue
        covered = (F[a:b] - F[a]) / change
        hit = np.flatnonzero(covered >= level)
        if hit.size:
            out.append(abs(x[a + hit[0]] - x[a]))
    return float(np.median(out)) if out else float("nan")


#: Regimes for the per-regime errors (`regimes`).
REGIMES = ("rest", "presliding", "sliding")


def regimes(x, travel: float) -> dict[str, np.ndarray]:
    """Boolean masks over the samples of `x` (m): ``"rest"`` (no position change since the
    previous sample), ``"presliding"`` (moving, less than `travel` (m) from the last
    reversal) and ``"sliding"`` (moving, farther)."""
    x = np.asarray(x, dtype=np.float64)
    moving = np.concatenate([[False], np.diff(x) != 0])
    far = travel_since_reversal(x) >= travel
    return {"rest": ~moving, "presliding": moving & ~far, "sliding": moving & far}
