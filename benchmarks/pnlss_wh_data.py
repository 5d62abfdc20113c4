"""Make servoid's shipped copy of the Wiener–Hammerstein benchmark record (SYSID 2009).

Reads the original ``WienerHammerBenchmark.csv`` (path as the argument; its sha256 is
checked against the one in ``src/servoid/datasets/wiener_hammerstein/PROVENANCE.md``) and
writes the benchmark's two parts as compressed MAT files (v5, zlib) into that folder:

* ``wh_estimation.mat`` — samples [5200:105200] of the CSV (the estimation part),
* ``wh_test.mat`` — samples [105200:184000] (the test part),

each with the vectors ``u`` and ``y`` [V] as the CSV's values parsed to float64 (the CSV gives
five significant digits; the parsed values are stored exactly) and the scalar ``fs`` = 51200 Hz.

Usage::

    python benchmarks/pnlss_wh_data.py WienerHammerBenchmark.csv
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np
from scipy.io import savemat

SHA256 = "95f241ac5e0afb48c47b24b3630f55e0d6f8f2f4dec145bd8adf852b19851fa3"
OUT = Path(__file__).resolve().parents[1] / "src" / "servoid" / "datasets" / "wiener_hammerstein"


def main(argv: list[str]) -> int:
    path = Path(argv[0])
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if digest != SHA256:
        print(f"{path} is not the benchmark's file (sha256 {digest})")
        return 1
    data = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(0, 1))
    u, y = data[5200:184000, 0], data[5200:184000, 1]
    for name, part in (("wh_estimation.mat", slice(0, 100_000)),
                       ("wh_test.mat", slice(100_000, None))):
        savemat(OUT / name, {"u": u[part], "y": y[part], "fs": 51200.0},
                do_compression=True, oned_as="column")
        print(name, u[part].size, "samples,", (OUT / name).stat().st_size, "bytes,",
              hashlib.sha256((OUT / name).read_bytes()).hexdigest())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
