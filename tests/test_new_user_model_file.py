"""A model file that imports a module beside it and caches its numba code (``cache=True``).

Loaded by ``--model path/to/file.py:NAME`` (:func:`bayes_update.load_model`) in fresh
processes, with and without the folder on PYTHONPATH, twice each (the second run reads
numba's cache, which ``NUMBA_CACHE_DIR`` puts in a temporary folder), run in a worker
process started by *spawn*, and then imported by the user's own script under its own name
from the same cache.
"""

import json
import os
import subprocess
import sys
import textwrap

import pytest

KERNEL = '''
import numpy as np
from numba import njit


@njit(cache=True)
def hop(f, dt, wn, zeta, k3):
    """Semi-implicit Euler of x'' + 2 zeta wn x' + wn^2 x + k3 x^3 = f; displacement out."""
    x, v = 0.0, 0.0
    out = np.empty(f.size)
    for i in range(f.size):
        v += dt * (f[i] - 2 * zeta * wn * v - wn * wn * x - k3 * x ** 3)
        x += dt * v
        out[i] = x
    return out
'''

MODEL = """
import numpy as np
from numba import njit

from bayes_update import Parameter
from pogo_kernel import hop


@njit(cache=True)
def _gain(y, g):
    return g * y


class Pogo:
    parameters = [Parameter("fn", 11.0, 19.0, unit="Hz"), Parameter("zeta", 0.01, 0.2, log=True)]

    def simulate(self, theta, force, fs):
        y = hop(np.asarray(force, float), 1.0 / fs, 2 * np.pi * theta["fn"], theta["zeta"], 0.0)
        return _gain(y, 3.0)
"""

# what --model does: load, check, and a run (in a worker process started by spawn, or here)
TOOL = """
import json, multiprocessing, sys
from concurrent.futures import ProcessPoolExecutor
import numpy as np
from bayes_update import check_model, load_model

model = load_model(sys.argv[1])
force = np.sin(np.arange(600) * 0.11)
check_model(model, force, 250.0)
if sys.argv[2] == "spawn":
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        y = pool.submit(model.simulate, {"fn": 14.2, "zeta": 0.05}, force, 250.0).result()
else:
    y = model.simulate({"fn": 14.2, "zeta": 0.05}, force, 250.0)
mod = sys.modules[type(model).__module__]
print(json.dumps({"module": type(model).__module__, "hits": sum(mod._gain.stats.cache_hits.values()),
                  "y": float(np.abs(y).sum())}))
"""

# the user's own script, importing the file by its name, from the same numba cache
USER = """
import json
import numpy as np
import pogo
y = pogo.Pogo().simulate({"fn": 14.2, "zeta": 0.05}, np.sin(np.arange(600) * 0.11), 250.0)
print(json.dumps({"hits": sum(pogo._gain.stats.cache_hits.values()), "y": float(np.abs(y).sum())}))
"""


def _run(code, cwd, env, *args):
    res = subprocess.run(
        [sys.executable, "-c", code, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("pythonpath", [False, True])
def test_a_model_file_imports_its_neighbour_and_reloads_its_numba_cache(tmp_path, pythonpath):
    project = tmp_path / "project"
    project.mkdir()
    (project / "pogo_kernel.py").write_text(textwrap.dedent(KERNEL))
    (project / "pogo.py").write_text(textwrap.dedent(MODEL))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba_cache")
    env["PYTHONPATH"] = os.pathsep.join([repo] + ([str(project)] if pythonpath else []))
    spec = f"{project / 'pogo.py'}:Pogo"
    first = _run(TOOL, elsewhere, env, spec, "spawn")
    second = _run(TOOL, elsewhere, env, spec, "here")
    # loaded under its own name (importable: the spawned worker imported it), and the second
    # process read the compiled code the first one cached
    assert first["module"] == second["module"] == "pogo", first
    assert first["hits"] == 0 and second["hits"] > 0, (first, second)
    assert first["y"] == pytest.approx(second["y"], rel=1e-12)
    # the user's own script imports the same file by its name and reads the same cache
    env["PYTHONPATH"] = os.pathsep.join([repo, str(project)])
    mine = _run(USER, elsewhere, env)
    assert mine["hits"] > 0 and mine["y"] == pytest.approx(first["y"], rel=1e-12)


def test_a_model_file_whose_name_is_taken_loads_under_another_and_keeps_numba_cache_apart(tmp_path):
    """A file named like a module already imported (here ``json.py``) loads under a synthetic
    name; its numba functions then cache apart from the user's cache folder, so that the
    user's own ``import`` of a file of that name never reads entries it cannot rebuild."""
    project = tmp_path / "project"
    project.mkdir()
    (project / "pogo_kernel.py").write_text(textwrap.dedent(KERNEL))
    (project / "json.py").write_text(textwrap.dedent(MODEL))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba_cache")
    env["PYTHONPATH"] = repo
    env["TMPDIR"] = str(tmp_path / "tmp")  # where the synthetic name's own cache goes
    (tmp_path / "tmp").mkdir()
    code = textwrap.dedent("""
        import json, sys
        import numpy as np
        from bayes_update import check_model, load_model
        model = load_model(sys.argv[1])
        check_model(model, np.sin(np.arange(600) * 0.11), 250.0)
        print(json.dumps({"module": type(model).__module__}))
    """)
    out = _run(code, tmp_path, env, f"{project / 'json.py'}:Pogo")
    assert out["module"] != "json" and out["module"].startswith("_bayes_update_user_model_"), out
    # nothing of the synthetic module went to the user's cache folder
    cached = [p.name for p in (tmp_path / "numba_cache").rglob("*.nbi")] if (tmp_path / "numba_cache").exists() else []
    assert not [n for n in cached if n.startswith("json.")], cached
    apart = [p.name for p in (tmp_path / "tmp" / "bayes_update_numba_cache").rglob("*.nbi")]
    assert any(n.startswith("json._gain") for n in apart), apart
