"""``adm-sim bridges``: the bridges B1-B4 of paper Table 3, or (``--field``) the parametric field as CSV."""

from __future__ import annotations

import sys

from adm_sim.model.bridge import TABLE3, named_bridge, parametric_field


def add_arguments(parser):
    """The options of ``adm-sim bridges``."""
    parser.add_argument("--field", action="store_true", help="the parametric field as CSV (mu in kg/m and t/m)")


def run(args):
    """Describe B1-B4, or print the parametric field (Section 3.3) as CSV with its count on stderr."""
    if args.field:
        field = parametric_field()
        print(f"parametric field: {len(field)} bridges (Section 3.3); mu in kg/m and t/m", file=sys.stderr)
        print("name,span_m,n0_hz,mu_kg_m,mu_t_m,EJ_Nm2,zeta_pct,type")
        for b in field:
            print(f"{b.name},{b.span_m:g},{b.n0_hz:.4f},{b.mass_per_length_kg_m:.1f},{b.mass_per_length_kg_m / 1000:.4f},"
                  f"{b.EJ_Nm2:.5g},{b.damping_ratio * 100:.4g},{b.bridge_type}")
    else:
        for name in TABLE3:
            print(named_bridge(name).describe())
    return 0
