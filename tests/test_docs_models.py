"""docs/models.md's example runs as written: its model against a closed form, and the model through
`sample` (small settings) on synthetic data.  (The command line with a model from a file:
tests/test_user_model.py.)"""

import re
import sys
import types
from pathlib import Path

import numpy as np

DOC = Path(__file__).resolve().parents[1] / "docs" / "models.md"


def _blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(), flags=re.S)


def _module(code, name="docs_models_example"):
    """Run ``code`` as a module of its own (so that its classes pickle for the worker processes)."""
    module = types.ModuleType(name)
    sys.modules[name] = module
    exec(code, module.__dict__)
    return module


def test_the_example_model_is_right():
    """Against the closed form of its linear limit (k3 = 0): the steady-state velocity at resonance
    is F / (2 zeta wn m) cos(wn t) for a force F cos(wn t), times sinc^2(f / fs): the model sees the
    samples of the force joined by straight lines (docs/models.md, "What the samples of the force
    mean"); measured 5.5e-8 with it (RK4 at 160 steps per period), 2.05e-3 without it at 40
    samples per period; tolerance 1e-6."""
    duffing = _module(_blocks("python")[0]).Duffing
    fs, fn, zeta, m = 2000.0, 50.0, 0.05, 0.1
    t = np.arange(int(3 * fs)) / fs
    w = 2 * np.pi * fn
    v = duffing().simulate({"fn": fn, "zeta": zeta, "k3": 0.0}, np.cos(w * t), fs)
    last = t >= 2.0
    a, b = np.linalg.lstsq(np.column_stack([np.cos(w * t[last]), np.sin(w * t[last])]), v[last], rcond=None)[0]
    expected = np.sinc(fn / fs) ** 2 / (2 * zeta * w * m)
    assert abs(np.hypot(a, b) / expected - 1) < 1e-6


def test_the_example_runs(tmp_path):
    from test_user_model import make_dataset

    from bayes_update.data.folder import write_dataset

    model_code, use_code = _blocks("python")[:2]
    write_dataset(make_dataset(seed=5, truth={"gain": 1.0, "k2": 0.0}), tmp_path / "my_test")
    use_code = use_code.replace('"my_test/"', repr(str(tmp_path / "my_test")))
    use_code = use_code.replace('"my_test_posterior/"', repr(str(tmp_path / "posterior")))
    use_code = use_code.replace("PosteriorSettings()", "PosteriorSettings.quick(n_linear=0, n_global=0)")
    summary = _module(model_code + "\n" + use_code, "docs_models_use").result.summary
    for name, value in {"fn": 41.3, "zeta": 0.021, "k3": 4.2}.items():
        assert summary[name]["hdi_3%"] <= value <= summary[name]["hdi_97%"], (name, summary[name])
    assert (tmp_path / "posterior" / "posterior_summary.json").is_file()
