"""`bayes-update reproduce --quick` end to end (ROM, coarse grids, small posterior)."""

import json
import re

import pytest

from bayes_update.cli import main
from bayes_update.models.beam.virtual_rig import load_default_dataset, truth_paper_units

PNG = b"\x89PNG\r\n\x1a\n"
POSTERIOR_HEADER = "| parameter | mean | sd | 94 % HDI | R-hat | bulk ESS | tail ESS |"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    assert main(["reproduce", "--quick", "--no-discrepancy", "--out", str(out), "--workers", "2"]) == 0
    return out


def _section(text, heading):
    start = text.index(heading)
    nxt = text.find("\n## ", start + 1)
    return text[start:] if nxt < 0 else text[start:nxt]


def test_report_has_every_table_and_figure(report):
    text = (report / "report.md").read_text()
    head = json.loads((report / "reproduce.json").read_text())
    for heading in (
        "Deterministic updating, bending_stiffness_factor 1.24",
        "factor 1 (locking-free",
        "The two models side by side",
        "Posterior, factor 1.24",
        "Posterior, factor 1",
        "Wall time",
    ):
        assert heading in text, heading
    # every linked figure is a PNG image, and each section shows its figures
    figures = re.findall(r"^!\[[^\]]*\]\(([^)]+)\)", text, flags=re.M)
    for path in figures:
        f = report / path
        assert f.read_bytes()[:8] == PNG and f.stat().st_size > 10_000, path
    assert "f1_against_preload.png" in figures
    for tag in ("factor_1.24", "factor_1"):
        assert f"posterior_{tag}/corner.png" in figures and f"calibrate_{tag}/fig8_e_lin_eta.png" in figures, tag
    # the paper's Tables 1-3, for both models
    for heading in (
        "Deterministic updating, bending_stiffness_factor 1.24",
        "Deterministic updating, bending_stiffness_factor 1 ",
    ):
        sec = _section(text, heading)
        for table in ("Table 1", "Table 2", "Table 3"):
            assert table in sec, (heading, table)
    # the side-by-side table: one row per model, P_eff as calibrate found it
    sec = _section(text, "The two models side by side")
    for f in ("1.24", "1"):
        row = next(line for line in sec.splitlines() if line.startswith(f"| factor {f} |"))
        assert f"**{head[f'calibrate_factor_{f}']['P_eff_N']:.2f}**" in row, row
    # each posterior section: the summary table with its five parameters, the numbers of reproduce.json
    for f in ("1.24", "1"):
        sec = _section(text, f"## Posterior, factor {f}\n")
        assert POSTERIOR_HEADER in sec, f
        post = head[f"posterior_factor_{f}"]
        for name in ("eta", "c", "F", "k_s", "P_eff"):
            row = next(line for line in sec.splitlines() if line.startswith(f"| {name} ["))
            cells = [c.strip() for c in row.split("|")[1:-1]]
            # each printed to the digits its sd supports: off by at most half a unit of its last
            # significant digit (an integer's trailing zeros are not significant: 160 is 16 tens)
            for cell, value in ((cells[1], post[name]["mean"]), (cells[2], post[name]["sd"])):
                places = (
                    len(cell.split(".")[1])
                    if "." in cell
                    else -(len(cell) - len(cell.rstrip("0")))
                    if cell.strip("-0")
                    else 0
                )
                assert abs(float(cell) - value) <= 0.5 * 10.0**-places * (1 + 1e-9), (f, name, row)
            assert len(cells[2].replace(".", "").lstrip("0")) >= 2, (f, name, row)  # sd: 2 digits at least


def test_headline_preloads_of_the_two_models(report):
    head = json.loads((report / "reproduce.json").read_text())
    truth = truth_paper_units(load_default_dataset())  # the data set's truth block: 74.063 N
    p_stiff = head["posterior_factor_1.24"]["P_eff"]
    # in posterior sds (1 % of P_eff would be about 190 of them): measured 74.0596 +- 0.0039 N, 0.90 sd
    # from the truth; 3 sd leaves 3.3x that
    assert abs(p_stiff["mean"] - truth["P_eff"]) <= 3.0 * p_stiff["sd"], (p_stiff, truth["P_eff"])
    assert p_stiff["hdi"][0] <= truth["P_eff"] <= p_stiff["hdi"][1]
    p_free = head["posterior_factor_1"]["P_eff"]["mean"]
    assert 40.0 < p_free < 46.0  # a locking-free beam: ~43 N for 37 Hz
