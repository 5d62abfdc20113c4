"""Why the indirect approach covers 0.98 on the delay loop: the study's seeds, not the covariance.

For each of 60 references of the delay loop this computes the indirect
estimate's first-order error ``(ΨᵀΨ)⁻¹Ψᵀw`` at the truth (Ψ from the
reference, w = S·v the loop noise through the sensitivity) and its exact
asymptotic standard deviation (the sandwich with the true noise
autocovariance), then the spread of error/σ with the noise of the study's
own seeds (seed s with reference seed 10000 + s) and with noise drawn from
seeds 5000 + s.  A spread of 1 is what a right covariance gives.

Run from ``tests/closedloop`` (numpy and scipy only):
``python anyloop_delay_seeds.py``.
"""

from __future__ import annotations

import numpy as np
from anyloop_rigs import RIGS, prbs_reference
from scipy import signal


def main(n: int = 10_000, seeds: int = 60) -> None:
    rig = RIGS["delay"]
    nb, nf, nk = rig.orders
    b, f = rig.sampled()
    cn, cd = (np.asarray(p, dtype=float) for p in rig.controller)
    cn = np.concatenate([np.zeros(cd.size - cn.size), cn]) / cd[0]
    cd = cd / cd[0]
    bq = np.concatenate([np.zeros(nk), b])
    # closed loop r → y: Bcl = q^-nk B Cn, Fcl = F Cd + q^-nk B Cn; S = F Cd / Fcl
    fcl = np.polyadd(np.convolve(f, cd)[::-1], np.convolve(bq, cn)[::-1])[::-1]
    s_num = np.convolve(f, cd)
    theta = np.concatenate([b, f[1:]])
    eps = 1e-7

    def y_cl(th: np.ndarray, r: np.ndarray) -> np.ndarray:
        bb = np.concatenate([np.zeros(nk), th[:nb]])
        ff = np.concatenate([[1.0], th[nb:]])
        num = np.convolve(bb, cn)
        den = np.polyadd(np.convolve(ff, cd)[::-1], num[::-1])[::-1]
        return signal.lfilter(num, den, r)

    imp = signal.lfilter(np.convolve(s_num, rig.noise[0]), np.convolve(fcl, rig.noise[1]),
                         np.r_[1.0, np.zeros(3000)])
    lags = 300
    acov = np.array([imp[: 3001 - t] @ imp[t:] for t in range(lags + 1)]) * rig.noise_std**2
    kernel = np.r_[acov[::-1], acov[1:]]
    z_study, z_other = [], []
    for s in range(seeds):
        r = prbs_reference(n, rig.clock, rig.amplitude, 10_000 + s)
        base = y_cl(theta, r)
        psi = np.column_stack([(y_cl(theta + eps * e, r) - base) / eps
                               for e in np.eye(theta.size)])
        gain = np.linalg.solve(psi.T @ psi, psi.T)
        meat = psi.T @ signal.fftconvolve(psi, kernel[:, None], axes=0)[lags: lags + n]
        inv = np.linalg.inv(psi.T @ psi)
        sd = np.sqrt(np.diag(inv @ meat @ inv))

        def noise(seed: int) -> np.ndarray:
            e = np.random.default_rng(seed).standard_normal(n) * rig.noise_std
            return signal.lfilter(s_num, fcl, signal.lfilter(rig.noise[0], rig.noise[1], e))

        z_study.append(gain @ noise(s) / sd)
        z_other.append(gain @ noise(5000 + s) / sd)
    names = [f"b{j}" for j in range(nb)] + [f"f{j}" for j in range(1, nf + 1)]
    print("coefficients:           ", "  ".join(f"{x:>5}" for x in names))
    print("spread, study's seeds:  ", "  ".join(f"{x:5.2f}" for x in np.std(z_study, axis=0)))
    print("spread, seeds 5000 + s: ", "  ".join(f"{x:5.2f}" for x in np.std(z_other, axis=0)))


if __name__ == "__main__":
    main()
