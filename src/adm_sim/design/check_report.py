"""A self-contained HTML report of the EN 1991-2 dynamic check (``adm-sim check --report F.html``).

One page, no network: the figures are inline SVG, the style sheet is inline, nothing is fetched.
It holds the inputs, the clause-by-clause verdict table, the acceleration envelopes over speed,
the 6.4.6.5(3) ratios over the deck, the governing cases, the damping per mode, the modes used,
what is not checked, and the software version and commit. Formatting only: every number comes from
the :class:`adm_sim.design.check.CheckResult`.
"""

from __future__ import annotations

import csv
import html
import io
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from adm_sim import __version__
from adm_sim.errors import RunError
from adm_sim.design.check_defaults import DEFAULTS
from adm_sim.design.check_text import summary
from adm_sim.design.design_loads import maintenance_text

_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39")


def _commit():
    """The git commit of the source tree, or "unknown" (no repository, no git)."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parent,
                             capture_output=True, text=True, timeout=5)
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _e(x):
    return html.escape(str(x))


def _svg_envelopes(res, width=860, height=360):
    """Largest deck acceleration over speed per train, the limit as a dashed line."""
    ml, mr, mt, mb = 60, 150, 20, 45
    v0, v1 = float(res.speeds_kmh[0]), float(res.speeds_kmh[-1])
    top = max(res.limit_m_s2, max(float(c.max_acc_m_s2.max()) for c in res.trains)) * 1.08
    X = lambda v: ml + (v - v0) / (v1 - v0) * (width - ml - mr)  # noqa: E731
    Y = lambda a: mt + (1 - a / top) * (height - mt - mb)  # noqa: E731
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" role="img" aria-label="acceleration envelopes">',
           f'<rect x="{ml}" y="{mt}" width="{width - ml - mr}" height="{height - mt - mb}" fill="none" stroke="#444"/>']
    for k in range(6):
        a = top * k / 5
        out.append(f'<text x="{ml - 6}" y="{Y(a) + 4:.1f}" font-size="11" text-anchor="end">{a:.1f}</text>')
    for v in np.linspace(v0, v1, 7):
        out.append(f'<text x="{X(v):.1f}" y="{height - mb + 16}" font-size="11" text-anchor="middle">{v:.0f}</text>')
    out.append(f'<text x="{(ml + width - mr) / 2}" y="{height - 8}" font-size="12" text-anchor="middle">speed (km/h)</text>')
    out.append(f'<text x="14" y="{(mt + height - mb) / 2}" font-size="12" transform="rotate(-90 14 '
               f'{(mt + height - mb) / 2})" text-anchor="middle">max deck acceleration (m/s²)</text>')
    for i, c in enumerate(res.trains):
        col = _COLORS[i % len(_COLORS)]
        pts = " ".join(f"{X(v):.1f},{Y(a):.1f}" for v, a in zip(c.speeds_kmh, c.max_acc_m_s2))
        out.append(f'<polyline points="{pts}" fill="none" stroke="{col}" stroke-width="1.3"/>')
        out.append(f'<text x="{width - mr + 8}" y="{mt + 12 + 14 * i}" font-size="11" fill="{col}">{_e(c.name)}</text>')
    yl = Y(res.limit_m_s2)
    out.append(f'<line x1="{ml}" y1="{yl:.1f}" x2="{width - mr}" y2="{yl:.1f}" stroke="#c00" stroke-dasharray="6,4"/>')
    out.append(f'<text x="{ml + 4}" y="{yl - 4:.1f}" font-size="11" fill="#c00">limit {res.limit_m_s2:g} m/s²</text>')
    t, v, a = res.governing
    out.append(f'<circle cx="{X(v):.1f}" cy="{Y(a):.1f}" r="4" fill="#000"/>')
    out.append("</svg>")
    return "\n".join(out)


def _svg_effects(res, width=860, height=300):
    """The largest 6.4.6.5(3) ratio over the trains at every section: moment and shear over x / L."""
    gov = res.effects_governing()
    if not gov:
        return ""
    ml, mr, mt, mb = 60, 150, 20, 45
    L = res.bridge.span_m
    top = max(1.05, max(d.ratio for _, d, _ in gov) * 1.1)
    X = lambda x: ml + x / L * (width - ml - mr)  # noqa: E731
    Y = lambda r: mt + (1 - r / top) * (height - mt - mb)  # noqa: E731
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" role="img" aria-label="ratios over the deck">',
           f'<rect x="{ml}" y="{mt}" width="{width - ml - mr}" height="{height - mt - mb}" fill="none" stroke="#444"/>',
           f'<line x1="{ml}" y1="{Y(1.0):.1f}" x2="{width - mr}" y2="{Y(1.0):.1f}" stroke="#c00" stroke-dasharray="6,4"/>']
    for k in range(6):
        r = top * k / 5
        out.append(f'<text x="{ml - 6}" y="{Y(r) + 4:.1f}" font-size="11" text-anchor="end">{r:.2f}</text>')
    for f in np.linspace(0, 1, 11):
        out.append(f'<text x="{X(f * L):.1f}" y="{height - mb + 16}" font-size="11" text-anchor="middle">{f:.1f}</text>')
    out.append(f'<text x="{(ml + width - mr) / 2}" y="{height - 8}" font-size="12" text-anchor="middle">'
               f'section x / L (-)</text>')
    out.append(f'<text x="14" y="{(mt + height - mb) / 2}" font-size="12" transform="rotate(-90 14 '
               f'{(mt + height - mb) / 2})" text-anchor="middle">ratio train / (Φ α LM71) (-)</text>')
    for kind, col, name in (("M", "#1f77b4", "moment"), ("V", "#ff7f0e", "shear, reactions")):
        pts = sorted((d.effect.x_m, d.ratio) for _, d, _ in gov
                     if d.effect.kind == kind or (kind == "V" and d.effect.kind in ("RA", "RB")))
        out.append(f'<polyline points="{" ".join(f"{X(x):.1f},{Y(r):.1f}" for x, r in pts)}" fill="none" '
                   f'stroke="{col}" stroke-width="1.6"/>')
        for x, r in pts:
            out.append(f'<circle cx="{X(x):.1f}" cy="{Y(r):.1f}" r="3" fill="{col}"/>')
        out.append(f'<text x="{width - mr + 8}" y="{mt + (12 if kind == "M" else 26)}" font-size="11" '
                   f'fill="{col}">{name}</text>')
    out.append("</svg>")
    return "\n".join(out)


def _table(header, rows):
    h = "".join(f"<th>{_e(x)}</th>" for x in header)
    body = "".join("<tr>" + "".join(f"<td>{_e(x)}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def verdict_rows(res):
    """(clause, what, value, limit, verdict) per checked clause."""
    t, v, a = res.governing
    rows = [("EN 1990 A2.4.4.2.1", f"peak deck acceleration ({t.name}, {v:g} km/h)", f"{a:.4f} m/s²",
             f"{res.limit_m_s2:g} m/s²", "PASS" if a <= res.limit_m_s2 else "FAIL")]
    if res.bounds:
        label, tb, vb, ab = res.envelope_governing()
        rows.append(("EN 1991-2 6.4.6.3.2/3", f"envelope over the bounds ({label}, {tb.name}, {vb:g} km/h)",
                     f"{ab:.4f} m/s²", f"{res.limit_m_s2:g} m/s²", "PASS" if res.passed else "FAIL"))
    ge = res.effects_envelope_governing()
    if ge is not None:
        case, tt, d = ge
        where = f", {case}" if res.bounds else ""
        rows.append(("EN 1991-2 6.4.6.5(3)", f"largest train / (Φ α LM71) ratio ({d.effect.label}, {tt.name}{where})",
                     f"{d.ratio:.3f}", "1", "Φ α LM71 governs" if d.ratio <= 1.0 else "the train governs"))
    if res.sls is not None:
        s = res.sls
        rows.append(("EN 1990 A2.4.4.2.3(1)", "vertical deflection under Φ α LM71", f"{1e3 * s.deflection_m:.3f} mm",
                     f"L/600 = {1e3 * s.deflection_limit_m:.3f} mm", "PASS" if s.deflection_ok else "FAIL"))
        ok = s.end_rotation_ok
        rows.append(("infrastructure manager's rule (project's choice; not EN 1991-2)",
                     "deck end rotation under Φ α LM71", f"{1e3 * s.end_rotation_rad:.3f} mrad",
                     "6.5 mrad" if s.track == "ballasted" else "relevant authority",
                     "not judged" if ok is None else ("PASS" if ok else "FAIL")))
        if s.delta_h_m is None:
            rows.append(("EN 1991-2 6.5.4.5.2", "deck-end displacement δ_H = θ h", "h not given", "8 / 10 mm",
                         "not checked"))
        else:
            ok8, ok10 = s.delta_h_ok
            rows.append(("EN 1991-2 6.5.4.5.2", f"deck-end displacement δ_H = θ h (h = {s.deck_end_height_m:g} m)",
                         f"{1e3 * s.delta_h_m:.3f} mm", "8 / 10 mm",
                         f"{'PASS' if ok8 else 'FAIL'} / {'PASS' if ok10 else 'FAIL'}"))
        rows.append(("EN 1990 A2.4.4.2.4(3)", "first lateral frequency", "not given" if s.lateral_frequency_hz is None
                     else f"{s.lateral_frequency_hz:g} Hz", ">= 1.2 Hz",
                     "not checked" if s.lateral_ok is None else ("PASS" if s.lateral_ok else "FAIL")))
    return rows


def table_rows(res, job=None, sources=None, version=None, commit=None):
    """Every table of the report as ``{name: (header, rows)}`` (the page and ``--tables`` CSV files)."""
    version = __version__ if version is None else version
    commit = _commit() if commit is None else commit
    b = res.bridge
    zeta = ", ".join(f"{100 * z:.4g} %" for z in b.modal_damping_ratios(0.0))
    inputs = [("bridge", b.describe(), ""), ("maximum line speed V", f"{res.max_line_speed_kmh:g} km/h", "user"),
              ("speeds", f"{res.speeds_kmh[0]:g} .. {res.speeds_kmh[-1]:g} km/h", "EN 1991-2 6.4.6.2(1)"),
              ("track", res.track, "user" if res.track else ""), ("damping", res.damping, ""),
              ("damping model", res.damping_model, ""), ("ζ per mode", zeta, ""),
              ("modes", ", ".join(str(j) for j in res.modes), "EN 1990 A2.4.4.2.1"),
              ("track maintenance", maintenance_text(res.track_maintenance, res.maintenance_named), ""),
              ("α", f"{res.alpha:g}", "EN 1991-2 6.3.2(3)"), ("trains", ", ".join(c.name for c in res.trains), "")]
    inputs += [(f"source: {k}", v, s) for k, v, s in (sources or [])]
    inputs += [(f"damping of {c.name}", f"{c.delta_zeta_pct:.3f} %", c.damping_note) for c in res.trains]
    inputs += [("program", f"adm-sim {version}", f"commit {commit}")]
    near = [(c.name, f"{c.max_acc_m_s2.max():.4f}", f"{c.speeds_kmh[c.i_max]:g}",
             "" if c.x_max_m is None else f"{c.x_max_m:.3f}") for c in res.near_governing()]
    effects = [(d.effect.label, t.name, f"{d.phi_dyn:.3f}",
                f"{t.effects.at_speed_kmh[i]:.1f}"
                + (" (range end)" if d.phi_dyn > 1e-9 and res.speed_end(t.effects.at_speed_kmh[i]) else ""),
                f"{d.train_static / 1e3:.1f}", f"{d.train_design / 1e3:.1f}", f"{d.lm71_design / 1e3:.1f}",
                f"{d.ratio:.3f}")
               for t, d, i in res.effects_governing()]
    trains = [(c.name, f"{c.max_acc_m_s2.max():.4f}", f"{c.speeds_kmh[c.i_max]:g}",
               "" if c.x_max_m is None else f"{c.x_max_m:.3f}", f"{1000 * c.midspan_disp_m.max():.3f}",
               f"{c.phi_dyn:.3f}", f"{c.delta_zeta_pct:.3f}") for c in res.trains]
    bounds = [(label, f"{r.bridge.n0_hz:.3f}", r.governing[0].name, f"{r.governing[1]:g}", f"{r.governing[2]:.4f}")
              for label, r in [("nominal", res)] + list(res.bounds)]
    return {
        "job": (("field", "value"), (job.rows() if job is not None else [])),
        "inputs": (("item", "value", "source"), inputs),
        "verdict": (("clause", "what", "value", "limit", "verdict"), verdict_rows(res)),
        "governing": (("train within 5 % of the governing value", "max acc (m/s²)", "at (km/h)", "x (m)"), near),
        "trains": (("train", "max acc (m/s²)", "at (km/h)", "x (m)", "max midspan disp (mm)", "φ'_dyn midspan (-)",
                    "Δζ (%)"), trains),
        "effects": (("effect", "train", "φ'_dyn", "at (km/h)", "static (kNm, kN)", "design (kNm, kN)",
                     "Φ α LM71 (kNm, kN)", "ratio"), effects),
        "bounds": (("case", "n0 (Hz)", "governing train", "at (km/h)", "max acc (m/s²)"), bounds if res.bounds else []),
        "defaults": (("default", "value", "source", "kind"), [(d.name, d.value, d.source, d.kind) for d in DEFAULTS]),
        "not_checked": (("not checked",), [(x,) for x in res.not_checked()]),
    }


def write_tables(res, folder, job=None, sources=None, outs=None, option="--tables"):
    """Every table of :func:`table_rows` as ``<folder>/<name>.csv`` (UTF-8), through ``outs``
    (an :class:`adm_sim.files.OutputSet`: all or none) when given."""
    written = []
    for name, (header, rows) in table_rows(res, job, sources).items():
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)
        text = buf.getvalue()
        path = Path(folder) / f"{name}.csv"
        if outs is None:
            path.write_text(text, encoding="utf-8")
        else:
            outs.write(path, lambda p, t=text: p.write_text(t, encoding="utf-8"), option)
        written.append(path)
    return written


TABLE_NAMES = ("job", "inputs", "verdict", "governing", "trains", "effects", "bounds", "defaults", "not_checked")


def report_html(res, version=None, commit=None, job=None, sources=None):
    """The page as one string; ``job`` (:class:`adm_sim.inputs.job.Job`) and ``sources``
    (:func:`adm_sim.inputs.job.input_sources`) give its identification and the inputs' sources."""
    version = __version__ if version is None else version
    commit = _commit() if commit is None else commit
    if getattr(res, "is_deck", False):
        return deck_report_html(res, version, commit, job)
    tables = table_rows(res, job, sources, version, commit)
    verdict = "PASS" if res.passed else "FAIL"
    ident = (job.rows() if job is not None else [(k, "not given") for k in
                                                  ("project", "structure", "element", "author", "checker",
                                                   "revision", "date")])
    warn = "".join(f"<p class='warn'>The largest acceleration of {_e(', '.join(c.name for c in cs))} lies at the "
                   f"{_e(end)} of the checked range: the resonance may lie outside it.</p>"
                   for end, cs in res.range_end_maxima().items())
    warn += "".join(f"<p class='warn'>The maximum of {len(items)} governing effect(s) lies at the {_e(end)} of the "
                    f"checked range ({res.speeds_kmh[-1 if end == 'top' else 0]:g} km/h): "
                    + _e(", ".join(f"{e['effect']} ({e['train']}, φ'_dyn {e['phi_dyn']:.3f}, ratio {e['ratio']:.3f})"
                                   for e in items))
                    + "; φ'_dyn and the ratio may be larger outside it.</p>"
                    for end, items in res.effects_range_end().items())
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>EN 1991-2 dynamic check: {_e(verdict)}</title>",
        "<style>body{font-family:sans-serif;margin:2em;max-width:60em}table{border-collapse:collapse;"
        "margin:.5em 0}td,th{border:1px solid #999;padding:2px 6px;font-size:90%}th{background:#eee}"
        ".pass{color:#070}.fail{color:#b00}.warn{color:#b60}pre{font-size:75%;white-space:pre-wrap}"
        "@media print{body{margin:1cm}}</style></head><body>",
        "<h1>EN 1991-2 dynamic check</h1>",
        '<table id="identification"><tbody>' + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in ident)
        + "</tbody></table>",
        f'<p id="verdict" class="{verdict.lower()}"><b>Verdict: {verdict}</b></p>',
        f"<p>adm-sim {_e(version)}, commit {_e(commit)}</p>",
        "<h2>Inputs and their sources</h2>", _table(*tables["inputs"]),
        "<h2>Verdict, clause by clause</h2>", _table(*tables["verdict"]),
        "<h2>Governing cases</h2>", _table(*tables["governing"]), warn,
        "<h2>Trains</h2>", _table(*tables["trains"]),
        "<h2>Acceleration envelopes over speed</h2>", _svg_envelopes(res),
        "<h2>EN 1991-2 6.4.6.5(3) over the deck</h2>", _svg_effects(res), _table(*tables["effects"]),
        *(["<h2>Mass and stiffness bounds</h2>", _table(*tables["bounds"])] if res.bounds else []),
        *(["<h2>Rough track (beyond the standard)</h2>", f"<p>{_e(res.rough[0].to_dict()['note'])}</p>",
           _table(("train", "seed", "max midspan DIM acc (m/s²)", "at (km/h)", "smooth check (m/s²)"),
                  [(r.train, s, f"{a:.4f}", f"{v:g}", f"{r.smooth_check_m_s2:.4f}") for r in res.rough
                   for s, a, v in zip(r.seeds, r.max_acc_m_s2, r.at_speed_kmh)])] if res.rough else []),
        "<h2>Defaults and project choices</h2>", _table(*tables["defaults"]),
        "<h2>Not checked</h2>", "<ul>" + "".join(f"<li>{_e(x)}</li>" for x in res.not_checked()) + "</ul>",
        "<h2>Full output</h2>", f"<pre>{_e(summary(res))}</pre>",
        f"<p>adm-sim {_e(version)}, commit {_e(commit)}</p>", "</body></html>"]
    return "\n".join(parts)


def deck_report_html(res, version, commit, job=None):
    """The page of a continuous deck's check (:class:`adm_sim.design.check_deck.DeckCheckResult`): the
    identification, the verdict, the spans, the modes, the acceleration per span and the full output."""
    verdict = "PASS" if res.passed else "FAIL"
    ident = job.rows() if job is not None else [(k, "not given") for k in ("project", "structure", "element")]
    b = res.bridge
    spans = [(i + 1, f"{L:g}", f"{res.bridge.supports_m[i]:g} .. {res.bridge.supports_m[i + 1]:g}",
              f"{e:.4g}", f"{m:.6g}") for i, (L, e, m) in enumerate(zip(b.spans_m, b.span_EJ_Nm2, b.span_mu_kg_m))]
    modes = [(j, f"{f:.4f}", f"{m:.6g}") for j, f, m in zip(res.modes, b.frequencies_hz, b.modal_mass_kg)]
    per_span = [(s + 1, t.name, f"{v:g}", f"{x:.3f}", f"{a:.4f}", "PASS" if a <= res.limit_m_s2 else "FAIL")
                for s, (t, v, a, x) in enumerate(res.span_governing())]
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>EN 1991-2 dynamic check of a continuous deck: {_e(verdict)}</title>",
             "<style>body{font-family:sans-serif;margin:2em;max-width:60em}table{border-collapse:collapse}"
             "td,th{border:1px solid #999;padding:2px 6px;font-size:90%}pre{font-size:75%;white-space:pre-wrap}"
             "</style></head><body>", "<h1>EN 1991-2 dynamic check of a continuous deck</h1>",
             '<table id="identification"><tbody>' + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>"
                                                           for k, v in ident) + "</tbody></table>",
             f'<p id="verdict"><b>Verdict: {verdict}</b></p>', f"<p>adm-sim {_e(version)}, commit {_e(commit)}</p>",
             "<h2>Spans</h2>", _table(("span", "L (m)", "x (m)", "EJ (N m²)", "μ (kg/m)"), spans),
             "<h2>Modes used</h2>", _table(("mode", "frequency (Hz)", "modal mass (kg)"), modes),
             "<h2>Acceleration per span</h2>",
             _table(("span", "governing train", "speed (km/h)", "x (m)", "max |a| (m/s²)", "verdict"), per_span),
             "<h2>Acceleration envelopes over speed</h2>", _svg_envelopes(res),
             "<h2>Full output</h2>", f"<pre>{_e(res.summary())}</pre>", "</body></html>"]
    return "\n".join(parts)


def write_report(res, path, job=None, sources=None):
    """Write :func:`report_html` to ``path`` (UTF-8)."""
    Path(path).write_text(report_html(res, job=job, sources=sources), encoding="utf-8")


#: Names of a headless Chromium on PATH, in the order tried.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")


def find_chromium():
    """The path of a Chromium that can print to PDF, or None."""
    return next((p for p in map(shutil.which, CHROMIUM_NAMES) if p), None)


def write_pdf(res, path, job=None, sources=None, chromium=None, timeout_s=180.0):
    """The report as a PDF through headless Chromium (``--print-to-pdf``; no network: the page is a
    local file that fetches nothing, and Chromium runs without its background services).

    Raises
    ------
    RunError
        No Chromium, or Chromium failed (its last line).
    """
    exe = chromium or find_chromium()
    if exe is None:
        raise RunError(f"--report {path}: no headless Chromium on this machine ({', '.join(CHROMIUM_NAMES)} not on "
                       f"PATH); write --report X.html and print it to PDF from a browser")
    with tempfile.TemporaryDirectory(prefix="adm-sim-report-") as tmp:
        page = Path(tmp) / "report.html"
        page.write_text(report_html(res, job=job, sources=sources), encoding="utf-8")
        out = Path(tmp) / "report.pdf"
        cmd = [exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               "--no-first-run", "--no-pdf-header-footer", f"--user-data-dir={tmp}/profile",
               f"--print-to-pdf={out}", page.as_uri()]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
        except (OSError, subprocess.SubprocessError) as exc:
            raise RunError(f"--report {path}: Chromium failed ({exc})") from None
        if not out.is_file() or out.stat().st_size == 0:
            last = (r.stderr.strip().splitlines() or ["no output"])[-1]
            raise RunError(f"--report {path}: Chromium wrote no PDF (exit {r.returncode}: {last})")
        Path(path).write_bytes(out.read_bytes())
