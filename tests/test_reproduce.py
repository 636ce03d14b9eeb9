"""`bayes-update reproduce --quick` end to end (ROM, coarse grids, small posterior)."""
import json

import pytest

from bayes_update.cli import main


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    assert main(["reproduce", "--quick", "--no-discrepancy", "--out", str(out), "--workers", "2"]) == 0
    return out


def test_report_has_every_table_and_figure(report):
    text = (report / "report.md").read_text()
    for heading in ("Deterministic updating, bending_stiffness_factor 1.24", "factor 1 (locking-free",
                    "The two models side by side", "Posterior, factor 1.24", "Posterior, factor 1", "Wall time"):
        assert heading in text, heading
    for line in text.splitlines():
        if line.startswith("!["):
            assert (report / line.split("(")[1].rstrip(")")).exists(), line
    assert "Table 1" in text and "Table 2" in text and "Table 3" in text
    assert (report / "f1_against_preload.png").exists()


def test_headline_preloads_of_the_two_models(report):
    head = json.loads((report / "reproduce.json").read_text())
    p_stiff = head["posterior_factor_1.24"]["P_eff"]["mean"]
    p_free = head["posterior_factor_1"]["P_eff"]["mean"]
    assert p_stiff == pytest.approx(74.06, rel=0.01)       # the paper's 74 N
    assert 40.0 < p_free < 46.0                             # a locking-free beam: ~43 N for 37 Hz
