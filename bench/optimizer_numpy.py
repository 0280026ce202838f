"""The paper-model grid search of controller/src/optimizer.rs in vectorised NumPy.

Same problem, same grid, same algorithm: for each (omega, k) the largest feasible f0 from the
caps (stress, strain, f0_max) and the mileage condition h(z) >= K in z = g / f0, with
h(z) = z^2 (n_F - 2 asin(z) / pi); the rising root of h(z) = K by safeguarded Newton (vectorised,
fixed iteration count), then V = eps c_d / c_v (n_F - 2 asin(z) / pi) and the best cell: the lowest
f0 among the cells within 0.1 % of the fastest speed, as the Rust optimiser chooses.
"""

import numpy as np

AREA, RHO, E = 1e-4, 0.1, 140e3
CV, CD, EPS, NF = 1.0, 1.0, 0.1, 0.5
D, J0, SIGMA_MAX = 1.0, 20.0, 100e3
STRAIN_MAX, F0_MAX = 0.3, 5.0
OMEGA = (10.0, 300.0)
K = (2 * np.pi, 8 * np.pi)
TIE = 1e-3  # relative speed tolerance of the tie-break (the optimiser's default)


def h(z):
    return z * z * (NF - 2.0 * np.arcsin(np.minimum(z, 1.0)) / np.pi)


def h_peak():
    a, b = 0.0, np.sin(np.pi * NF / 2)
    r = 0.5 * (5 ** 0.5 - 1)
    x1, x2 = b - r * (b - a), a + r * (b - a)
    f1, f2 = h(x1), h(x2)
    while b - a > 1e-13:
        if f1 < f2:
            a, x1, f1 = x1, x2, f2
            x2 = a + r * (b - a)
            f2 = h(x2)
        else:
            b, x2, f2 = x2, x1, f1
            x1 = b - r * (b - a)
            f1 = h(x1)
    return (x1, f1) if f1 > f2 else (x2, f2)


def grid_search(n_omega=500, n_k=500):
    ae = AREA * E
    c = np.sqrt(ae / RHO)
    w, k = np.meshgrid(np.linspace(*OMEGA, n_omega), np.linspace(*K, n_k))
    alpha = w / (k * c)
    zeta = CV / (k * np.sqrt(RHO * ae))
    r0 = 1.0 / np.sqrt((alpha * alpha - 1.0) ** 2 + (zeta * alpha) ** 2)
    band = EPS * CD
    f_stress = SIGMA_MAX * AREA / (r0 * alpha * np.sqrt(alpha * alpha + zeta * zeta))
    f_strain = STRAIN_MAX * ae / r0
    cap = np.minimum(np.minimum(F0_MAX, f_stress), f_strain)
    g = band * NF / (k * zeta * r0 * alpha)
    z_star, h_star = h_peak()
    # The mileage condition h(z) >= K has K depending on k only: solve it once per row of k
    # (at alpha = 1), as the Rust implementation does.
    k_row = k[:, 0]
    zeta_row = CV / (k_row * np.sqrt(RHO * ae))
    g_row = band * NF * zeta_row / (k_row * zeta_row)  # R0 = 1/zeta, alpha = 1
    p_row = np.pi * zeta_row / zeta_row ** 2 * k_row * c / (k_row * ae)
    kk_row = (D / J0) * CV * p_row * g_row * g_row / band
    kk = np.repeat(kk_row[:, None], w.shape[1], axis=1)
    feasible = kk <= h_star
    z_root = rising_root(kk_row, z_star)
    z = np.repeat(z_root[:, None], w.shape[1], axis=1)
    z_cap = g / cap
    zz = np.maximum(z, z_cap)
    ok = feasible & (h(zz) >= kk * (1 - 1e-9)) & (zz <= 1.0)
    v = np.where(ok, band / CV * (NF - 2.0 * np.arcsin(np.minimum(zz, 1.0)) / np.pi), -np.inf)
    # The tie-break of the Rust optimiser: among the cells within TIE of the fastest speed, the
    # lowest amplitude f0 = g / z (the speed hardly changes along the mileage ridge).
    top = v.max()
    f0 = np.where(v >= top * (1.0 - TIE), g / zz, np.inf)
    i = np.unravel_index(np.argmin(f0), f0.shape)
    return float(v[i]), float(w[i]), float(k[i]), float(f0[i]), float(top)


def rising_root(kk, z_star):
    """Rising root of h(z) = kk on [0, z*]: safeguarded Newton, vectorised."""
    lo = np.zeros_like(kk)
    hi = np.full_like(kk, z_star)
    z = np.minimum(np.sqrt(np.maximum(kk, 0.0) / NF), z_star)
    for _ in range(40):
        f = h(z) - kk
        hi = np.where(f > 0, z, hi)
        lo = np.where(f > 0, lo, z)
        d = 2 * z * (NF - 2 * np.arcsin(z) / np.pi) - z * z * 2 / (np.pi * np.sqrt(1 - z * z))
        with np.errstate(divide="ignore", invalid="ignore"):
            nxt = z - f / d
        bad = ~((nxt > lo) & (nxt < hi)) | ~np.isfinite(nxt)
        nxt = np.where(bad, 0.5 * (lo + hi), nxt)
        if np.all(np.abs(nxt - z) <= 1e-15 * np.maximum(z, 1e-300)):
            z = nxt
            break
        z = nxt
    return z
