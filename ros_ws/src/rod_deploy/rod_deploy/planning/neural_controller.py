"""The neural controller (paper Sec. 4.3): (ls_bar, ks_bar, kappa_bar) -> the optimal grasp, in numpy.

The network is a small MLP trained by ``scripts/train_grasp_network.py`` on the optimal grasps of
``grasp_dataset.npz`` (continuum convention, ``rod_deploy.planning.optimal_grasp``). Two changes from the paper's
4 x 392 ReLU network, both measured (``benchmarks/grasp_network_accuracy.py``):

* inputs log(ls_bar), log(ks_bar), |kappa_bar| (standardised): the grasp varies fastest at small ls_bar and over
  decades of ks_bar;
* outputs x_bar, y_bar, ls_bar - z_bar and the rotation vector (standardised): ls_bar - z_bar tends to the heavy
  elastica's 1.5153 and x_bar to 2.5662 as ls_bar grows, so every output stays of order one over ls_bar 0.5-100.

Signed curvature: the network sees |kappa_bar|; for kappa_bar < 0 the grasp is mirrored in the x-z plane
(y -> -y, and the rotation R -> M R M with M = diag(1, -1, 1), i.e. rotvec (rx, ry, rz) -> (-rx, ry, -rz)), as the
released code does. Inputs outside the trained range raise :class:`OutOfTrainedRange`: never extrapolated.
Inference is a forward pass of dense layers compiled with numba (a 200-node pattern: about 1 ms; torch is not imported):
numpy's matrix product hands a 200 x 128 x 128 product to OpenBLAS's threads, which on a loaded 2-core machine took
20 ms of wall clock and 8 ms of CPU per layer, their spinning afterwards doubling the CPU time of the whole plan
(benchmarks/results/planning_speed.md); a single-threaded BLAS does it in 0.15 ms. The loaded weights are kept per
file (path, size and modification time), so that planning does not read them each time.
"""
from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np
from numba import njit

DEFAULT_WEIGHTS = Path(__file__).resolve().parents[1] / 'data' / 'grasp_network.npz'


class OutOfTrainedRange(ValueError):
    """An input outside the range the network was trained on (it is never extrapolated)."""


def features(ls_bar, ks_bar, kappa_bar):
    """Network inputs before standardisation: (log ls_bar, log ks_bar, |kappa_bar|), shape (n, 3)."""
    return np.stack([np.log(ls_bar), np.log(ks_bar), np.abs(kappa_bar)], axis=-1)


def targets(ls_bar, position, rotvec):
    """Network outputs before standardisation: (x, y, ls_bar - z, rotvec), shape (n, 6)."""
    position = np.asarray(position, float)
    return np.concatenate([position[:, :2], (ls_bar - position[:, 2])[:, None], np.asarray(rotvec, float)], axis=1)


def mirror(position, rotvec):
    """The grasp for -kappa_bar from the grasp for +kappa_bar: reflection y -> -y of the pose."""
    p = np.array(position, float, copy=True)
    r = np.array(rotvec, float, copy=True)
    p[..., 1] *= -1.0
    r[..., 0] *= -1.0
    r[..., 2] *= -1.0
    return p, r


class GraspPredictor:
    """A trained grasp network: ``predict(ls_bar, ks_bar, kappa_bar) -> (position (n, 3) [L_gb], rotvec (n, 3))``
    in the frame and conventions of :func:`rod_deploy.planning.optimal_grasp.optimal_grasp` (continuum)."""

    def __init__(self, weights: list, biases: list, input_mean, input_std, output_mean, output_std,
                 trained_range: dict, record: dict | None = None):
        self.weights = [np.asarray(w, float) for w in weights]
        self._weights_t = [np.ascontiguousarray(w.T) for w in self.weights]
        self.biases = [np.asarray(b, float) for b in biases]
        self.input_mean, self.input_std = np.asarray(input_mean, float), np.asarray(input_std, float)
        self.output_mean, self.output_std = np.asarray(output_mean, float), np.asarray(output_std, float)
        self.trained_range = trained_range
        self.record = record or {}

    def check_range(self, ls_bar, ks_bar, kappa_bar):
        for name, values, (lo, hi) in (('ls_bar', ls_bar, self.trained_range['ls_bar']),
                                       ('ks_bar', ks_bar, self.trained_range['ks_bar']),
                                       ('|kappa_bar|', np.abs(kappa_bar), self.trained_range['abs_kappa_bar'])):
            values = np.asarray(values, float)
            bad = ~np.isfinite(values) | (values < lo * (1 - 1e-9)) | (values > hi * (1 + 1e-9))
            if np.any(bad):
                i = int(np.flatnonzero(bad)[0])
                raise OutOfTrainedRange(f'{name} = {values.flat[i]:.6g} (input {i}) is outside the range the grasp '
                                        f'network was trained on, [{lo:g}, {hi:g}]; use the numeric planner')

    def predict(self, ls_bar, ks_bar, kappa_bar):
        ls_bar, ks_bar, kappa_bar = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float))
                                                          for v in (ls_bar, ks_bar, kappa_bar)))
        self.check_range(ls_bar, ks_bar, kappa_bar)
        h = (features(ls_bar, ks_bar, kappa_bar) - self.input_mean) / self.input_std
        h = np.ascontiguousarray(h)
        for w_t, b in zip(self._weights_t[:-1], self.biases[:-1]):
            h = dense_layer(h, w_t, b)
            h = h / (1.0 + np.exp(-h))                       # SiLU
        out = dense_layer(h, self._weights_t[-1], self.biases[-1]) * self.output_std + self.output_mean
        position = np.stack([out[:, 0], out[:, 1], ls_bar - out[:, 2]], axis=1)
        rotvec = out[:, 3:6].copy()
        negative = kappa_bar < 0
        if np.any(negative):
            position[negative], rotvec[negative] = mirror(position[negative], rotvec[negative])
        return position, rotvec


@njit(cache=True)
def dense_layer(h, weight_t, bias):
    """h (n, k) @ weight_t (k, m) + bias (m,), single-threaded (the innermost loop over the m outputs vectorises)."""
    n, k = h.shape
    m = weight_t.shape[1]
    out = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            out[i, j] = bias[j]
        for q in range(k):
            a = h[i, q]
            for j in range(m):
                out[i, j] += a * weight_t[q, j]
    return out


def load_grasp_network(path=None) -> GraspPredictor:
    """The shipped network (``rod_deploy/data/grasp_network.npz``) or the one at ``path``; read once per file
    version (the same object is returned while the file is unchanged)."""
    path = Path(path) if path is not None else DEFAULT_WEIGHTS
    if not path.exists():
        raise FileNotFoundError(f'grasp network weights {path} not found (scripts/train_grasp_network.py makes them)')
    st = path.stat()
    return _read_grasp_network(path.resolve(), st.st_size, st.st_mtime_ns)


@lru_cache(maxsize=4)
def _read_grasp_network(path, size, mtime_ns):
    with np.load(path, allow_pickle=False) as z:
        n = int(z['n_layers'])
        record = json.loads(str(z['record'])) if 'record' in z.files else {}
        return GraspPredictor([z[f'w{i}'] for i in range(n)], [z[f'b{i}'] for i in range(n)],
                              z['input_mean'], z['input_std'], z['output_mean'], z['output_std'],
                              json.loads(str(z['trained_range'])), record)
