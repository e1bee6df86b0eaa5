"""Marks on a plan view that locate a turn: the roundabout test's limit circles with labels placed where the run
drew nothing, and an arrow at the edge of a zoom pointing towards the turn centre.

Used by the swept-path figure (:mod:`.swept_path`), the comparison figure and the animation.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.axes import Axes

from .metrics import ROUNDABOUT_INNER_RADIUS, ROUNDABOUT_OUTER_RADIUS

__all__ = ["LIMIT_COLOURS", "draw_circles", "free_angle", "mark_turn_centre", "towards_turn_centre"]

LIMIT_COLOURS = {"outer": "darkorange", "inner": "darkviolet"}
"""Colours of the roundabout test's outer (12.50 m) and inner (5.30 m) limit circles."""


def free_angle(
    centre: tuple[float, float],
    points: np.ndarray,
    avoid: list[np.ndarray] | tuple = (),
    clear: list[np.ndarray] | tuple = (),
) -> float:
    """The direction [rad] from ``centre`` least crowded by ``points`` ``(n, 2)`` and farthest from ``avoid``.

    Where a label on a circle about ``centre`` collides with nothing the run drew: candidates every 10°, the
    fewest points within ±20°, ties broken by the largest angle to the directions of ``avoid`` (points). Candidates
    within ±20° of the direction of a point of ``clear`` are taken only when there is no other.
    """
    c = np.asarray(centre, dtype=float)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    candidates = np.radians(np.arange(0.0, 360.0, 10.0))
    angles = np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0])

    def gap(a: np.ndarray, b: float) -> np.ndarray:
        return np.abs((a - b + np.pi) % (2.0 * np.pi) - np.pi)

    crowd = np.array([np.count_nonzero(gap(angles, a) < np.radians(20.0)) for a in candidates])
    for q in (np.asarray(q, dtype=float) for q in clear):
        crowd[gap(candidates, float(np.arctan2(q[1] - c[1], q[0] - c[0]))) < np.radians(20.0)] += len(pts) + 1
    away = [np.arctan2(p[1] - c[1], p[0] - c[0]) for p in (np.asarray(q, dtype=float) for q in avoid)]
    spread = np.array([min((gap(np.array([a]), b)[0] for b in away), default=np.pi) for a in candidates])
    best = np.lexsort((-spread, crowd))[0]
    return float(candidates[best])


def draw_circles(
    ax: Axes, centre: tuple[float, float], label_angle: float | None = None, *, fontsize: float = 8
) -> dict[str, Any]:
    """The roundabout test's 12.50 m (outer) and 5.30 m (inner) circles, each in its colour with its label.

    Lines carry the ``gid`` ``limit:outer`` and ``limit:inner`` and a legend label. With ``label_angle`` [rad]
    each circle is also labelled in place at that direction: the outer one just outside it, the inner one just
    inside it, so that neither label sits on the swept annulus between them (``limit:outer:label``,
    ``limit:inner:label``).
    """
    a = np.linspace(0.0, 2.0 * np.pi, 721)
    lines: dict[str, Any] = {}
    for key, radius, words in (
        ("outer", ROUNDABOUT_OUTER_RADIUS, "tractor stays inside"),
        ("inner", ROUNDABOUT_INNER_RADIUS, "trailer stays outside"),
    ):
        colour = LIMIT_COLOURS[key]
        (line,) = ax.plot(
            centre[0] + radius * np.cos(a),
            centre[1] + radius * np.sin(a),
            color=colour,
            lw=1.5,
            ls="-" if key == "outer" else (0, (6, 2)),
            zorder=5,  # over the vehicle drawn at the critical instant
            label=f"{key} limit {radius:.2f} m ({words})",
        )
        line.set_gid(f"limit:{key}")
        lines[key] = line
        if label_angle is not None:
            direction = np.array([np.cos(label_angle), np.sin(label_angle)])
            offset = 0.4 if key == "outer" else -0.4
            at = np.asarray(centre) + (radius + offset) * direction
            sense = direction if key == "outer" else -direction  # text extends away from the swept annulus
            text = ax.text(
                *at,
                f"{radius:.2f} m",
                color=colour,
                fontsize=fontsize,
                fontweight="bold",
                ha="left" if sense[0] > 0.3 else "right" if sense[0] < -0.3 else "center",
                va="bottom" if sense[1] > 0.3 else "top" if sense[1] < -0.3 else "center",
                zorder=8,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8},
            )
            text.set_gid(f"limit:{key}:label")
    ax.plot(*centre, "k+", ms=8, zorder=2)
    return lines


def towards_turn_centre(
    columns: dict[str, np.ndarray], k: int, point: np.ndarray, centre: tuple[float, float] | None, sign: int
) -> np.ndarray:
    """Unit vector from ``point`` towards the turn centre: the test circles' centre, or else the side the tractor
    yaws towards at sample ``k`` (its yaw rate's sign; the run's turn direction where it does not yaw)."""
    if centre is not None:
        towards = np.asarray(centre, dtype=float) - np.asarray(point, dtype=float)
        norm = float(np.hypot(*towards))
        if norm > 0.0:
            return towards / norm
    yaw_rate = float(columns["r1"][k]) if "r1" in columns else 0.0
    side = float(np.sign(yaw_rate)) if abs(yaw_rate) > 1e-6 else float(sign or 1)
    psi = float(columns["psi1"][k])
    return side * np.array([-np.sin(psi), np.cos(psi)])


def mark_turn_centre(ax: Axes, direction: np.ndarray) -> None:
    """An arrow at the edge of a zoom pointing towards the turn centre (``gid`` ``turn-centre``)."""
    d = np.asarray(direction, dtype=float)
    tip, tail = 0.5 + 0.46 * d, 0.5 + 0.30 * d
    arrow = ax.annotate(
        "turn centre",
        xy=tuple(tip),
        xytext=tuple(tail),
        xycoords="axes fraction",
        textcoords="axes fraction",
        ha="center",
        va="center",
        fontsize=7,
        color="0.25",
        arrowprops={"arrowstyle": "->", "color": "0.25", "lw": 1.0},
        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85},
        zorder=8,
    )
    arrow.set_gid("turn-centre")
