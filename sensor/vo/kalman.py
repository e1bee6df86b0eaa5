"""Optional constant-acceleration Kalman smoothing of the per-frame motion.

The StereoScan paper (Geiger, Ziegler & Stiller 2011, §III-B) filters the ego-motion with a
constant-acceleration Kalman filter; libviso2 does not contain one (docs/visual_odometry.md §12), so the
filter here is off by default. Each of the six motion parameters θ = (rx, ry, rz, tx, ty, tz) per
frame — a velocity sampled at the camera rate — has the state (θ_i, θ̇_i) with

    x_k = F x_{k−1} + G a_k,   F = [[1, 1], [0, 1]],   G = [½, 1]ᵀ,   a_k ~ N(0, σ_p²)
    z_k = θ_i,measured = [1, 0] x_k + n_k,   n_k ~ N(0, σ_m²)

(time unit: one frame). A failed frame only predicts.
"""

from __future__ import annotations

import numpy as np

from sensor.vo.config import VOConfig

__all__ = ["MotionKalmanFilter"]


class MotionKalmanFilter:
    """Six independent constant-acceleration filters, vectorised.

    Parameters
    ----------
    config : VOConfig
        Process and measurement standard deviations (rotation [rad], translation [m], per frame).
    """

    def __init__(self, config: VOConfig) -> None:
        proc = np.array([config.kalman_rotation_process_std] * 3 + [config.kalman_translation_process_std] * 3)
        meas = np.array([config.kalman_rotation_measurement_std] * 3 + [config.kalman_translation_measurement_std] * 3)
        self._f = np.array([[1.0, 1.0], [0.0, 1.0]])
        g = np.array([0.5, 1.0])
        self._q = proc[:, None, None] ** 2 * np.outer(g, g)[None]  # (6, 2, 2)
        self._r = meas**2  # (6,)
        self.reset()

    def reset(self) -> None:
        """Forget the state; the next measurement initialises it."""
        self._x: np.ndarray | None = None  # (6, 2)
        self._p: np.ndarray | None = None  # (6, 2, 2)

    def predict(self) -> None:
        """Propagate one frame."""
        if self._x is None or self._p is None:
            return
        self._x = self._x @ self._f.T
        self._p = self._f @ self._p @ self._f.T + self._q

    def update(self, params: np.ndarray) -> np.ndarray:
        """Predict one frame, fuse a measured θ (6,) and return the filtered θ."""
        params = np.asarray(params, dtype=float)
        if self._x is None or self._p is None:
            self._x = np.stack([params, np.zeros(6)], axis=1)
            self._p = np.zeros((6, 2, 2))
            self._p[:, 0, 0] = self._r
            self._p[:, 1, 1] = self._r + self._q[:, 1, 1] * 100.0
            return params.copy()
        self.predict()
        innovation = params - self._x[:, 0]
        s = self._p[:, 0, 0] + self._r
        gain = self._p[:, :, 0] / s[:, None]  # (6, 2)
        self._x = self._x + gain * innovation[:, None]
        self._p = self._p - gain[:, :, None] * self._p[:, 0, None, :]
        return self._x[:, 0].copy()
