"""--scheduler: the model runs of a command on a Dask cluster (the runs-per-posterior issue's
scale-out), against a LocalCluster started here: the same numbers as local processes, the
runs seen on the cluster, a user's model file imported by the workers, a clear error
without a scheduler."""

import json

import pytest

distributed = pytest.importorskip("distributed", reason="dask[distributed] is not installed (a dev extra)")


@pytest.fixture(scope="module")
def duffing_data(tmp_path_factory):
    from test_user_model import make_dataset

    from bayes_update.data.folder import write_dataset

    path = tmp_path_factory.mktemp("duffing")
    write_dataset(make_dataset(seed=31), path)
    return path


@pytest.mark.slow  # about 45 s (a cluster and two calibrations): outside the 15-minute default run
def test_calibrate_on_a_dask_cluster_gives_the_local_numbers(duffing_data, tmp_path):
    from bayes_update.cli import main

    model = "tests/test_user_model.py:three_parameter_duffing"
    args = ["calibrate", "--model", model, "--data", str(duffing_data), "--quick"]
    with (
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        distributed.Client(cluster) as client,
    ):
        with distributed.get_task_stream(client) as stream:
            assert main(args + ["--out", str(tmp_path / "dask"), "--scheduler", cluster.scheduler_address]) == 0
        # the model runs went to the cluster's workers (the file model imported there by its name)
        assert len(stream.data) > 10
        assert {t["worker"] for t in stream.data} <= set(client.scheduler_info()["workers"])
    assert main(args + ["--out", str(tmp_path / "local"), "--workers", "2"]) == 0
    got, ref = (json.loads((tmp_path / k / "calibration.json").read_text()) for k in ("dask", "local"))
    for name in ("fn", "zeta", "k3"):
        assert got[name] == ref[name], name


def test_no_scheduler_there_is_one_line_and_status_2(duffing_data, tmp_path, capsys):
    from bayes_update.cli import main

    rc = main(
        [
            "calibrate",
            "--model",
            "tests/test_user_model.py:three_parameter_duffing",
            "--data",
            str(duffing_data),
            "--quick",
            "--out",
            str(tmp_path / "x"),
            "--scheduler",
            "tcp://127.0.0.1:9",
        ]
    )
    assert rc == 2
    err = capsys.readouterr().err
    assert "--scheduler tcp://127.0.0.1:9: no Dask scheduler answers there" in err
    assert not (tmp_path / "x").exists()
