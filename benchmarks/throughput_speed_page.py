"""The tables of docs/speed.md, written from the benchmarks' JSONs (no number typed by hand).

docs/speed.md holds its prose; each table sits between ``<!-- table: NAME -->`` and
``<!-- end table -->`` and this script rewrites what is between them from
``benchmarks/throughput.json``, ``benchmarks/montecarlo_speed.json`` and the profiles in
``benchmarks/profiling/profile_two_state*.json`` and ``profile_fit_fixed.json``. Run ``python
benchmarks/throughput_speed_page.py`` after re-running any of them (``--check`` exits 1 when
the page is out of date, without writing).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "speed.md"
PURE = "TwoState (pure JAX)"
PROFILES = {
    "one trajectory, 1e5 (`profile_two_state.json`)": "profile_two_state.json",
    "one trajectory, 1e5, pure JAX (`profile_two_state_pure_jax.json`)":
        "profile_two_state_pure_jax.json",
    "`vmap` 256 x 1e4 (`profile_two_state_batch.json`)": "profile_two_state_batch.json",
    "256 parameter sets x 1e4 (`profile_two_state_params.json`)":
        "profile_two_state_params.json",
}


def _load(rel: str) -> dict | None:
    path = ROOT / rel
    return json.loads(path.read_text()) if path.is_file() else None


def _g(x, spec=".3g") -> str:
    return "-" if x is None else format(x, spec)


def _table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join(["---"] + ["---:"] * (len(header) - 1)) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _row(case, kernel, pure, numba) -> list[str]:
    def ratio(t):
        return _g(None if t is None or numba is None else numba / t, ".2f")

    return [case, _g(kernel), _g(pure), _g(numba), ratio(kernel), ratio(pure)]


def simulation_table(tp: dict | None, mc: dict | None) -> str:
    rows = []
    if tp is not None:
        single = {(r["impl"], r["n"]): r["median_s"] for r in tp["single"]["rows"]}
        for n in tp["config"]["single_n"]:
            rows.append(_row(f"one trajectory, {n:.0e} (`throughput.py`)",
                             single.get(("TwoState", n)), single.get((PURE, n)),
                             single.get(("Numba two-state", n))))
        for r in tp["batch"]["rows"]:
            rows.append(_row(f"`vmap` batch, {r['B']} x {r['n']:.0e} (`throughput.py`)",
                             r.get("jax_median_s"), r.get("jax_pure_median_s"),
                             r.get("numba_median_s")))
    if mc is not None:
        for r in mc["rows"]:
            size = r["size"]
            if size["B"] == 1:  # one trajectory: `throughput.py`'s rows above
                continue
            what = (r["case"].split(":")[0] if size["B"] > 1 else
                    f"one trajectory, {size['n']:.0e}")
            if size["B"] > 1:
                what += f", {size['B']} x {size['n']:.0e}, `simulate_many`"
            rows.append(_row(f"{what} (`montecarlo_speed.py`)", r["jaxfric_s"],
                             r["pure_jax_s"], r["numba_s"]))
    table = _table(["case (script)", "kernel s", "pure JAX s", "Numba s", "ratio, kernel",
                    "ratio, pure JAX"], rows)
    return table.replace("e+0", "e")


def _profile_value(rows, name, stage=False):
    for r in rows:
        if r["stage"].startswith(name):
            return r["stage_ns_per_sample"] if stage else r["ns_per_sample"]
    return None


def profile_table() -> str:
    rows = []
    for label, name in PROFILES.items():
        d = _load(f"benchmarks/profiling/{name}")
        if d is None:
            continue
        r = d["rows"]
        # With JAXFRIC_EVENT_KERNEL=jax the kernel's rows ran the JAX path: not shown.
        kernel = d["meta"].get("event_pass") != "pure JAX"
        rows.append([label, _g(_profile_value(r, "2.", stage=True), ".0f"),
                     _g(_profile_value(r, "6.", stage=False), ".0f"),
                     _g(_profile_value(r, "forward kernel") if kernel else None, ".0f"),
                     _g(_profile_value(r, "jacfwd, kernel") if kernel else None, ".0f"),
                     _g(_profile_value(r, "jacfwd, JAX path"), ".0f")])
    return _table(["profile (JSON in `benchmarks/profiling/`)", "event pass",
                   "JAX path, whole", "forward kernel", "jacfwd, kernel", "jacfwd, JAX path"],
                  rows)


def lm_table(tp: dict | None) -> str:
    if tp is None:
        return "No results: `benchmarks/throughput.json` is missing."
    lm, pure = tp["lm"], tp.get("lm_pure_jax")
    rows = [["one LM iteration", _g(lm["iteration_s"]),
             _g(pure and pure["iteration_s"]),
             _g(pure and pure["iteration_s"] / lm["iteration_s"], ".2f")]]
    for g in tp["grad"]["rows"][-1:]:  # the largest size
        rows.append([f"`jacfwd` of `simulate`, {g['n']:.0e}", _g(g["jacfwd"]["median_s"]),
                     "-", "-"])
        rows.append([f"`grad` of a loss, {g['n']:.0e}", _g(g["grad"]["median_s"]), "-", "-"])
    return _table(["case", "kernel s", "pure JAX s", "pure / kernel"], rows).replace("e+0", "e")


def fit_fixed_table() -> str:
    d = _load("benchmarks/profiling/profile_fit_fixed.json")
    if d is None:
        return "No results: `benchmarks/profiling/profile_fit_fixed.json` is missing."
    one, five = d["fits"]
    extra = max(five["num_steps"] - one["num_steps"], 1)
    rows = [[stage, _g(one["median_s"][stage]), _g(five["median_s"][stage]),
             _g((five["median_s"][stage] - one["median_s"][stage]) / extra)]
            for stage in one["median_s"]]
    for key, label in (("total_blas_threads_s", "total, OpenBLAS's own threads"),
                       ("total_gc_s", "total, garbage collector running")):
        if key in one:
            a, b = one[key], five[key]
            rows.append([label, _g(a), _g(b), _g((b - a) / extra)])
    return _table(["stage", "max_steps=1 s", "max_steps=5 s", "per further step s"],
                  rows).replace("e-0", "e-")


def render(text: str) -> str:
    tp, mc = _load("benchmarks/throughput.json"), _load("benchmarks/montecarlo_speed.json")
    tables = {"simulation": simulation_table(tp, mc), "profile": profile_table(),
              "lm": lm_table(tp), "fit_fixed": fit_fixed_table()}

    def fill(m):
        name = m.group(1)
        if name not in tables:
            raise SystemExit(f"docs/speed.md: unknown table {name!r}")
        return f"<!-- table: {name} -->\n{tables[name]}\n<!-- end table -->"

    return re.sub(r"<!-- table: (\w+) -->\n.*?<!-- end table -->", fill, text, flags=re.S)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the page is out of date")
    args = ap.parse_args(argv)
    old = PAGE.read_text()
    new = render(old)
    if args.check:
        return int(new != old)
    PAGE.write_text(new)
    print(f"wrote {PAGE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
