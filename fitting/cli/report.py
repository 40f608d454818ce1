"""One HTML page with the figures and tables of a diagnosis (``jaxfric diagnose --report``,
``jaxfric demo``)."""

import html
from pathlib import Path

import numpy as np

from jaxfric import units as _units

from ._io import diagnosis_json, param_units
from ._output import atomic_file, write_json
from .plots import plot_diagnosis


def _table(header, rows) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><tr>{head}</tr>{body}</table>"


def _params_table(res, kind: str) -> str:
    rows, units = [], param_units(res, kind)
    for name in res.names:
        v, s = float(res.params[name]), float(res.stderr[name])
        rel = f"{100 * s / abs(v):.2g} %" if v != 0 and np.isfinite(s) else "-"
        rows.append([name, f"{v:.6g}", f"{s:.3g}", rel, units.get(name, "?")])
    return _table(["parameter", "value", "std. error", "relative", "unit (SI)"], rows)


def _regimes_table(before: dict, after: dict, unit: str) -> str:
    rows = []
    for name, b in before.items():
        a = after.get(name, {})
        fall = (1 - a["rmse"] / b["rmse"]) * 100 if a and b["rmse"] > 0 else float("nan")
        rows.append([name, b["samples"], f"{b['rmse']:.4g}", f"{a.get('rmse', float('nan')):.4g}",
                     f"{fall:.0f} %"])
    return _table(["regime", "samples", f"RMSE before [{unit}]", f"RMSE after [{unit}]",
                   "fall"], rows)


def _runs_tables(d, validation, unit: str, kind: str) -> list[str]:
    """The per-run tables of a diagnosis of several runs: each run's held-out RMSE before
    and after each addition (and its in-sample RMSE), and the runs not used
    (`validation`: ``--validate``), by the baseline and the diagnosed model."""
    if len(d.runs) < 2 and not validation:
        return []
    heads = ["baseline"] + [f"+ {' + '.join(s.added[len(b.added):])}"
                            for b, s in zip([d.baseline, *d.steps], d.steps)]
    rows = [[Path(str(r["run"])).name, r["samples"], *(f"{v:.4g}" for v in r["rmse_holdout"]),
             *(f"{v:.4g}" for v in r["rmse"])] for r in d.runs]
    ins = ["in-sample baseline"] + (["in-sample final"] if d.steps else [])
    out = [f"<h2>Error per run (cross-validation folds: {html.escape(d.folds)})</h2>",
           "<p>held-out RMSE: each run predicted by the models fitted without it "
           f"[{unit}]</p>",
           _table(["run", "samples", *heads, *ins], rows)]
    if validation:
        out += ["<h2>Runs not used (--validate)</h2>",
                _table(["run", "samples", f"baseline [{unit}]", f"diagnosed [{unit}]"],
                       [[Path(v["file"]).name, v["samples"],
                         f"{v['baseline']['rmse']:.4g}", f"{v['diagnosed']['rmse']:.4g}"]
                        for v in validation])]
    return out


def write_report(out_dir, m, d, *, title: str, intro: str = "", shown=None,
                 validation=None) -> Path:
    """Figures (`plot_diagnosis`), ``diagnosis.json`` and ``report.html`` in `out_dir`.
    `m` has ``t, x, F`` and ``velocity()`` (and ``kind``, linear unless it says rotary: then
    every unit on the page is rotary); `d` is a `fitting.Diagnosis`. Several runs: `shown`
    is `d` as the figures read it (predictions concatenated, `m` the runs end to end),
    `validation` the errors of the runs not used. Returns the page."""
    out = Path(out_dir)
    kind = getattr(m, "kind", _units.LINEAR)
    unit = _units.si_unit("F", kind)
    files = plot_diagnosis(out, m, d if shown is None else shown)
    write_json(out / "diagnosis.json", diagnosis_json(d, kind))
    def num(value, fmt):
        return format(value, fmt) if np.isfinite(value) else "-"

    cands = [[c.name, num(c.score, ".3f"), num(c.t_stat, ".2f"),
              "yes" if c.significant else "no", _units.speak(c.evidence, kind)]
             for c in d.candidates]
    steps = [["baseline", f"{d.baseline.rmse:.4g}", f"{d.baseline.rmse_holdout:.4g}",
              f"{100 * d.baseline.rel_error:.3g} %"]]
    steps += [[f"+ {' + '.join(s.added[len(before.added):])}", f"{s.rmse:.4g}",
               f"{s.rmse_holdout:.4g}", f"{100 * s.rel_error:.3g} %"]
              for before, s in zip([d.baseline, *d.steps], d.steps)]
    code = "".join(f"<li><code>{html.escape(c.code)}</code></li>" for c in d.candidates
                   if c.name in d.final.added)
    flags = "".join(f"<li>{which} model: {html.escape(_units.speak(w, kind))}</li>"
                    for which, ws in d.warnings.items() for w in ws)
    how = [d.velocity and f"velocity: {d.velocity}", d.search and f"search: {d.search}",
           d.finding]
    parts = [
        f"<h1>{html.escape(title)}</h1>",
        f"<p>{intro}</p>" if intro else "",
        "".join(f"<p>{html.escape(_units.speak(h, kind))}</p>" for h in how if h),
        "<h2>Error as effects are added</h2>",
        _table(["model", f"RMSE [{unit}]", f"held-out RMSE [{unit}]", "relative"], steps),
        "<h2>Plausibility of the fitted models</h2>",
        f"<ul>{flags or '<li>no warning</li>'}</ul>",
        "<h2>Candidates of the first round (each refitted with the baseline)</h2>",
        "<p>gain = share of the baseline's held-out sum of squares the candidate removes "
        "in the blocked cross-validation (- where not cross-validated: not among the best "
        "training fits, or it cannot qualify: not physical or not converged); z = mean "
        "gain per block over its standard error; added = the "
        "candidate that qualified (z and a physical fit, docs/diagnosis.md) with the "
        "largest gain.</p>",
        _table(["candidate", "gain", "z", "added", "evidence"], cands),
        f"<h3>Added in code</h3><ul>{code or '<li>nothing</li>'}</ul>",
        *_runs_tables(d, validation, unit, kind),
        "<h2>Error per regime, before and after</h2>",
        _regimes_table(_units.speak_json(d.baseline.regimes, kind),
                       _units.speak_json(d.final.regimes, kind), unit),
        "<h2>Figures</h2>",
        *(f'<p><img src="{f}" alt="{f}" style="max-width:100%"></p>' for f in files),
        "<h2>Baseline parameters</h2>",
        _params_table(d.baseline.fit, kind),
        "<h2>Final parameters</h2>",
        _params_table(d.final.fit, kind),
    ]
    page = ("<!doctype html><html><head><meta charset='utf-8'><title>"
            f"{html.escape(title)}</title><style>body{{font-family:sans-serif;max-width:1100px;"
            "margin:auto}} table{border-collapse:collapse} td,th{border:1px solid #ccc;"
            "padding:3px 8px;text-align:right} td:first-child{text-align:left}</style></head>"
            "<body>" + "\n".join(parts) + "</body></html>\n")
    target = out / "report.html"
    with atomic_file(target) as f:
        f.write(page)
    return target
