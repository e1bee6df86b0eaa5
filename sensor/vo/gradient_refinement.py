"""Gradient (Lucas–Kanade) refinement of the matched positions (``VOConfig.gradient_refinement = "lucas_kanade"``).

After the descriptor refinement (:mod:`sensor.vo.refinement`), each of the 1p, 2p and 2c positions of a match is
moved to the minimum of the sum of squared grey-level differences between a square window of the current-left image
around the fixed 1c position and the same window around that position in the other image, bilinearly interpolated:
Gauss–Newton iterations on the window's brightness constancy (Lucas & Kanade 1981), in the form of Bouguet's
implementation (the gradient and its 2×2 normal matrix taken once, on the 1c window; Bouguet 2000, OpenCV's
``calcOpticalFlowPyrLK`` at one pyramid level, started from the refined position).

The descriptor refinement compares sparse taps of quantised Sobel responses at whole (or half) pixel offsets and fits
a curve through three costs: its sub-pixel position is drawn towards the grid it searches on. The gradient
refinement solves for the sub-pixel displacement directly from the grey levels, with no grid of candidates
(docs/visual_odometry.md §8; docs/camera.md, a long lead trailer's side camera). It assumes the four images' grey
levels agree (one exposure for the four): a brightness change between them moves its minimum.

A position whose window is too flat (OpenCV's smallest-eigenvalue test), whose iterations leave the image, or that
moves more than :data:`MAX_MOVE` px from where the descriptor refinement put it keeps that position.
"""

from __future__ import annotations

import cv2
import numpy as np

from sensor.vo.match_columns import U1C, U1P, U2C, U2P

__all__ = ["MAX_ITERATIONS", "MAX_MOVE", "STEP_TOLERANCE", "WINDOW", "refine_gradient"]

#: Side [px] of the square window compared around each position.
WINDOW = 9
#: Gauss–Newton iterations at most per position.
MAX_ITERATIONS = 30
#: The iterations stop once a step is shorter than this [px].
STEP_TOLERANCE = 1e-3
#: Largest move [px] (either coordinate) from the descriptor refinement's position; beyond it the position is kept.
MAX_MOVE = 1.0


def _track(template: np.ndarray, target: np.ndarray, fixed: np.ndarray, start: np.ndarray) -> np.ndarray:
    """(N, 2) positions in ``target`` of the windows of ``template`` at ``fixed``, iterated from ``start`` [px]."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, MAX_ITERATIONS, STEP_TOLERANCE)
    found, status, _ = cv2.calcOpticalFlowPyrLK(
        template,
        target,
        np.ascontiguousarray(fixed, dtype=np.float32).reshape(-1, 1, 2),
        np.ascontiguousarray(start, dtype=np.float32).reshape(-1, 1, 2),
        winSize=(WINDOW, WINDOW),
        maxLevel=0,
        criteria=criteria,
        flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    moved = found.reshape(-1, 2).astype(np.float64)
    keep = (status.ravel() == 1) & np.isfinite(moved).all(axis=1) & (np.abs(moved - start).max(axis=1) <= MAX_MOVE)
    return np.where(keep[:, None], moved, start)


def refine_gradient(xy: np.ndarray, images: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """Move the 1p, 2p and 2c positions to the grey-level minimum of the 1c window (module docstring).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches (columns :data:`~sensor.vo.match_columns.COLUMNS`) [px].
    images : tuple of numpy.ndarray
        The (H, W) uint8 grey images of 1p, 2p, 1c and 2c.

    Returns
    -------
    numpy.ndarray
        Refined (N, 8) matches, the 1c columns unchanged.
    """
    if xy.shape[0] == 0:
        return xy
    previous_left, previous_right, current_left, current_right = images
    out = np.array(xy, dtype=np.float64, copy=True)
    fixed = out[:, U1C : U1C + 2]
    for image, col in ((previous_left, U1P), (previous_right, U2P), (current_right, U2C)):
        out[:, col : col + 2] = _track(current_left, image, fixed, out[:, col : col + 2])
    return out
