"""What an ARX ``servoid identify`` loads and reads: modules, start-up time, hashes.

Writes a small ARX record (two CSV files of 3000 samples, a validation
record, a truth file) into a temporary folder and measures, over
``--repeat`` fresh processes:

* **modules**: the ``servoid`` modules the run imports (``python -X
  importtime``), against every module of the source tree;
* **first line**: wall time from the process start to the first line of
  the result on stdout (the progress lines on stderr wait for 2 s of
  quiet, so they are not counted), and the whole run (``servoid identify
  e.toml --out …``, the interpreter's exit included);
* **hashes**: in one process, how many times each input file is hashed
  (SHA-256 of its bytes) during ``identify`` with its results written.

Usage::

    PYTHONPATH=src python benchmarks/startup_identify.py --repeat 5

Prints one table; the numbers depend on the machine and its load (the
module count and the hash count do not).
"""

from __future__ import annotations

import argparse
import collections
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_HASH_PROBE = r"""
import collections, sys
from pathlib import Path
counts = collections.Counter()
watched = {str(Path(p).resolve()) for p in sys.argv[2:]}
# every SHA-256 of a whole file goes through one of these two functions; wrapped before the
# modules that import them by name are loaded
import servoid._lock as lock
import servoid.workflows._common as common
for module, name in ((common, "sha256"), (lock, "sha256_file")):
    def wrapped(path, _fn=getattr(module, name)):
        key = str(Path(path).resolve())
        if key in watched:
            counts[Path(key).name] += 1
        return _fn(path)
    setattr(module, name, wrapped)
from servoid.workflows import identify
identify(sys.argv[1], out=Path(sys.argv[1]).parent / "hash-results", overwrite=True)
print(dict(sorted(counts.items())))
"""


def main() -> int:
    """Make the record, run the measurements, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes (default 5)")
    args = parser.parse_args()
    src = Path(__file__).resolve().parent.parent / "src"
    env = {**os.environ, "PYTHONPATH": f"{src}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
           "OPENBLAS_NUM_THREADS": "1"}
    every = sorted(p for p in (src / "servoid").rglob("*.py"))
    total = len(every)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        toml = _record(folder)
        command = [sys.executable, "-m", "servoid", "identify", str(toml), "--out",
                   str(folder / "results"), "--overwrite"]
        # warm the compiled kernels' cache and the file system once
        subprocess.run(command, env=env, capture_output=True, check=True)
        imported = _modules(command, env)
        firsts, totals = [], []
        for _ in range(args.repeat):
            first, whole = _first_line(command, env)
            firsts.append(first)
            totals.append(whole)
        probe = subprocess.run(
            [sys.executable, "-c", _HASH_PROBE, str(toml),
             *(str(folder / n) for n in ("run0.csv", "run1.csv", "e.toml", "truth.json"))],
            env=env, capture_output=True, text=True, check=True)
        hashes = probe.stdout.strip().splitlines()[-1]
    print(f"servoid modules imported by an ARX identify: {len(imported)} of {total}")
    print(f"time to the first line [s]: median {statistics.median(firsts):.2f} "
          f"(min {min(firsts):.2f}, max {max(firsts):.2f}, {args.repeat} runs)")
    print(f"whole run [s]: median {statistics.median(totals):.2f} "
          f"(min {min(totals):.2f}, max {max(totals):.2f})")
    print(f"SHA-256 of each input file during one run: {hashes}")
    heavy = sorted(m for m in imported if m.split(".")[1:2] and m.split(".")[1] in
                   ("plants", "closedloop", "nonlinear", "fleet", "bench", "signals"))
    print(f"of which in plants/closedloop/nonlinear/fleet/bench/signals: {len(heavy)}")
    for m in heavy:
        print(f"  {m}")
    return 0


def _record(folder: Path) -> Path:
    """Two ARX records with noise, an experiment file validating on the second."""
    import numpy as np
    from scipy.signal import lfilter

    a, b = [1.0, -1.2, 0.5], [0.0, 0.8, 0.3]
    for k, seed in enumerate((7, 8)):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(3000)
        y = lfilter(b, a, u) + lfilter([1.0], a, 0.02 * rng.standard_normal(3000))
        t = np.arange(3000) * 0.01
        np.savetxt(folder / f"run{k}.csv", np.column_stack([t, u, y]), delimiter=",",
                   header="t,u,y", comments="")
    (folder / "truth.json").write_text('{"seed": 7}\n', encoding="utf-8")
    toml = folder / "e.toml"
    toml.write_text(
        '[data]\nfile = "run0.csv"\ntime = "t"\n\n'
        '[channels.u]\nsource = "u"\nrole = "u"\nunit = "V"\n\n'
        '[channels.y]\nsource = "y"\nrole = "y"\nunit = "mm"\n\n'
        '[validation]\nfile = "run1.csv"\n\n'
        '[identify]\nmethod = "arx"\nna = 2\nnb = 2\nnk = 1\n\n'
        '[report]\ntruth = "truth.json"\n', encoding="utf-8")
    return toml


def _modules(command: list[str], env: dict[str, str]) -> list[str]:
    """The servoid modules a run imports (``-X importtime`` on stderr)."""
    run = subprocess.run([command[0], "-X", "importtime", *command[1:]], env=env,
                         capture_output=True, text=True, check=True)
    names = collections.OrderedDict()
    for line in run.stderr.splitlines():
        if line.startswith("import time:") and "|" in line:
            name = line.rsplit("|", 1)[1].strip()
            if name == "servoid" or name.startswith("servoid."):
                names[name] = None
    return list(names)


def _first_line(command: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Seconds to the first line on stdout, and to the process's end."""
    start = time.monotonic()
    proc = subprocess.Popen(command, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL)
    assert proc.stdout is not None
    proc.stdout.readline()
    first = time.monotonic() - start
    proc.stdout.read()
    proc.wait()
    return first, time.monotonic() - start


if __name__ == "__main__":
    raise SystemExit(main())
