"""Gradient (Lucas–Kanade) refinement of the matched positions (``VOConfig.gradient_refinement``).

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

``"lucas_kanade_affine"`` drops that assumption: each window's grey levels may differ from the 1c window's by a gain
and an offset of their own, ``g(x + p) = a·f(x) + b`` (f the 1c window, g the other image), solved with the
displacement. The offset and gain are projected out of the residual and of the steepest-descent images (the
project-out inverse compositional algorithm, with the appearance images 1 and f; Baker, Gross & Matthews 2003,
"Lucas-Kanade 20 Years On: A Unifying Framework: Part 3", CMU-RI-TR-03-35): the 2×2 normal matrix is taken once, on
the 1c window's gradient with its components along 1 and f removed, and each Gauss–Newton step is that matrix's solve
of the projected residual divided by the window's gain (the chain rule at the solution, ∇g = a·∇f;
:func:`_affine_track`). Its minimum is that of the zero-mean normalised sum of squared differences (ZNSSD, the
criterion of digital image correlation's inverse compositional Gauss–Newton; Pan, Li & Tong 2013), which a gain and
an offset between the windows do not move.

A position whose window is too flat (OpenCV's smallest-eigenvalue test; the affine variant's on its projected
normal matrix, and a 1c window of no grey-level spread), whose iterations leave the image, whose fitted gain is not
positive (the affine variant), or that moves more than :data:`MAX_MOVE` px from where the descriptor refinement put it
keeps that position.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import cv2
import numpy as np

from sensor.vo.match_columns import U1C, U1P, U2C, U2P

__all__ = ["MAX_ITERATIONS", "MAX_MOVE", "MIN_EIGENVALUE", "STEP_TOLERANCE", "WINDOW", "refine_gradient"]


#: Side [px] of the square window compared around each position.
WINDOW = 9
#: Gauss–Newton iterations at most per position.
MAX_ITERATIONS = 30
#: The iterations stop once a step is shorter than this [px].
STEP_TOLERANCE = 1e-3
#: Largest move [px] (either coordinate) from the descriptor refinement's position; beyond it the position is kept.
MAX_MOVE = 1.0
#: Smallest eigenvalue [grey²/px²] of the window's normal matrix over its pixel count below which the window is too
#: flat to track (OpenCV's ``minEigThreshold`` default, in the same units).
MIN_EIGENVALUE = 1e-4


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


def _sample(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``image`` at (u, v) [px], every sample at least one pixel inside the image."""
    u0, v0 = np.floor(u).astype(np.intp), np.floor(v).astype(np.intp)
    fu, fv = u - u0, v - v0
    width = image.shape[1]
    flat = image.ravel()
    i00 = v0 * width + u0
    top = flat[i00] * (1.0 - fu) + flat[i00 + 1] * fu
    bottom = flat[i00 + width] * (1.0 - fu) + flat[i00 + width + 1] * fu
    return top * (1.0 - fv) + bottom * fv


def _inside(image: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(N,) whether the windows centred on ``centre`` [px] and their bilinear neighbours lie inside ``image``."""
    half = WINDOW // 2
    height, width = image.shape
    u, v = centre[:, 0], centre[:, 1]
    finite = np.isfinite(centre).all(axis=1)
    return finite & (u - half >= 0) & (v - half >= 0) & (u + half < width - 1) & (v + half < height - 1)


class _Templates(NamedTuple):
    """The 1c windows of :func:`_affine_track`, taken once for the three other images."""

    rows: np.ndarray  # (M,) the matches whose 1c window lies inside the image and is not flat
    centred: np.ndarray  # (M, W²) f̃, the window's grey levels less their mean [grey]
    spread: np.ndarray  # (M,) ⟨f̃, f̃⟩ [grey²]
    sd_u: np.ndarray  # (M, W²) the projected steepest-descent images [grey/px]
    sd_v: np.ndarray
    h11: np.ndarray  # (M,) their normal matrix [grey²/px²]
    h12: np.ndarray
    h22: np.ndarray


def _window_offsets() -> tuple[np.ndarray, np.ndarray]:
    """(W²,) u and v offsets [px] of a window's pixels from its centre."""
    half = WINDOW // 2
    offsets = np.arange(-half, half + 1, dtype=np.float64)
    du, dv = np.meshgrid(offsets, offsets)
    return du.ravel(), dv.ravel()


def _affine_templates(template: np.ndarray, fixed: np.ndarray) -> _Templates:
    """The 1c windows, their projected steepest-descent images and normal matrices (Baker, Gross & Matthews 2003,
    Part 3, the project-out algorithm, the warp a translation): with P⊥ the projection off the window's constant and f̃,
    SD = P⊥·∇f and H = SDᵀ·SD; the windows too flat to track dropped."""
    du, dv = _window_offsets()
    image = template.astype(np.float64)
    rows = np.flatnonzero(_inside(image, fixed))
    su, sv = fixed[rows, 0:1] + du, fixed[rows, 1:2] + dv  # (M, W²)
    f = _sample(image, su, sv)
    centred = f - f.mean(axis=1, keepdims=True)
    spread = np.einsum("ij,ij->i", centred, centred)
    basis = centred / np.sqrt(np.maximum(spread, np.finfo(float).tiny))[:, None]

    def project(gradient: np.ndarray) -> np.ndarray:
        less_mean = gradient - gradient.mean(axis=1, keepdims=True)
        return less_mean - np.einsum("ij,ij->i", less_mean, basis)[:, None] * basis

    sd_u = project(_sample(cv2.Scharr(image, cv2.CV_64F, 1, 0) / 32.0, su, sv))  # Scharr's weights sum to 32
    sd_v = project(_sample(cv2.Scharr(image, cv2.CV_64F, 0, 1) / 32.0, su, sv))
    h11 = np.einsum("ij,ij->i", sd_u, sd_u)
    h12 = np.einsum("ij,ij->i", sd_u, sd_v)
    h22 = np.einsum("ij,ij->i", sd_v, sd_v)
    min_eig = 0.5 * (h11 + h22 - np.sqrt((h11 - h22) ** 2 + 4.0 * h12**2)) / du.size
    keep = (spread > 0.0) & (min_eig >= MIN_EIGENVALUE)
    return _Templates(rows[keep], centred[keep], spread[keep], sd_u[keep], sd_v[keep], h11[keep], h12[keep], h22[keep])


def _affine_track(templates: _Templates, target: np.ndarray, start: np.ndarray) -> np.ndarray:
    """(N, 2) positions in ``target`` of the 1c windows up to a gain and an offset of the grey levels per window,
    iterated from ``start`` [px] (module docstring).

    Each iteration samples the target window g at p and steps p ← p − H⁻¹·SDᵀ·g / â (SDᵀ·P⊥·g = SDᵀ·g, SD being
    orthogonal to 1 and f̃; Baker, Gross & Matthews 2003, Part 3), with â = √(⟨g̃, g̃⟩ / ⟨f̃, f̃⟩) the ratio of the two
    windows' grey-level spreads (ZNSSD's normalisation, Pan, Li & Tong 2013; at the solution the gain a, and unlike
    the regression ⟨g̃, f̃⟩ / ⟨f̃, f̃⟩ not shrunk by the misalignment, so the steps do not overshoot). The step's scale
    does not move the solution, where SDᵀ·g = 0. The offset b never enters: it lies along the projected-out constant.
    A window anti-correlated with the 1c window (⟨g̃, f̃⟩ ≤ 0) is no match and keeps its position.
    """
    du, dv = _window_offsets()
    result = np.array(start, dtype=np.float64, copy=True)
    t = templates
    image = target.astype(np.float64)
    p = np.array(start[t.rows], dtype=np.float64, copy=True)
    good = _inside(image, p)
    active = good.copy()
    det = t.h11 * t.h22 - t.h12**2
    for _ in range(MAX_ITERATIONS):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        g = _sample(image, p[idx, 0:1] + du, p[idx, 1:2] + dv)
        g_centred = g - g.mean(axis=1, keepdims=True)
        positive = np.einsum("ij,ij->i", g_centred, t.centred[idx]) > 0.0
        gain = np.sqrt(np.einsum("ij,ij->i", g_centred, g_centred) / t.spread[idx])
        bu = np.einsum("ij,ij->i", t.sd_u[idx], g)
        bv = np.einsum("ij,ij->i", t.sd_v[idx], g)
        scale = 1.0 / (np.where(positive, gain, 1.0) * det[idx])
        step_u = (t.h22[idx] * bu - t.h12[idx] * bv) * scale
        step_v = (t.h11[idx] * bv - t.h12[idx] * bu) * scale
        p[idx, 0] -= step_u
        p[idx, 1] -= step_v
        stays = positive & _inside(image, p[idx])
        good[idx[~stays]] = False
        active[idx] = stays & (np.hypot(step_u, step_v) >= STEP_TOLERANCE)
    keep = good & (np.abs(p - start[t.rows]).max(axis=1) <= MAX_MOVE)
    result[t.rows[keep]] = p[keep]
    return result


def refine_gradient(
    xy: np.ndarray,
    images: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    method: Literal["lucas_kanade", "lucas_kanade_affine"] = "lucas_kanade",
) -> np.ndarray:
    """Move the 1p, 2p and 2c positions to the grey-level minimum of the 1c window (module docstring).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches (columns :data:`~sensor.vo.match_columns.COLUMNS`) [px].
    images : tuple of numpy.ndarray
        The (H, W) uint8 grey images of 1p, 2p, 1c and 2c.
    method : {"lucas_kanade", "lucas_kanade_affine"}
        Brightness constancy between the windows, or a gain and an offset of the grey levels per window.

    Returns
    -------
    numpy.ndarray
        Refined (N, 8) matches, the 1c columns unchanged.
    """
    if method not in ("lucas_kanade", "lucas_kanade_affine"):
        raise ValueError(f"gradient refinement method = {method!r}: must be 'lucas_kanade' or 'lucas_kanade_affine'")
    if xy.shape[0] == 0:
        return xy
    previous_left, previous_right, current_left, current_right = images
    out = np.array(xy, dtype=np.float64, copy=True)
    fixed = out[:, U1C : U1C + 2]
    templates = _affine_templates(current_left, fixed) if method == "lucas_kanade_affine" else None
    for image, col in ((previous_left, U1P), (previous_right, U2P), (current_right, U2C)):
        start = out[:, col : col + 2]
        if templates is None:
            out[:, col : col + 2] = _track(current_left, image, fixed, start)
        else:
            out[:, col : col + 2] = _affine_track(templates, image, start)
    return out
