"""Small ARX fleets for the input and cluster tests: each record identifies in milliseconds."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

EXPERIMENT = """\
[data]
file = "data.csv"
time = "time"

[channels.u]
role = "u"
unit = "V"

[channels.y]
role = "y"
unit = "m"

[identify]
method = "arx"
na = 1
nb = 1
nk = 1
"""


def write_record(folder: Path, seed: int, n: int = 200) -> Path:
    """A first-order plant under a random binary input, noise 0.01; returns its experiment file."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-1.0, 1.0], n // 5 + 1), 5)[:n]
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.8 * y[k - 1] + 0.5 * u[k - 1]
    y += 0.01 * rng.standard_normal(n)
    folder.mkdir(parents=True, exist_ok=True)
    rows = "\n".join(f"{0.01 * k!r},{float(u[k])!r},{float(y[k])!r}" for k in range(n))
    (folder / "data.csv").write_text("time [s],u [V],y [m]\n" + rows + "\n", encoding="utf-8")
    (folder / "exp.toml").write_text(EXPERIMENT, encoding="utf-8")
    return folder / "exp.toml"


def write_fleet(root: Path, serials: list[str], extra: str = "") -> Path:
    """Records ``units/<serial>/exp.toml``, a manifest ``units.csv`` and ``fleet.toml``."""
    rows = [["path", "serial"]]
    for k, serial in enumerate(serials):
        write_record(root / "units" / f"U{k}", seed=k)
        rows.append([f"units/U{k}/exp.toml", serial])
    with (root / "units.csv").open("w", newline="", encoding="utf-8") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
    (root / "fleet.toml").write_text('[records]\nmanifest = "units.csv"\n' + extra,
                                     encoding="utf-8")
    return root / "fleet.toml"


def write_pem(client, folder):
    """Write a TLS client's CA, certificate and key to PEM files; return their paths by name."""
    pem = {}
    for name, text in (("ca", client.security.tls_ca_file),
                       ("cert", client.security.tls_client_cert),
                       ("key", client.security.tls_client_key)):
        pem[name] = folder / f"{name}.pem"
        pem[name].write_text(text, encoding="utf-8")
    return pem
