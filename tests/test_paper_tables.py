"""Table-diff tests against the committed results of the full run.

They read the regenerated tables and the paper's values (workflow/paper_values.yaml) and check
each declared tolerance and claim, printing a readable side-by-side diff when one fails.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from crgpr.report.paper import FAILS, HOLDS, MATCH, OUTSIDE, build, build_sweep_claims, in_band, load_values

ROOT = Path(__file__).resolve().parents[1]
RES = ROOT / "results"
TABLES = RES / "tables"
VALUES = ROOT / "workflow" / "paper_values.yaml"

COMMITTED = TABLES / "paper_vs_reproduction.csv"
pytestmark = pytest.mark.skipif(not COMMITTED.exists(), reason="no committed full-run results")


def side_by_side(df: pd.DataFrame) -> str:
    cols = ["id", "paper", "ours", "rel_diff", "tolerance", "verdict", "known_deviation"]
    return "\n" + df[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}")


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    return pd.read_csv(COMMITTED, keep_default_na=False, na_values=[""])


def test_every_quantity_was_produced(table):
    missing = table[table["verdict"] == "missing"]
    assert missing.empty, "quantities not produced by the full run:" + side_by_side(missing)


def test_every_quantity_in_band_or_documented(table):
    """A number outside its band must carry the documented reason (known_deviation)."""
    bad = table[(table["verdict"] == OUTSIDE) & (table["known_deviation"].fillna("") == "")]
    assert bad.empty, "outside the tolerance band without a documented reason:" + side_by_side(bad)


def test_documented_deviations_are_still_deviations(table):
    """A known_deviation on a number that now matches is stale documentation."""
    stale = table[(table["verdict"] == MATCH) & (table["known_deviation"].fillna("") != "")]
    assert stale.empty, "known_deviation set but the value is inside the band:" + side_by_side(stale)


def test_verdicts_follow_from_values_and_bands(table):
    """Recompute each verdict from paper, ours and the declared band (guards hand edits)."""
    vals = {q["id"]: q for q in load_values(VALUES)["quantities"]}
    wrong = []
    for r in table.itertuples():
        q = vals[r.id]
        assert r.paper == pytest.approx(q["paper"]), r.id
        expected = MATCH if in_band(q["paper"], r.ours, q["tolerance"]) else OUTSIDE
        if not math.isnan(r.ours) and expected != r.verdict:
            wrong.append(r.id)
    assert not wrong, f"verdicts inconsistent with the bands: {wrong}" + side_by_side(
        table[table["id"].isin(wrong)])


def test_claims_are_evaluated(table):
    claims = pd.read_csv(TABLES / "paper_claims.csv")
    assert set(claims["verdict"]) <= {HOLDS, FAILS}, "claims left unevaluated:\n" + claims[
        ["id", "verdict"]].to_string(index=False)


def test_committed_tables_are_regenerated_by_current_code(tmp_path):
    """Rerunning paper_tables on the committed metrics reproduces the tables byte for byte."""
    outs = {k: tmp_path / n for k, n in [("csv", "paper_vs_reproduction.csv"),
                                         ("md", "paper_vs_reproduction.md"),
                                         ("claims", "paper_claims.csv")]}
    build(str(VALUES), str(RES / "metrics" / "accuracy.parquet"),
          str(TABLES / "table2_hyperparameters.csv"), str(RES / "metrics" / "timing.parquet"),
          str(TABLES / "uq_coverage.csv"), str(outs["csv"]), str(outs["md"]), str(outs["claims"]))
    for path in outs.values():
        committed = (TABLES / path.name).read_bytes()
        assert path.read_bytes() == committed, f"{path.name} differs from the committed table"


def test_noise_claims_belong_to_the_sweeps_target(tmp_path):
    """Without noise_ablation.csv (rule paper_tables in `all`) the noise claims are left out and
    named in the markdown; with it (after `snakemake sweeps`) they are evaluated."""
    noise_ids = {c["id"] for c in load_values(VALUES)["claims"] if "noise:" in c["check"]}
    assert noise_ids
    out = [str(tmp_path / n) for n in ("q.csv", "q.md", "c.csv")]
    _, ct = build(str(VALUES), None, None, None, None, *out)
    assert noise_ids.isdisjoint(ct["id"])
    assert all(i in Path(out[1]).read_text() for i in noise_ids)
    rows = [{"noise_mm": n, "prefilter": p, "features": f, "rmse_theta_mean_finite": 0.1 + n * (p == "fd")}
            for n in (0.0, 2.0) for p in ("gp", "fd") for f in ("objective", "paper")]
    pd.DataFrame(rows).to_csv(tmp_path / "noise.csv", index=False)
    _, ct = build(str(VALUES), None, None, None, None, *out, noise=str(tmp_path / "noise.csv"))
    verdicts = ct.set_index("id")["verdict"]
    assert noise_ids <= set(verdicts.index) and set(verdicts[list(noise_ids)]) == {HOLDS}
    # rule paper_claims_sweeps: exactly the noise claims, the same verdicts
    sw = build_sweep_claims(str(VALUES), str(tmp_path / "noise.csv"), str(tmp_path / "s.csv"))
    assert set(sw["id"]) == noise_ids and set(sw["verdict"]) == {HOLDS}
    assert pd.read_csv(tmp_path / "s.csv")["id"].tolist() == sw["id"].tolist()
    # FD no worse than the GP prefilter at 2 mm: the claims do not hold
    rows = [dict(r, rmse_theta_mean_finite=0.1) for r in rows]
    pd.DataFrame(rows).to_csv(tmp_path / "noise.csv", index=False)
    sw = build_sweep_claims(str(VALUES), str(tmp_path / "noise.csv"), str(tmp_path / "s.csv"))
    assert set(sw["verdict"]) == {FAILS}
