"""The command line's shared behaviour: --version, required --out, --config,
the log (no progress bar in a file), and a failed command leaving no OUT."""

import subprocess
import sys

import pytest

from bayes_update.cli import main


def test_version_and_required_out(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    from bayes_update import __version__

    assert capsys.readouterr().out.strip() == f"bayes-update {__version__}"
    with pytest.raises(SystemExit) as exc:  # make-dataset never writes into the installed package
        main(["make-dataset"])
    assert exc.value.code == 2
    assert "--out" in capsys.readouterr().err


def test_config_file_is_read_and_checked(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[sample]\nn_walkerz = 48\n")
    assert main(["sample", "--quick", "--model", "rom", "--config", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "n_walkerz" in capsys.readouterr().err
    bad.write_text("[sampel]\nn_walkers = 48\n")
    assert main(["sample", "--quick", "--model", "rom", "--config", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "sampel" in capsys.readouterr().err
    from bayes_update.cli.options import read_config, settings_from
    from bayes_update.core.posterior import PosteriorSettings

    good = tmp_path / "good.toml"
    good.write_text("[sample]\nn_walkers = 48\nn_steps = 5000\n")
    s = settings_from(PosteriorSettings, True, read_config(good, "sample"), n_steps=4000, seed=None)
    assert (s.n_walkers, s.n_steps, s.seed) == (48, 4000, 0)  # the command line wins over the file


def test_a_failed_command_leaves_no_out_folder(tmp_path):
    out = tmp_path / "never"
    assert main(["sample", "--quick", "--model", "rom", "--prior", "G=1:2", "--out", str(out)]) == 2
    assert not out.exists()


def test_calibrate_logs_to_a_file_without_progress_bars(tmp_path):
    """stderr to a file (not a terminal): the log's lines, no carriage returns, no bars."""
    out, err = tmp_path / "cal", tmp_path / "stderr.txt"
    with open(err, "w") as fh:
        res = subprocess.run(
            [
                sys.executable,
                "-m",
                "bayes_update",
                "calibrate",
                "--quick",
                "--model",
                "rom",
                "--workers",
                "1",
                "--out",
                str(out),
                "--log-file",
                str(tmp_path / "log.txt"),
            ],
            stdout=subprocess.PIPE,
            stderr=fh,
            text=True,
            timeout=600,
        )
    text = err.read_text()
    assert res.returncode == 0, text[-2000:]
    assert "\r" not in text and "it/s" not in text and "run/s" not in text, text[-2000:]
    assert "Kautz pole" in text  # the log's lines are there
    assert "Kautz pole" in (tmp_path / "log.txt").read_text()
    quiet = subprocess.run(
        [
            sys.executable,
            "-m",
            "bayes_update",
            "calibrate",
            "--quick",
            "--model",
            "rom",
            "--workers",
            "1",
            "--quiet",
            "--out",
            str(tmp_path / "cal2"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert quiet.returncode == 0 and "Kautz pole" not in quiet.stderr


def test_reproduce_takes_the_config_files_tables(tmp_path, monkeypatch):
    """reproduce used to accept --config and ignore it: its tables now change the study's
    own settings (the rest kept: the report's opt-in diagnostics), and a wrong key is named."""
    import bayes_update.reports.beam_study as study
    from bayes_update.cli import main

    seen = {}
    monkeypatch.setattr(study, "reproduce", lambda out, **kw: seen.update(kw) or {})
    cfg = tmp_path / "s.toml"
    cfg.write_text("[sample]\nn_walkers = 48\nn_steps = 3000\n[discrepancy]\nmax_effects = 1\n")
    assert main(["reproduce", "--out", str(tmp_path / "o"), "--config", str(cfg)]) == 0
    post, disc = seen["settings"]["sample"], seen["settings"]["discrepancy"]
    assert (post.n_walkers, post.n_steps, post.n_predictive, post.n_global) == (48, 3000, 32, 128)
    assert disc.max_effects == 1 and "calibrate" not in seen["settings"]
    cfg.write_text("[sample]\nn_walker = 48\n")
    assert main(["reproduce", "--out", str(tmp_path / "o"), "--config", str(cfg)]) != 0


def test_reproduce_hands_each_table_to_its_own_step(tmp_path, monkeypatch):
    """The study's own wiring (the CLI test above stops at its arguments): a loop variable
    once shadowed the settings dict and the discrepancy step failed after the posteriors.
    The steps are stubbed; each must receive the settings object given for it."""
    import types

    import bayes_update.core.discrepancy as disc_module
    import bayes_update.reports.beam_study as study
    from bayes_update.core.discrepancy import DiscrepancySettings
    from bayes_update.core.posterior import PosteriorSettings
    from bayes_update.models.beam.calibrate import CalibrationSettings

    given = {
        "calibrate": CalibrationSettings.quick(),
        "sample": PosteriorSettings.quick(n_linear=0),
        "discrepancy": DiscrepancySettings.quick(max_effects=1),
    }
    seen = {"calibrate": [], "sample": []}

    class Reached(Exception):
        pass

    def fake_find(data, model, settings, workers, log):
        seen["discrepancy"] = settings
        raise Reached

    monkeypatch.setattr(
        study, "calibrate", lambda d, m, s, **kw: seen["calibrate"].append(s) or types.SimpleNamespace(final_theta=None)
    )
    monkeypatch.setattr(study, "sample", lambda d, m, s, **kw: seen["sample"].append(s))
    monkeypatch.setattr(study, "write_result", lambda *a, **kw: None)
    monkeypatch.setattr(study, "write_posterior", lambda *a, **kw: None)
    monkeypatch.setattr(study, "discrepancy_dataset", lambda: study.load_default_dataset())
    monkeypatch.setattr(disc_module, "find_discrepancy", fake_find)
    with pytest.raises(Reached):
        study.reproduce(tmp_path, quick=True, settings=given, log=lambda *a: None)
    # the stated factor takes the given table; the locking-free comparison keeps its coarse grids
    assert seen["calibrate"][0] is given["calibrate"] and len(seen["calibrate"]) == 2
    assert seen["sample"] == [given["sample"]] * 2
    assert seen["discrepancy"] is given["discrepancy"]
