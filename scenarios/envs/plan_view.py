"""Fast plan-view frames for ``render_mode="rgb_array"``: OpenCV drawing on a NumPy canvas (about 1 ms).

North-up (global x to the right, y up), drawn around a centre point with a given span in metres: the
reference path of the driver's control point, the kingpin's and the follow point's tracks, the tractor
and trailer outlines, the trailer axles with their steer, a scale bar at the bottom left and a few lines of
text.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.geometry import (
    kingpin_position,
    place_points,
    towed_outlines,
    tractor_outline,
    trailer_frames,
    trailer_outline,
    trailer_points,
)
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

__all__ = ["SCALE_BAR_STEPS", "camera_strip", "check_render_mode", "draw_plan_view", "scale_bar_length"]

SCALE_BAR_STEPS: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)
"""Lengths a scale bar can show [m]: the longest that fits in a quarter of the view's width is drawn."""

_SHIFT = 3  # fractional bits of OpenCV's sub-pixel coordinates
_BACKGROUND = (236, 236, 228)
_PATH = (150, 150, 150)
_KINGPIN_TRACK = (40, 90, 200)
_FOLLOW_TRACK = (220, 110, 20)
_TRACTOR = (60, 80, 140)
_TRAILER = (200, 140, 60)
_AXLE = (200, 30, 30)
_TEXT = (20, 20, 20)


class _Canvas:
    def __init__(self, size: tuple[int, int], centre: np.ndarray, span: float) -> None:
        self.height, self.width = size
        self.image = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self.image[:] = _BACKGROUND
        self.scale = self.width / span
        self.centre = centre

    def pixels(self, points: np.ndarray) -> np.ndarray:
        """World points ``(N, 2)`` [m] → OpenCV sub-pixel coordinates ``(N, 1, 2)`` int32."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        col = (p[:, 0] - self.centre[0]) * self.scale + 0.5 * self.width
        row = 0.5 * self.height - (p[:, 1] - self.centre[1]) * self.scale
        fixed = np.column_stack([col, row]) * (1 << _SHIFT)
        return np.clip(np.round(fixed), -(2**28), 2**28).astype(np.int32).reshape(-1, 1, 2)

    def line(self, points: np.ndarray, colour: tuple[int, int, int], thickness: int = 1) -> None:
        if len(points) >= 2:
            cv2.polylines(self.image, [self.pixels(points)], False, colour, thickness, cv2.LINE_AA, _SHIFT)

    def polygon(self, points: np.ndarray, colour: tuple[int, int, int]) -> None:
        pts = self.pixels(points)
        cv2.fillPoly(self.image, [pts], colour, cv2.LINE_AA, _SHIFT)
        cv2.polylines(self.image, [pts], True, (30, 30, 30), 1, cv2.LINE_AA, _SHIFT)

    def dot(self, point: np.ndarray, colour: tuple[int, int, int], radius: int = 3) -> None:
        centre = tuple(int(v) for v in self.pixels(point)[0, 0])
        cv2.circle(self.image, centre, radius << _SHIFT, colour, -1, cv2.LINE_AA, _SHIFT)

    def scale_bar(self) -> None:
        """A bar of a round length at the bottom left, labelled in metres."""
        length = scale_bar_length(self.width / self.scale)
        px = length * self.scale
        x0, y = 10, self.height - 12
        x1 = round(x0 + px)
        cv2.line(self.image, (x0, y), (x1, y), _TEXT, 2, cv2.LINE_AA)
        for x in (x0, x1):
            cv2.line(self.image, (x, y - 4), (x, y + 4), _TEXT, 1, cv2.LINE_AA)
        label = f"{length:g} m"
        cv2.putText(self.image, label, (x0, y - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.4, _TEXT, 1, cv2.LINE_AA)

    def text(self, lines: Sequence[str]) -> None:
        for i, line in enumerate(lines):
            cv2.putText(self.image, line, (6, 16 + 15 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.42, _TEXT, 1, cv2.LINE_AA)


def draw_plan_view(
    params: VehicleParams,
    state: VehicleState,
    path_points: np.ndarray,
    *,
    kingpin_track: np.ndarray | None = None,
    follow_track: np.ndarray | None = None,
    trailer_steer: Sequence[float] = (),
    trailer_axles: Sequence[str] = (),
    centre: np.ndarray | None = None,
    span: float = 50.0,
    size: tuple[int, int] = (400, 400),
    text: Sequence[str] = (),
    scale_bar: bool = True,
) -> np.ndarray:
    """Plan view of the combination as an ``(height, width, 3)`` uint8 RGB image.

    Parameters
    ----------
    params
        The combination.
    state
        Its state.
    path_points
        The reference path ``(N, 2)`` [m].
    kingpin_track, follow_track
        Past positions ``(M, 2)`` [m] of the kingpin and of the follow point.
    trailer_steer, trailer_axles
        Steer [rad] of the named steerable trailer axles (drawn as short red lines).
    centre
        World point [m] at the image centre (default: the middle of the trailer).
    span
        Width of the view [m].
    size
        ``(height, width)`` [px].
    text
        Lines written at the top left.
    scale_bar
        Draw a scale bar (:func:`scale_bar_length`) at the bottom left.
    """
    psi2 = state.psi2
    if centre is None:  # midway between the kingpin and the follow point
        midway = np.array([[-0.5 * params.follow_point_offset, 0.0]])
        centre = trailer_points(params, state.X, state.Y, state.psi1, state.gamma, midway)[0]
    canvas = _Canvas(size, np.asarray(centre, dtype=float), span)
    canvas.line(path_points, _PATH, 2)
    if kingpin_track is not None:
        canvas.line(kingpin_track, _KINGPIN_TRACK)
    if follow_track is not None:
        canvas.line(follow_track, _FOLLOW_TRACK)
    canvas.polygon(trailer_outline(params, state.X, state.Y, state.psi1, state.gamma), _TRAILER)
    further = params.n_units > 2
    if further:  # the units behind the first towed one
        for outline in towed_outlines(params, state.X, state.Y, state.psi1, state.articulations)[1:]:
            canvas.polygon(outline, _TRAILER)
    canvas.polygon(tractor_outline(params, state.X, state.Y, state.psi1), _TRACTOR)
    axles = {a.name: a for a in params.trailer.axles}
    half = 0.5 * params.trailer.width
    frames = trailer_frames(params, state.X, state.Y, state.psi1, state.articulations) if further else []
    behind = {a.name: (k, a) for k, unit in enumerate(params.trailers) if k > 0 for a in unit.axles}
    for name, steer in zip(trailer_axles, trailer_steer, strict=False):
        if name in behind:
            k, axle = behind[name]
            origin, unit_heading = frames[k]
            unit_half = 0.5 * params.trailers[k].width
            heading = float(unit_heading) + float(steer)
            dx, dy = 0.6 * math.cos(heading), 0.6 * math.sin(heading)
            for side in (-unit_half, unit_half):
                p = place_points(origin, unit_heading, np.array([[axle.x, side]]))[0]
                canvas.line(np.array([[p[0] - dx, p[1] - dy], [p[0] + dx, p[1] + dy]]), _AXLE, 2)
            continue
        axle = axles[name]
        heading = psi2 + float(steer)
        dx, dy = 0.6 * math.cos(heading), 0.6 * math.sin(heading)
        for side in (-half, half):
            p = trailer_points(params, state.X, state.Y, state.psi1, state.gamma, np.array([[axle.x, side]]))[0]
            canvas.line(np.array([[p[0] - dx, p[1] - dy], [p[0] + dx, p[1] + dy]]), _AXLE, 2)
    canvas.dot(kingpin_position(params, state.X, state.Y, state.psi1), _KINGPIN_TRACK)
    if follow_track is not None and len(follow_track):
        canvas.dot(follow_track[-1], _FOLLOW_TRACK)
    canvas.text(text)
    if scale_bar:
        canvas.scale_bar()
    return canvas.image


def scale_bar_length(span: float) -> float:
    """The longest of :data:`SCALE_BAR_STEPS` [m] that fits in a quarter of a view ``span`` metres wide."""
    fitting = [s for s in SCALE_BAR_STEPS if s <= 0.25 * span]
    return fitting[-1] if fitting else SCALE_BAR_STEPS[0]


def check_render_mode(render_mode: Any, supported: Sequence[str]) -> None:
    """Refuse a render mode the environments do not have, ``"human"`` with what to do instead.

    Raises
    ------
    InputError
        ``render_mode`` neither ``None`` nor in ``supported``.
    """
    if render_mode is None or render_mode in supported:
        return
    if render_mode == "human":
        raise InputError(
            "render_mode = 'human' is not supported: the co-simulation runs headless and opens no window; use "
            "render_mode='rgb_array' and show the frames yourself (e.g. matplotlib's imshow, or wrap the env "
            "in gymnasium.wrappers.HumanRendering, which needs pygame)"
        )
    raise InputError(f"render_mode = {render_mode!r} must be one of {list(supported)} or None")


def camera_strip(grey: np.ndarray, width: int) -> np.ndarray:
    """A grey camera image scaled to ``width`` pixels as RGB uint8 (to stack under a plan view)."""
    h, w = grey.shape[:2]
    height = max(1, round(h * width / w))
    small = cv2.resize(grey, (width, height), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(small, cv2.COLOR_GRAY2RGB)
