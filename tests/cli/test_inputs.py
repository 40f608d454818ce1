"""Bad inputs and bad options: one line on stderr, exit 2, no traceback, nothing blocks or
grows without bound (issue 21, item 4). The command line cases run in one subprocess
(`_RUNNER`) to pay for the import of JAX once."""

import json
import os
import subprocess
import sys
import tempfile
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from jaxfric import data
from jaxfric.data import DataError


_RUNNER = r"""
import contextlib, io, json, resource, sys, traceback
import fitting.cli.commands  # imported before any privilege is dropped
from fitting.cli.main import main as cli_main
cases, drop = json.loads(sys.argv[1]), int(sys.argv[2])
if drop:
    import os
    os.setgid(65534)
    os.setuid(65534)
out = {}
for name, argv in cases.items():
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = cli_main(argv)
        except BaseException:
            traceback.print_exc()
            rc = "traceback"
    out[name] = {"rc": rc, "stderr": err.getvalue(),
                 "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
print(json.dumps(out))
"""


def _run_cases(cases: dict, drop: bool = False, timeout: float = 120) -> dict:
    env = {**os.environ, "JAXFRIC_CACHE_DIR": ""}  # nothing of the cache on stderr
    r = subprocess.run([sys.executable, "-c", _RUNNER, json.dumps(cases), str(int(drop))],
                       capture_output=True, text=True, timeout=timeout, env=env)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def _signal(n=200):
    t = np.arange(n) * 1e-3
    x = 1e-3 * np.sin(2 * np.pi * t / t[-1] * 2)
    v = np.gradient(x, t)
    return t, x, np.tanh(v / 1e-3)


def _csv(path, header="t,x,F", trailing=""):
    t, x, F = _signal()
    rows = "\n".join(f"{a:.17g},{b:.17g},{c:.17g}{trailing}" for a, b, c in zip(t, x, F))
    path.write_text(f"{header}\n{rows}\n")
    return path


def _bomb(path, n):
    """An .npz whose column t inflates to `n` float64 zeros from about n/1000 bytes."""
    _, x, F = _signal()
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open("t.npy", "w", force_zip64=True) as f:
            np.lib.format.write_array_header_1_0(
                f, {"descr": "<f8", "fortran_order": False, "shape": (n,)})
            chunk = bytes(8 * 1_000_000)
            for _ in range(n // 1_000_000):
                f.write(chunk)
        for name, arr in (("x", x), ("F", F)):
            with z.open(f"{name}.npy", "w") as f:
                np.lib.format.write_array(f, arr)
    return path


@pytest.fixture(scope="module")
def cli_results(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("inputs")
    good = _csv(tmp / "good.csv")
    t, x, F = _signal()
    np.save(tmp / "array.npy", np.c_[t, x, F])
    os.replace(tmp / "array.npy", tmp / "renamed.npz")
    np.savez(tmp / "objects.npz", t=t, x=np.array(list(x), dtype=object), F=F)
    fifo = tmp / "pipe.csv"
    os.mkfifo(fifo)
    bomb = _bomb(tmp / "bomb.npz", 30_000_000)
    huge = tmp / "huge.csv"
    with open(huge, "wb") as f:  # sparse: no disk used, and nothing may read it
        f.truncate(data.MAX_FILE_BYTES + 1)
    time_back = tmp / "back.csv"
    time_back.write_text("t,x,F\n" + "\n".join(
        f"{0.01 * i if i != 9 else 0.07985:.17g},{1e-4 * i},1" for i in range(20)) + "\n")
    params_list = tmp / "plist.json"
    params_list.write_text(json.dumps({"model": "tustin", "params": [1.0, 2.0]}))
    fit = ["fit", "--model", "tustin"]
    cases = {
        "npy_renamed": [*fit, str(tmp / "renamed.npz")],
        "object_npz": [*fit, str(tmp / "objects.npz")],
        "dev_zero": [*fit, "/dev/zero"],
        "fifo": [*fit, str(fifo)],
        "bomb": [*fit, str(bomb)],
        "huge": [*fit, str(huge)],
        "time_back": [*fit, str(time_back)],
        "elements_0": ["fit", "--model", "gms", "--elements", "0", str(good)],
        "max_steps_negative": [*fit, "--max-steps", "-1", str(good)],
        "window_nan": ["diagnose", "--velocity-window", "nan", str(good)],
        "window_negative": ["diagnose", "--velocity-window", "-0.01", str(good)],
        "search_negative": ["diagnose", "--search-samples", "-5", str(good)],
        "kind_conflict": [*fit, "--rotary", "--kind", "linear", str(good)],
        "params_list": ["simulate", str(good), "--params", str(params_list),
                        "--out", str(tmp / "sim.csv")],
    }
    return _run_cases(cases, timeout=120)


EXPECTED = {
    "npy_renamed": "a single .npy array, not an .npz archive",
    "object_npz": "column 'x' holds Python objects",
    "dev_zero": "zero: is a device, not a data file",
    "fifo": "pipe.csv: is a FIFO (named pipe), not a data file",
    "bomb": f"column 't' has 30000000 values, beyond the limit of {data.MAX_SAMPLES}",
    "huge": "MiB is beyond the limit of 1024 MiB",
    "time_back": "time decreases (0.07985 after 0.08)",
    "elements_0": "--elements 0: a GMS model needs at least 1 element",
    "max_steps_negative": "--max-steps -1: must be 0 or more",
    "window_nan": "--velocity-window nan: must be a finite time > 0",
    "window_negative": "--velocity-window -0.01: must be a finite time > 0",
    "search_negative": "--search-samples -5: must be 0 (every sample) or more",
    "kind_conflict": "--rotary and --kind linear contradict each other",
    "params_list": "plist.json: 'params' must be an object of parameter names and numbers",
}


@pytest.mark.parametrize("case", sorted(EXPECTED))
def test_bad_input_is_one_line_exit_2(cli_results, case):
    r = cli_results[case]
    assert r["rc"] == 2, r["stderr"]
    lines = r["stderr"].strip().splitlines()
    assert len(lines) == 1, r["stderr"]  # no traceback
    assert EXPECTED[case] in lines[0], lines[0]
    assert "np.float64" not in lines[0]


def test_a_small_npz_that_inflates_is_refused_without_inflating_it(cli_results):
    # 30 million doubles would be 240 MB; the header is refused before the data is read.
    # The whole process (JAX imported) stays well under that on top of the import.
    assert cli_results["bomb"]["maxrss_mb"] < cli_results["npy_renamed"]["maxrss_mb"] + 100


def test_unreadable_file_is_one_line():
    """A file we may not read (as root, the runner drops to the user nobody first)."""
    with tempfile.TemporaryDirectory() as folder:
        os.chmod(folder, 0o755)  # the folder may be entered, the file not read
        path = _csv(Path(folder) / "secret.csv")
        path.chmod(0)
        r = _run_cases({"perm": ["fit", "--model", "tustin", str(path)]},
                       drop=os.geteuid() == 0, timeout=60)["perm"]
    assert r["rc"] == 2, r["stderr"]
    lines = r["stderr"].strip().splitlines()
    assert len(lines) == 1 and "secret.csv: permission denied" in lines[0], r["stderr"]


def test_text_column_is_ignored_with_a_note(tmp_path):
    t, x, F = _signal()
    rows = "\n".join(f"{a:.17g},{b:.17g},run {i},{c:.17g}"
                     for i, (a, b, c) in enumerate(zip(t, x, F)))
    path = tmp_path / "label.csv"
    path.write_text(f"t,x,label,F\n{rows}\n")
    m = data.load(path)
    np.testing.assert_array_equal(m.F, F)
    assert "label" not in m.extra
    assert any("'label' is text" in n and "ignored" in n for n in m.notes), m.notes


def test_text_in_a_standard_column_is_still_an_error(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("t,x,F\n" + "\n".join(f"{i * 1e-3},{i * 1e-5},abc" for i in range(20)))
    with pytest.raises(DataError, match=r"column 'F', row 1: 'abc' is not a number"):
        data.load(path)


def test_trailing_commas_are_accepted(tmp_path):
    F = _signal()[2]
    for header, trailing in (("t,x,F,", ","), ("t,x,F", ","), ("t,x,F,", "")):
        m = data.load(_csv(tmp_path / "trail.csv", header, trailing))
        np.testing.assert_array_equal(m.F, F)
        assert set(m.extra) == set()


def test_csv_read_is_streamed(tmp_path):
    """Peak memory of loading a CSV is a small multiple of the numbers kept, not of the
    text (reading all lines into Python strings takes about 30 times the arrays)."""
    n = 200_000
    t = np.arange(n) * 1e-3
    x = 1e-3 * np.sin(t)
    F = np.cos(t)
    path = tmp_path / "long.csv"
    np.savetxt(path, np.c_[t, x, F], delimiter=",", header="t,x,F", comments="", fmt="%.17g")
    tracemalloc.start()
    try:
        m = data.load(path, check_sign=False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    kept = 3 * n * 8
    assert len(m) == n
    assert peak < 4 * kept, (peak / kept, path.stat().st_size / kept)


def test_wrong_npz_from_python_is_a_data_error(tmp_path):
    (tmp_path / "text.npz").write_text("t,x,F\n1,2,3\n")
    with pytest.raises(DataError, match=r"not an \.npz file"):
        data.load(tmp_path / "text.npz")
    np.savez(tmp_path / "two_d.npz", t=np.zeros((20, 2)), x=np.zeros(20), F=np.zeros(20))
    with pytest.raises(DataError, match=r"column 't' must be 1-D, got shape \(20, 2\)"):
        data.load(tmp_path / "two_d.npz")


def test_binary_or_unparseable_file_named_csv(tmp_path):
    t, x, F = _signal()
    np.savez(tmp_path / "a.npz", t=t, x=x, F=F)
    os.replace(tmp_path / "a.npz", tmp_path / "zip.csv")
    with pytest.raises(DataError, match=r"zip\.csv: is a zip archive, not a text \(CSV\) file"):
        data.load(tmp_path / "zip.csv")
    (tmp_path / "bin.csv").write_bytes(b"\x7fELF\x02\x01\x01\x00" + bytes(100))
    with pytest.raises(DataError, match=r"bin\.csv: is binary data"):
        data.load(tmp_path / "bin.csv")
    (tmp_path / "wide.csv").write_text("t,x,F\n1," + "9" * 200_000 + ",3\n")
    with pytest.raises(DataError, match=r"wide\.csv: not a readable CSV file \(field larger"):
        data.load(tmp_path / "wide.csv")
