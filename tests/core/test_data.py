"""Loading measurements: formats, units, irregular sampling, and one test per kind of bad
input (each error names the source, the column and the row)."""

import warnings
from pathlib import Path

import numpy as np
import pytest

from jaxfric import data
from jaxfric.data import DataError, DataWarning


def _signal(n=200, seed=0):
    """A friction-like measurement in SI: 0.2 mm strokes, F with the sign of v."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n))  # irregular sampling
    x = 1e-4 * np.sin(2 * np.pi * t / t[-1] * 3)
    v = np.r_[0.0, np.diff(x) / np.diff(t)]
    F = 2.0 * np.tanh(v / 1e-4) + 0.01 * rng.normal(size=n)
    return t, x, F


def _write_csv(path: Path, header: str, columns) -> Path:
    rows = np.column_stack(columns)
    lines = [",".join(repr(float(v)) for v in r) for r in rows]
    path.write_text(header + "\n" + "\n".join(lines) + "\n")
    return path


def test_csv_in_si_keeps_irregular_time(tmp_path):
    t, x, F = _signal()
    m = data.load(_write_csv(tmp_path / "a.csv", "t,x,F", (t, x, F)))
    np.testing.assert_array_equal(m.t, t)
    np.testing.assert_array_equal(m.x, x)
    np.testing.assert_array_equal(m.F, F)
    assert m.u is None and m.v is None and len(m) == t.size
    assert np.ptp(np.diff(m.t)) > 1e-4  # not resampled


def test_units_in_header_and_by_option(tmp_path):
    t, x, F = _signal()
    path = _write_csv(tmp_path / "a.csv", "t[ms], x[mm], F[mN]", (t * 1e3, x * 1e3, F * 1e3))
    m = data.load(path)
    np.testing.assert_allclose(m.t, t, rtol=1e-15)
    np.testing.assert_allclose(m.x, x, rtol=1e-15)
    np.testing.assert_allclose(m.F, F, rtol=1e-15)
    assert any("mm" in note for note in m.notes)
    m2 = data.load(_write_csv(tmp_path / "b.csv", "t,x,F", (t, x * 1e6, F)), units={"x": "um"})
    np.testing.assert_allclose(m2.x, x, rtol=1e-15)


def test_npz_dict_and_dataframe(tmp_path):
    t, x, F = _signal()
    np.savez(tmp_path / "a.npz", t=t, x=x, F=F, normal=np.full(t.size, 5.0))
    m = data.load(tmp_path / "a.npz")
    np.testing.assert_array_equal(m.F, F)
    np.testing.assert_array_equal(m.normal, 5.0)
    m = data.load({"t": t, "x[mm]": x * 1e3, "u": F, "temperature": np.ones(t.size)})
    assert m.F is None and m.force_column == "u"
    np.testing.assert_allclose(m.x, x, rtol=1e-15)
    assert "temperature" in m.extra
    pd = pytest.importorskip("pandas")
    m = data.load(pd.DataFrame({"t": t, "x": x, "F": F}))
    np.testing.assert_array_equal(m.F, F)


def test_semicolon_and_tab_separated(tmp_path):
    t, x, F = _signal()
    for sep, name in ((";", "a.csv"), ("\t", "a.tsv")):
        p = tmp_path / name
        p.write_text("t" + sep + "x" + sep + "F\n"
                     + "\n".join(sep.join(repr(float(v)) for v in r) for r in zip(t, x, F)))
        np.testing.assert_array_equal(data.load(p).F, F)


# ---- bad input: one test per kind ------------------------------------------------------


def _bad(tmp_path, text, name="bad.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _good_rows(n=20):
    t, x, F = _signal(n)
    return [f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in zip(t, x, F)]


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match=r"nope\.csv: no such file"):
        data.load(tmp_path / "nope.csv")


def test_empty_file(tmp_path):
    with pytest.raises(DataError, match=r"bad\.csv: the file is empty"):
        data.load(_bad(tmp_path, ""))
    with pytest.raises(DataError, match="no data rows"):
        data.load(_bad(tmp_path, "t,x,F\n"))


def test_no_header(tmp_path):
    with pytest.raises(DataError, match="no header row"):
        data.load(_bad(tmp_path, "\n".join(_good_rows())))


def test_missing_column(tmp_path):
    rows = [r.rsplit(",", 1)[0] for r in _good_rows()]
    with pytest.raises(DataError, match=r"missing column 'F' .* or 'u'"):
        data.load(_bad(tmp_path, "t,x\n" + "\n".join(rows)))
    with pytest.raises(DataError, match="missing column 'x'"):
        data.load(_bad(tmp_path, "t,y,F\n" + "\n".join(_good_rows())))


def test_non_numeric_cell(tmp_path):
    rows = _good_rows()
    cells = rows[6].split(",")
    rows[6] = ",".join([cells[0], "abc", cells[2]])
    with pytest.raises(DataError, match=r"column 'x', row 7: 'abc' is not a number"):
        data.load(_bad(tmp_path, "t,x,F\n" + "\n".join(rows)))


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_non_finite(tmp_path, value):
    rows = _good_rows()
    cells = rows[11].split(",")
    rows[11] = ",".join([cells[0], cells[1], value])
    with pytest.raises(DataError, match=r"column 'F', row 12: .* \(not finite\)"):
        data.load(_bad(tmp_path, "t,x,F\n" + "\n".join(rows)))


@pytest.mark.parametrize(("kind", "word"), [("duplicate", "repeats"), ("back", "decreases")])
def test_time_not_increasing(tmp_path, kind, word):
    t, x, F = _signal(30)
    t[9] = t[8] if kind == "duplicate" else t[8] - 1e-3
    with pytest.raises(DataError, match=rf"column 't', row 10: time {word}"):
        data.load(_write_csv(tmp_path / "bad.csv", "t,x,F", (t, x, F)))


def test_too_few_samples(tmp_path):
    with pytest.raises(DataError, match="only 5 samples"):
        data.load(_bad(tmp_path, "t,x,F\n" + "\n".join(_good_rows(5))))


def test_no_motion(tmp_path):
    t, _, F = _signal()
    with pytest.raises(DataError, match="no motion at all"):
        data.load(_write_csv(tmp_path / "bad.csv", "t,x,F", (t, np.full(t.size, 0.01), F)))


def test_unit_that_looks_wrong(tmp_path):
    t, x, F = _signal()
    # A 0.2 m stroke written in mm without declaring it: 200 "m".
    path = _write_csv(tmp_path / "bad.csv", "t,x,F", (t, x * 1e6, F))
    with pytest.raises(DataError, match=r"column 'x' spans 199.9 .*'x\[mm\]'"):
        data.load(path)
    # Declaring metres explicitly accepts it (some machines do travel that far, at a
    # velocity below jaxfric.data.ABSURD: here 1e4 times slower).
    slow = _write_csv(tmp_path / "slow.csv", "t,x,F", (t * 1e4, x * 1e6, F))
    assert data.load(slow, units={"x": "m", "t": "s"}).x.max() > 2


def test_unknown_unit(tmp_path):
    t, x, F = _signal()
    with pytest.raises(DataError, match=r"column 'x': unknown unit 'furlong'"):
        data.load(_write_csv(tmp_path / "bad.csv", "t,x[furlong],F", (t, x, F)))


def test_absurd_magnitude(tmp_path):
    t, x, F = _signal()
    F[3] = 1e9
    with pytest.raises(DataError, match=r"column 'F', row 4: 1e\+09 is absurd"):
        data.load(_write_csv(tmp_path / "bad.csv", "t,x[m],F", (t, x, F)))


def test_row_length_mismatch(tmp_path):
    rows = _good_rows()
    rows[3] += ",7"
    with pytest.raises(DataError, match="row 4: 4 cells, the header has 3"):
        data.load(_bad(tmp_path, "t,x,F\n" + "\n".join(rows)))


def test_force_sign_opposite_warns_and_flip_fixes(tmp_path):
    t, x, F = _signal()
    path = _write_csv(tmp_path / "a.csv", "t,x,F", (t, x, -F))
    with pytest.warns(DataWarning, match="flip-force"):
        m = data.load(path)
    assert data.sign_correlation(m) < -0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        flipped = data.load(path, flip_force=True)
        data.load(_write_csv(tmp_path / "b.csv", "t,x,F", (t, x, F)))  # right sign: silent
    np.testing.assert_array_equal(flipped.F, F)
    assert any("flip" in n for n in flipped.notes)
