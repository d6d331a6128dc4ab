"""The text of the EN 1991-2 dynamic check (``adm-sim check``): formatting only.

:mod:`adm_sim.design.check` computes; this module turns a :class:`adm_sim.design.check.CheckResult` into the lines
the command prints. Nothing here changes a number.
"""

from __future__ import annotations

from adm_sim.design.check import MIN_SPEED_M_S, NEAR_GOVERNING_FRACTION, REFINE_STEP_KMH
from adm_sim.design.design_loads import maintenance_text
from adm_sim.limits import DESIGN_SPEED_FACTOR


def damping_model_text(res):
    """The damping model and the ζ of every mode of the bridge without Δζ."""
    z = res.bridge.modal_damping_ratios(0.0)
    modes = ", ".join(f"{100 * x:.4g} %" for x in z)
    if res.damping_model == "modal":
        how = "modal: zeta on every mode (EN 1991-2 6.4.6.3.1, Table 6.6)"
    else:
        how = "rayleigh13: Rayleigh damping anchored at modes 1 and 3"
    return f"damping model {how}; zeta per mode {modes}"


def position_text(res, t):
    x = t.x_max_m
    if x is None:
        return ""
    return f", x = {x:.3f} m ({x / res.bridge.span_m:.3f} L)"


def where_sentence(res):
    if res.where == "deck":
        return ("largest |a| anywhere on the deck (EN 1990 A2.4.4.2.1), exact in time and position "
                "(adm_sim.integrate.envelope: closed form, Newton in (t, x))")
    if res.where == "midspan":
        return "at midspan only (--where midspan; the standard limits the whole deck)"
    return f"at {res.where_text} only (--where; the standard limits the whole deck)"


def header_lines(res):
    b = res.bridge
    v = res.speeds_kmh
    return [b.describe(),
            f"speeds: {v.min():g} .. {v.max():g} km/h ({MIN_SPEED_M_S:g} m/s .. {DESIGN_SPEED_FACTOR:g} x "
            f"{res.max_line_speed_kmh:g} km/h, "
            f"EN 1991-2 6.4.6.2), {v.size} speeds at <= 1 km/h, refined at {REFINE_STEP_KMH:g} km/h "
            f"around every resonance",
            "modes: " + ", ".join(f"{j} ({f:.3f} Hz, {m / 1000:.5g} t)" for j, f, m in
                                  zip(res.modes, b.frequencies_hz, b.modal_mass_kg))
            + " (frequency, modal mass; EN 1990 A2.4.4.2.1: at least all modes up to "
            f"max(30 Hz, 1.5 n0, n3) = {res.f_limit_hz:.1f} Hz; "
            + ("every mode moves the deck)" if res.where != "midspan" else "even modes do not move midspan)"),
            f"acceleration: {where_sentence(res)}",
            damping_model_text(res),
            f"track maintenance: {maintenance_text(res.track_maintenance, res.maintenance_named)}",
            f"damping: zeta = {100 * b.damping_ratio:.3g} % plus, per train:"]


def _name_width(names, least):
    """Width of a column of train names: ``least``, or wider for a longer name (HSLM-B:N=..:d=..)."""
    return max([least] + [len(n) for n in names])


def train_table_lines(res):
    xs = res.where != "midspan"
    w = _name_width([c.name for c in res.trains], 14)
    out = [f"{'train':{w}s} {'max acc':>9s} {'at':>8s}" + (f" {'x':>7s}" if xs else "")
           + f" {'max disp':>9s} {'phi_dyn':>8s} {'dzeta':>7s}  zeta per mode",
           f"{'':{w}s} {'(m/s2)':>9s} {'(km/h)':>8s}" + (f" {'(m)':>7s}" if xs else "")
           + f" {'(mm)':>9s} {'(-)':>8s} {'(%)':>7s}  (%)"]
    for c in res.trains:
        i = c.i_max
        out.append(f"{c.name:{w}s} {c.max_acc_m_s2[i]:9.4f} {c.speeds_kmh[i]:8.1f}"
                   + (f" {c.x_max_m:7.3f}" if xs else "")
                   + f" {1000 * c.midspan_disp_m.max():9.3f} {c.phi_dyn:8.3f} {c.delta_zeta_pct:7.3f}  "
                   f"{c.zeta_text()}")
    out.append("max disp: midspan; phi_dyn = phi'_dyn = max |y_dyn / y_stat| - 1 at midspan (EN 1991-2 "
               "6.4.6.5(3), Eq. 6.14)")
    return out


def design_lines(res):
    """EN 1991-2 6.4.6.5(3): the midspan moment and deflection per train against Φ x α x LM71."""
    comps = [c.design for c in res.trains if c.design is not None]
    if not comps:
        return []
    d0 = comps[0]
    w = _name_width([c.name for c in res.trains], 14)
    phi = "Phi2 (careful maintenance, 6.4.5.2(2))" if res.track_maintenance == "careful" else \
        "Phi3 (standard maintenance, 6.4.5.2(3))"
    dd = "phi''/2" if d0.phi_dd_factor == 0.5 else "phi''"
    out = [f"EN 1991-2 6.4.6.5(3), midspan of the simply supported span: (1 + phi'_dyn + {dd}) x train "
           f"vs {phi} = {d0.Phi:.3f} x alpha = {d0.alpha:g} x LM71 (6.3.2); phi'' = {d0.phi_dd:.4f} (Annex C, "
           f"v = {res.max_line_speed_kmh:g} km/h); alpha x LM71 static: M {d0.lm71_static_moment_Nm / 1e3:.1f} kNm, "
           f"w {1e3 * d0.lm71_static_deflection_m:.3f} mm",
           f"{'train':{w}s} {'phi_M':>7s} {'M design':>10s} {'M/LM71':>7s} {'phi_w':>7s} {'w design':>9s} "
           f"{'w/LM71':>7s}",
           f"{'':{w}s} {'(-)':>7s} {'(kNm)':>10s} {'(-)':>7s} {'(-)':>7s} {'(mm)':>9s} {'(-)':>7s}"]
    for c in res.trains:
        d = c.design
        if d is None:
            continue
        out.append(f"{c.name:{w}s} {d.phi_dyn_moment:7.3f} {d.train_design_moment_Nm / 1e3:10.1f} "
                   f"{d.ratio_moment:7.3f} {d.phi_dyn_deflection:7.3f} {1e3 * d.train_design_deflection_m:9.3f} "
                   f"{d.ratio_deflection:7.3f}")
    for e, d in res.design_governing().items():
        side = "the train" if getattr(d, f"governs_{e}") == "train" else "Phi x alpha x LM71"
        out.append(f"design {e}: governed by {side} (largest train ratio {getattr(d, f'ratio_{e}'):.3f}, "
                   f"{d.train})")
    return out


def effects_lines(res):
    """EN 1991-2 6.4.6.5(3) for every effect along the span: the governing train per effect and section."""
    gov = res.effects_governing()
    if not gov:
        return []
    t0 = gov[0][0]
    d0 = gov[0][1]
    w = _name_width([t.name for t, _, _ in gov], 10)
    share = "phi''/2 (careful maintenance, Annex C: 1 + phi' + phi''/2)" if d0.phi_dd_factor == 0.5 else \
        "phi'' (standard maintenance, Annex C: 1 + phi' + phi'')"
    out = [f"EN 1991-2 6.4.6.5(3), every effect: (1 + phi'_dyn + {share}) x train vs Phi = {d0.Phi:.3f} x alpha "
           f"x LM71 (distributed load on the unfavourable part of each influence line); phi'_dyn by the "
           f"mode-acceleration method: {t0.effects.n_modes} modes dynamic plus the exact static effect "
           f"(every mode), sections every L/10; M in kNm, V and reactions in kN",
           f"{'effect':16s} {'train':{w}s} {'phi_dyn':>8s} {'at':>7s} {'static':>9s} {'design':>9s} "
           f"{'Phi LM71':>9s} {'ratio':>6s}",
           f"{'':16s} {'':{w}s} {'(-)':>8s} {'(km/h)':>7s} {'':>9s} {'':>9s} {'':>9s} {'(-)':>6s}"]
    for t, d, i in gov:
        end = res.speed_end(t.effects.at_speed_kmh[i]) if d.phi_dyn > 1e-9 else None
        out.append(f"{d.effect.label:16s} {t.name:{w}s} {d.phi_dyn:8.3f} {t.effects.at_speed_kmh[i]:7.1f} "
                   f"{d.train_static / 1e3:9.1f} {d.train_design / 1e3:9.1f} {d.lm71_design / 1e3:9.1f} "
                   f"{d.ratio:6.3f}" + (f"  at the {end} of the range" if end else ""))
    t, d, _ = max(gov, key=lambda g: g[1].ratio)
    side = "the train" if d.ratio > 1.0 else "Phi x alpha x LM71"
    out.append(f"every effect: governed by {side} (largest ratio {d.ratio:.3f}: {d.effect.label}, {t.name})")
    return out


def comfort_lines(res):
    out = []
    for c in res.trains:
        cd = c.comfort_dict()
        if cd is not None:
            out.append(f"passenger comfort {c.name}: largest vertical car-body acceleration b_v = "
                       f"{cd['b_v_m_s2']:.3f} m/s2 (DIM): {cd['level']} (EN 1990 A2.4.4.3: 1.0 very good, "
                       f"1.3 good, 2.0 acceptable)")
    return out


def verdict_lines(res):
    """The governing line, the trains within 5 % of it, and any maximum at an end of the speed range."""
    t, sp, acc = res.governing
    margin = res.limit_m_s2 - acc
    what = {"deck": "max deck acceleration (whole deck)", "midspan": "max midspan acceleration"}.get(
        res.where, f"max acceleration at {res.where_text}")
    out = [f"governing: {t.name} at {sp:g} km/h{position_text(res, t)}, {what} {acc:.4f} m/s2; limit "
           f"{res.limit_m_s2:g} m/s2 ({res.track} track, EN 1990 A2.4.4.2.1): "
           f"{'PASS' if acc <= res.limit_m_s2 else 'FAIL'}{' (nominal bridge)' if res.bounds else ''}, "
           f"margin {margin:+.4f} m/s2 "
           f"({100 * margin / res.limit_m_s2:+.1f} % of the limit); damping model {res.damping_model} "
           f"(zeta per mode {t.zeta_text()} %)"]
    near = [c for c in res.near_governing() if c is not t]
    if near:
        items = ", ".join(f"{c.name} {c.max_acc_m_s2.max():.4f} m/s2 at {c.speeds_kmh[c.i_max]:g} km/h "
                          f"({100 * (c.max_acc_m_s2.max() / acc - 1):+.1f} %)" for c in near)
        out.append(f"within {100 * NEAR_GOVERNING_FRACTION:g} % of the governing value: {items}")
    else:
        out.append(f"no other train within {100 * NEAR_GOVERNING_FRACTION:g} % of the governing value")
    for end, trains in res.range_end_maxima().items():
        names = ", ".join(f"{c.name} ({c.max_acc_m_s2.max():.4f} m/s2)" for c in trains)
        if end == "top":
            out.append(f"WARNING: the largest acceleration of {names} lies at the top of the checked range, "
                       f"{res.speeds_kmh[-1]:g} km/h = 1.2 V: the resonance may lie above it; extend the range "
                       f"with a higher --max-line-speed (1.2 V is the check's top) to see the peak")
        else:
            out.append(f"WARNING: the largest acceleration of {names} lies at the bottom of the checked range, "
                       f"{res.speeds_kmh[0]:g} km/h = {MIN_SPEED_M_S:g} m/s: a resonance lies at or below it, outside the "
                       f"speeds EN 1991-2 6.4.6.2(1) asks for; check the lower speeds with adm-sim sweep")
    out.extend(effects_range_end_lines(res))
    return out


def effects_range_end_lines(res):
    """The warning of :func:`verdict_lines` for every governing effect whose maximum lies at an end of
    the checked speeds (:meth:`adm_sim.design.check.CheckResult.effects_range_end`)."""
    out = []
    for end, items in res.effects_range_end().items():
        names = ", ".join(f"{e['effect']} ({e['train']}, phi'_dyn {e['phi_dyn']:.3f}, ratio {e['ratio']:.3f})"
                          for e in items)
        if end == "top":
            out.append(f"WARNING: the maximum of {len(items)} governing effect(s) lies at the top of the checked range, "
                       f"{res.speeds_kmh[-1]:g} km/h = 1.2 V: {names}; the resonance may lie above it, so phi'_dyn "
                       f"and the 6.4.6.5(3) ratio may be larger there; extend the range with a higher "
                       f"--max-line-speed to see the peak")
        else:
            out.append(f"WARNING: the maximum of {len(items)} governing effect(s) lies at the bottom of the checked "
                       f"range, {res.speeds_kmh[0]:g} km/h = {MIN_SPEED_M_S:g} m/s: {names}; a resonance lies at or "
                       f"below it, outside the speeds EN 1991-2 6.4.6.2(1) asks for")
    return out


def bounds_lines(res):
    """The nominal bridge and every mass and stiffness bound: n0, governing train, speed, acceleration."""
    if not res.bounds:
        return []
    out = ["mass and stiffness bounds (EN 1991-2 6.4.6.3.2, 6.4.6.3.3): the check at every bound"]
    for label, r in [("nominal", res)] + list(res.bounds):
        t, v, a = r.governing
        g = r.largest_effect_ratio()
        eff = "" if g is None else f"; 6.4.6.5(3) largest ratio {g[1].ratio:.3f} ({g[1].effect.label}, {g[0].name})"
        out.append(f"  {label:38s} n0 {r.bridge.n0_hz:7.3f} Hz: {t.name} {a:.4f} m/s2 at {v:g} km/h{eff}")
    label, t, v, a = res.envelope_governing()
    out.append(f"envelope over the bounds: {a:.4f} m/s2, {t.name} at {v:g} km/h, governed by {label}; limit "
               f"{res.limit_m_s2:g} m/s2: {'PASS' if res.passed else 'FAIL'}")
    ge = res.effects_envelope_governing()
    if ge is not None:
        label, t, d = ge
        out.append(f"6.4.6.5(3) over the bounds: largest ratio {d.ratio:.3f} ({d.effect.label}, {t.name}), at {label}: "
                   f"{'Phi x alpha x LM71 governs' if d.ratio <= 1.0 else 'the train governs'}")
    return out


def defaults_lines():
    """The check's defaults that are the project's choice, not the standard's (every default with its
    source: the JSON's ``defaults``, the report, docs/check.md)."""
    from adm_sim.design.check_defaults import project_choices  # noqa: PLC0415  it imports the check

    return ["project's choices (not the standard's; every default with its clause: --json 'defaults', --report):"] + [
        f"  {d.name}: {d.value} ({d.source})" for d in project_choices()]


def summary(res):
    """Every line ``adm-sim check`` prints for ``res``."""
    lines = header_lines(res)
    lines.extend(dict.fromkeys(f"  {c.damping_note}" for c in res.trains))
    lines.extend(train_table_lines(res))
    lines.extend(design_lines(res))
    lines.extend(effects_lines(res))
    lines.extend(comfort_lines(res))
    lines.extend(verdict_lines(res))
    lines.extend(bounds_lines(res))
    lines.extend(r.line(res.limit_m_s2) for r in res.rough)
    if res.sls is not None:
        lines.extend(res.sls.lines())
    lines.append(res.screening)
    lines.extend(defaults_lines())
    lines.append("not checked: " + "; ".join(res.not_checked()))
    return "\n".join(lines)
