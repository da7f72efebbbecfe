# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""How fast a substep of two Jacobi density passes damps one mode, with and without a compression-rate term.

A mode of the pass's operator with eigenvalue ``mu`` (docs/validation/one_kernel/operator_spectrum.py) is
one number: its constraint error ``x``. A substep predicts ``x + y`` (``y`` = velocity x substep),
corrects it twice by ``-w mu C_eff`` and takes the velocity from the move, as ``SolverXPBD`` does. With
``C_eff = C`` (today) a long wave decays at ``-ln(radius) x 480`` per second (8 substeps at 60 Hz). Two
rate terms are tried: ``C_eff = C + g (C_first - C_first_previous)`` (the first pass's error against
the previous substep's, no extra neighbour loop) and ``C_eff = C + g y`` (the rate from the velocities).
Prints the largest spectral radius over ``mu`` in (0, 2.6] (above 1: unstable) and the decay of the
40-layer column's first mode (``mu`` about 0.0026: the spectrum's longest sampled wave, pi / 48 d, 0.0072 at
step 1, scaled by ``k^2`` to a quarter wave over 40 layers, pi / 80 d). docs/archive/validation_notebook.md,
"The one-kernel column's slow breathing".

Usage: python docs/validation/one_kernel/rate_damping_modes.py
"""

import numpy as np

STEP = 0.7208  # the default relaxation for two passes at h = 1.8 d
COLUMN_MU = 0.0026
SUBSTEPS_PER_S = 480.0


def substep_matrix(mu: float, g: float, lagged: bool) -> np.ndarray:
    """The substep's linear map of (x, y[, previous first-pass error])."""
    size = 3 if lagged else 2
    m = np.zeros((size, size))
    for k in range(size):
        s = np.zeros(size)
        s[k] = 1.0
        x, y = s[0], s[1]
        predicted = x + y
        rate = predicted - s[2] if lagged else y
        xn = predicted
        for _ in range(2):
            xn -= STEP * mu * (xn + g * rate)
        m[:, k] = (xn, xn - x, predicted)[:size]
    return m


def radius(mu: float, g: float, lagged: bool) -> float:
    return float(np.abs(np.linalg.eigvals(substep_matrix(mu, g, lagged))).max())


def main():
    mus = np.linspace(1e-4, 2.6, 800)
    print(f"{'rate term':<12}{'g':>6}{'largest radius':>16}{'at mu':>8}{'column mode [1/s]':>19}")
    for lagged in (True, False):
        for g in (0.0, 0.25, 0.5, 1.0, 2.0):
            r = [radius(mu, g, lagged) for mu in mus]
            worst = int(np.argmax(r))
            decay = -SUBSTEPS_PER_S * np.log(radius(COLUMN_MU, g, lagged))
            name = "lagged C" if lagged else "velocity"
            print(f"{name:<12}{g:>6.2f}{r[worst]:>16.4f}{mus[worst]:>8.3f}{decay:>19.2f}")


if __name__ == "__main__":
    main()
