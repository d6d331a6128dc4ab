"""results/irregularity/README.md's first finding is the table exceedance.py prints from the shipped
rough-track runs (the rough-track DIM peak against the smooth MLM peak with Δζ = 0, split at 3.5 m/s²),
and the numbers the README's and docs/irregularities.md's prose quote are that table's."""

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "results" / "irregularity" / "README.md"


def _exceedance():
    spec = importlib.util.spec_from_file_location("exceedance", ROOT / "results" / "irregularity" / "exceedance.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_readme_table_is_the_computed_one_and_comes_first():
    mod = _exceedance()
    text = README.read_text()
    got = text.split("<!-- exceedance:begin -->\n")[1].split("<!-- exceedance:end -->")[0]
    assert got == mod.table()
    assert text.index("<!-- exceedance:begin -->") < text.index("## What was run")


def test_quoted_shares_are_the_tables():
    """27 / 36 / 40 % at >= 3.5 m/s² (German low, FRA 6, German high): recounted from the runs here over
    the cases that keep wheel-rail contact (a contact_lost line is counted apart)."""
    mod = _exceedance()
    data = mod.rows()
    share = {}
    for _, label in mod.SPECTRA:
        x = [(m, d) for s, _, m, d, lost, *_ in data if s == label and m >= 3.5 and not lost]
        share[label] = round(100 * sum(d > m for m, d in x) / len(x))
    assert share == {"German low": 27, "FRA class 6": 36, "German high": 40}
    for doc in (README, ROOT / "docs" / "irregularities.md"):
        t = " ".join(doc.read_text().split())
        assert re.search(r"27 %.{0,40}36 %.{0,40}40 %", t), doc
