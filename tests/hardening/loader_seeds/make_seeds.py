"""Write the seed documents of the loader fuzzers (``loader_inputs.py``).

Run from the repository root (about two minutes)::

    PYTHONPATH=src python tests/hardening/loader_seeds/make_seeds.py

It runs ``servoid identify`` once per method family on small records and
keeps what a user would hand to the loaders:

- ``results/<run>.json`` and ``results/<run>.manifest.json``: a run's
  ``results.json`` and ``manifest.json``;
- ``models/<name>.json``: model files written by ``servoid.save_model``
  (every model the runs fitted, an Estimate with its covariance, and
  hand-made models of the kinds no run writes: discretised transfer
  functions and state space, each static block shape);
- ``tanks.py``: the grey-box run's Python model (its SHA-256 is in the
  grey-box seeds, which name the Python integrator: ``"compiled": false``).

Absolute paths of the run folders are replaced by ``@RUN@`` (the folder
holding the experiment files) and ``@CODE@`` (the folder of ``tanks.py``);
the fuzzers put their scratch folder there.  JSON is written compact, one
document per file.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import scipy.signal as sps

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
EXAMPLES = ROOT / "examples"

LINEAR_TOML = """[data]
file = "data.csv"
time = "time"

[channels.u]
role = "u"
unit = "V"

[channels.y]
role = "y"
unit = "m"

[identify]
method = "{method}"
{extra}"""

LINEAR = {"arx": "na = 2\nnb = 2\nnk = 1\n", "oe": "nb = 2\nnf = 2\nnk = 1\n", "armax": "",
          "bj": "", "tf": "", "n4sid": "", "frf": "",
          "narx": "na = 2\nnb = 2\ndegree = 2\n"}


def main() -> None:
    warnings.simplefilter("ignore")
    from servoid.cli import main as cli
    from servoid.workflows import identify

    for sub in ("results", "models"):
        shutil.rmtree(HERE / sub, ignore_errors=True)
        (HERE / sub).mkdir()
    shutil.copy(EXAMPLES / "greybox" / "tanks.py", HERE / "tanks.py")
    with tempfile.TemporaryDirectory(prefix="servoid-seeds-") as name:
        tmp = Path(name)
        runs: dict[str, tuple[Path, Path]] = {}  # run name → (results folder, @RUN@)
        lin = tmp / "lin"
        lin.mkdir()
        (lin / "data.csv").write_text(_linear_csv(), encoding="utf-8")
        for method, extra in LINEAR.items():
            (lin / f"{method}.toml").write_text(LINEAR_TOML.format(method=method, extra=extra),
                                                encoding="utf-8")
            identify(lin / f"{method}.toml", tmp / method)
            runs[method] = (tmp / method, lin)
        blocks = tmp / "blocks"
        shutil.copytree(EXAMPLES / "blocks", blocks)
        subprocess.run([sys.executable, "make_data.py"], cwd=blocks, check=True,
                       capture_output=True)
        identify(blocks / "blocks.toml", tmp / "hammerstein")
        runs["hammerstein"] = (tmp / "hammerstein", blocks)
        grey = tmp / "greybox"
        grey.mkdir()
        for file in ("tanks.toml", "tanks.csv", "tanks_validation.csv"):
            shutil.copy(EXAMPLES / "greybox" / file, grey / file)
        shutil.copy(HERE / "tanks.py", grey / "tanks.py")
        toml = grey / "tanks.toml"  # one start: the seeds need a fit, not the best one
        toml.write_text(toml.read_text(encoding="utf-8").replace("multistart = 4", "multistart = 0"),
                        encoding="utf-8")
        identify(toml, tmp / "greybox-run", allow_code=True)
        runs["greybox"] = (tmp / "greybox-run", grey)
        bench = tmp / "ehsa"
        assert cli(["bench", "ehsa", "--out", str(bench), "-n", "7", "--clock", "4"]) == 0
        identify(bench / "ehsa.toml", tmp / "closedloop")
        runs["closedloop"] = (tmp / "closedloop", bench)
        for run, (folder, source) in runs.items():
            for name, target in (("results.json", f"{run}.json"),
                                 ("manifest.json", f"{run}.manifest.json")):
                _write(HERE / "results" / target,
                       _placeholders((folder / name).read_text(encoding="utf-8"), source, grey))
        _models(runs, grey, tmp)


def _linear_csv() -> str:
    rng = np.random.default_rng(1)
    n = 300
    u = np.repeat(rng.choice([-1.0, 1.0], n // 5 + 1), 5)[:n]
    y = sps.lfilter([0.0, 0.5, 0.2], [1.0, -1.2, 0.5], u) + 0.01 * rng.standard_normal(n)
    rows = (f"{0.01 * k!r},{float(a)!r},{float(b)!r}" for k, (a, b) in enumerate(zip(u, y)))
    return "time [s],u [V],y [m]\n" + "\n".join(rows) + "\n"


def _placeholders(text: str, run: Path, code: Path) -> str:
    # the grey-box seeds name the Python integrator: the fuzzers read them thousands of times,
    # and numba would compile the model once per process (seconds)
    text = text.replace('"compiled": true', '"compiled": false')
    return text.replace(str(code), "@CODE@").replace(str(run), "@RUN@")


def _write(path: Path, text: str) -> None:
    path.write_text(json.dumps(json.loads(text), separators=(",", ":")) + "\n", encoding="utf-8")


def _models(runs: dict[str, tuple[Path, Path]], grey: Path, tmp: Path) -> None:
    import servoid
    from servoid.data import Experiment
    from servoid.estimate import fit_arx
    from servoid.models import PolynomialModel, StateSpace, TransferFunction, c2d, save_model
    from servoid.nonlinear import (
        AbsoluteValue,
        BlockModel,
        DeadZone,
        PiecewiseLinear,
        Polynomial,
        Saturation,
        SignedPower,
    )

    models: dict[str, object] = {}
    for run, (folder, _) in runs.items():
        loaded = servoid.load_results(folder / "results.json", allow_code=True)
        for name, model in loaded.models.items():
            models[f"{run}-{name}"] = model
    tf = TransferFunction([2.0, 1.0], [0.1, 1.2, 1.0], delay=0.01)
    models["tf-continuous"] = tf
    models["tf-tustin"] = c2d(TransferFunction([2.0, 1.0], [0.1, 1.2, 1.0]), 0.01, method="tustin", prewarp=20.0)
    models["ss-zoh"] = c2d(StateSpace([[-1.0, 0.5], [0.0, -2.0]], [[1.0], [0.5]], [[1.0, 0.0]],
                                  [[0.0]]), 0.01)
    models["poly-two-inputs"] = PolynomialModel(
        [1.0, -0.5], ([0.3, 0.1], [0.2]), (1, 2), 0.01, c=[1.0, 0.4], d=[1.0, -0.2],
        f=([1.0, -0.7], [1.0, 0.1]), noise_variance=1e-4, input_names=("u1", "u2"),
        output_name="y")
    linear = PolynomialModel([1.0], ([0.5, 0.3],), (1,), 0.01, f=([1.0, -1.2, 0.5],))
    shapes = {"deadzone": DeadZone(-0.4, 0.6), "saturation": Saturation(-1.0, 1.0),
              "pwl": PiecewiseLinear((-1.0, 0.0, 1.0), (0.5, 1.0, 2.0, 0.5)),
              "poly": Polynomial((0.0, 1.0, 0.2)), "power": SignedPower(1.5),
              "abs": AbsoluteValue(0.1)}
    for kind, shape in shapes.items():
        models[f"block-wiener-{kind}"] = BlockModel("wiener", linear, 0.01,
                                                    output_nonlinearity=shape)
    models["block-hw"] = BlockModel("hammerstein-wiener", tf, 0.01,
                                    input_nonlinearity=shapes["deadzone"],
                                    output_nonlinearity=shapes["saturation"], offset=0.2)
    for name, model in models.items():
        path = save_model(model, tmp / f"{name}.json", overwrite=True,
                          units={"u": "V", "y": "m"} if name.startswith("tf-") else None)
        _write(HERE / "models" / f"{name}.json",
               _placeholders(path.read_text(encoding="utf-8"), grey, grey))
    rng = np.random.default_rng(3)
    u = rng.standard_normal(200)
    exp = Experiment.from_arrays(0.01, u=u, y=sps.lfilter([0.0, 0.5], [1.0, -0.8], u)
                                 + 0.01 * rng.standard_normal(200))
    path = save_model(fit_arx(exp, 1, 1), tmp / "estimate.json", overwrite=True)
    _write(HERE / "models" / "arx-estimate.json", path.read_text(encoding="utf-8"))


if __name__ == "__main__":
    main()
