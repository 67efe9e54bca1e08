"""A compiled multilayer perceptron (linear layers, ELU between them) for a few rows at a time.

A solve runs the SIK networks on a few rows (the posture indices of its solutions, a seed's
own posture), where NumPy's per-call cost outweighs the arithmetic. The layers' weights are
packed into one float32 array (:func:`pack_layers`); :func:`mlp_rows` runs every layer in one
call.
"""

from typing import List, Tuple

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE


def pack_layers(layers: List[Tuple[np.ndarray, np.ndarray]]) -> Tuple[np.ndarray, np.ndarray]:
    """Weights (in, out) and biases (out,) of each layer, packed for :func:`mlp_rows`.

    Returns:
        the parameters (P,) float32 and each layer's (inputs, outputs, offset) (L, 3) int64.
    """
    parts, shapes, offset = [], [], 0
    for w, b in layers:
        parts += [np.asarray(w, np.float32).ravel(), np.asarray(b, np.float32).ravel()]
        shapes.append((w.shape[0], w.shape[1], offset))
        offset += w.size + b.size
    return np.concatenate(parts), np.array(shapes, dtype=np.int64)


@njit('float32[:, ::1](float32[:, ::1], float32[::1], int64[:, ::1])', cache=CACHE, nogil=True,
      fastmath=True)
def mlp_rows(x, params, shapes):  # pragma: no cover (compiled)
    """The network's outputs (M, out) for inputs ``x`` (M, in): ELU (alpha 1) between layers."""
    m = x.shape[0]
    width = 0
    for k in range(shapes.shape[0]):
        width = max(width, shapes[k, 0], shapes[k, 1])
    a, b = np.zeros((m, width), np.float32), np.zeros((m, width), np.float32)
    a[:, :x.shape[1]] = x
    last = shapes.shape[0] - 1
    for k in range(shapes.shape[0]):
        n_in, n_out, off = shapes[k, 0], shapes[k, 1], shapes[k, 2]
        w = params[off:off + n_in * n_out].reshape((n_in, n_out))
        bias = params[off + n_in * n_out:off + n_in * n_out + n_out]
        for r in range(m):
            out = b[r]
            for j in range(n_out):
                out[j] = bias[j]
            for i in range(n_in):
                v = a[r, i]
                if v != 0.0:
                    row = w[i]
                    for j in range(n_out):
                        out[j] += v * row[j]
            if k < last:
                for j in range(n_out):
                    if out[j] < 0.0:
                        out[j] = np.expm1(out[j])
        a, b = b, a
    return a[:, :shapes[last, 1]].copy()
