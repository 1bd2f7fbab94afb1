"""The GRU recurrences of the sequence CNN-GRU's fast prediction as one compiled loop (Numba).

Predicting an NSGA-II generation, the sequence network spends most of its time in its GRUs'
recurrences: per layer and time step one small matrix product of the hidden states and five
gate operations (:func:`railsusp.surrogate.recurrence.gru_step`). As torch operations each is
a pass over the whole (rows, 3H) gate array through memory; on a 2-core Xeon the gates cost
twice the product (bench/README.md, stop 47). :func:`gru_gates` runs all five in one
compiled pass per row instead, on the calling thread (the prediction's workers share the
cores by parameter sets: a parallel pass per step, thousands a generation, waited for a
thread that another process held); the product stays torch's (oneDNN's or MKL's), which a
plain compiled loop did not match (2.7 times slower).

The equations are torch's ``nn.GRU`` ones with the weights as :func:`cell_params
<railsusp.surrogate.recurrence.cell_params>` prepares them (input-side biases folded in, the
n gate's rows doubled so that tanh(y) = 2 sigmoid(2 y) - 1). The gates are evaluated in
float64 with the logistic function of :func:`_sigmoid` and rounded to float32 once: the
outputs agree with torch's to float32 rounding (tests/surrogate/test_gru_kernel.py). The
fast-math flags are the simulator's (:data:`railsusp.vehicle.kernel_cache.FASTMATH`): none
that assumes finite values, so a NaN propagates as in torch.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from railsusp.vehicle.kernel_cache import FASTMATH  # (the kernels' flags and cache folder)

#: beyond this |x| the logistic function is taken as e^-24 = 3.8e-11 from 1 or 0 (1 in float32
#: on that side; on the other 3.8e-11 instead of less, far below the gates' float32 sums)
_SIGMOID_CLAMP = 24.0
#: e^-|x| as (e^(-|x| / 64))^64: the Taylor polynomial of degree 8 of e^-y for y <= 0.375
_REDUCTION = 1.0 / 64.0


@nb.njit(cache=True, fastmath=FASTMATH, inline="always", error_model="numpy")
def _sigmoid(x):
    """The logistic function 1 / (1 + e^-x) of a float64, branch-free so that loops over it
    vectorise (the C library's exp does not): e^-|x| by range reduction, the Taylor
    polynomial of degree 8 of e^-y at y = |x| / 64 (remainder 5.7e-10 relative at y = 0.375,
    |x| = 24, and 3e-14 at |x| = 8), then six squarings, which multiply its relative error by
    64. Beyond |x| = 24 the result is clamped at e^-24 = 3.8e-11 from 0 or 1. The error is
    far below float32's resolution of the gates (tested: 1e-13 absolute within |x| <= 24,
    4e-8 relative). A NaN gives NaN (a diverging input is not hidden)."""
    a = abs(x)
    a = _SIGMOID_CLAMP if a > _SIGMOID_CLAMP else a  # (a NaN stays NaN, as in torch)
    y = a * _REDUCTION
    p = 1.0 + y * (-1.0 + y * (0.5 + y * (-1.0 / 6.0 + y * (1.0 / 24.0 + y * (
        -1.0 / 120.0 + y * (1.0 / 720.0 + y * (-1.0 / 5040.0 + y / 40320.0)))))))  # fmt: skip
    p = p * p  # six squarings, written out: an inner loop would stop the vectoriser
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    s = 1.0 / (1.0 + p)  # sigma(|x|)
    return s if x >= 0.0 else p * s  # sigma(-a) = e^-a / (1 + e^-a)


@nb.njit(cache=True, fastmath=FASTMATH, nogil=True, error_model="numpy")
def gru_gates(gates, t, gh, h, seq):
    """Step ``t`` of G GRUs over ``rows`` rows each, from the two sides' products.

    gates: (G, k, rows, 3H) float32, the input side W_ih x + b of k steps (r, z, n; the n
    rows doubled); gh: (G, rows, 3H) float32, the hidden side W_hh h + b_h (the n rows
    doubled); h: (G, rows, H) float32, the hidden states, overwritten with the new ones, which
    ``seq[:, t]`` (seq: (G, k, rows, H) float32) receives too. r = sigmoid(i_r + a_r),
    z = sigmoid(i_z + a_z), n = tanh(i_n + r a_n) (= 2 sigmoid(doubled) - 1),
    h' = n + z (h - n): torch's equations (:func:`railsusp.surrogate.recurrence.gru_step`)
    in one pass per row. On the calling thread, without the GIL: the prediction runs its
    workers side by side, each on its own parameter sets
    (:func:`railsusp.surrogate.sequence_sets.predict_sets_in_step`). (Whole contiguous
    arrays and the step's index, not the step's slices: Numba compiles a slice's strides as
    unknown, and the loop over the units then is not vectorised.)"""
    n_net, _, rows, h3 = gates.shape
    hs = h3 // 3
    for g in range(n_net):
        for r in range(rows):
            for j in range(hs):
                rg = _sigmoid(np.float64(gates[g, t, r, j]) + gh[g, r, j])
                z = _sigmoid(np.float64(gates[g, t, r, hs + j]) + gh[g, r, hs + j])
                n = 2.0 * _sigmoid(gates[g, t, r, 2 * hs + j] + rg * gh[g, r, 2 * hs + j]) - 1.0
                new = np.float32(n + z * (h[g, r, j] - n))
                h[g, r, j] = new
                seq[g, t, r, j] = new
