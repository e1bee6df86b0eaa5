"""How far refined checkerboard corners land from their true projections, by the rule that sizes ``cornerSubPix``'s
window: one window per corner (the default), one per view (a third of its smallest spacing), or a fixed window.

Rendered 9×6 boards of 25 mm squares (``sensor.calibration_target``: a ray-cast, 640×480, f = 540 px, no lens)
tilted 60° about a random in-plane axis and rolled up to ±30°, 0.35–0.5 m away, σ 0.8 px Gaussian blur and 2 grey
levels of noise; the corners ``cv2.findChessboardCorners`` finds are refined by each rule and compared with the
board's projected corners. Prints one JSON object: the RMS and max error [px] and the mean outward error per rule.

    python benchmarks/corner_windows.py [--views 12] [--seed 0] [--fixed 5]
"""

from __future__ import annotations

import argparse
import json
import math

import cv2
import numpy as np

from sensor.board_calibration import BoardPattern, corner_window_for, corner_windows, refine_corners
from sensor.calibration_target import Board, Camera, _rotation_about
from sensor.camera import Lens


def measure(views: int, seed: int, fixed: int) -> dict[str, object]:
    """Corner errors of ``views`` rendered views per window rule (module docstring)."""
    rng = np.random.default_rng(seed)
    camera = Camera.build(np.array([[540.0, 0, 320], [0, 540.0, 240], [0, 0, 1]]), Lens(), 640, 480)
    board = Board(9, 6, 0.025)
    pattern = BoardPattern(cols=9, rows=6, square=0.025)
    errors: dict[str, list[np.ndarray]] = {"per_corner": [], "per_view": [], f"fixed_{fixed}px": []}
    outward: dict[str, list[np.ndarray]] = {name: [] for name in errors}
    tries = 0
    while len(errors["per_corner"]) < views and tries < 20 * views:
        tries += 1
        axis = rng.uniform(0.0, 360.0)
        rot = _rotation_about(
            np.array([math.cos(math.radians(axis)), math.sin(math.radians(axis)), 0.0]), math.radians(60.0)
        )
        rot = rot @ _rotation_about(np.array([0.0, 0.0, 1.0]), math.radians(rng.uniform(-30.0, 30.0)))
        pose = np.eye(4)
        pose[:3, :3] = rot
        pose[:3, 3] = np.array([0.0, 0.0, rng.uniform(0.35, 0.5)]) - rot @ board.centre
        if not camera.sees(pose, board, 8.0):
            continue
        image = cv2.GaussianBlur(camera.render(pose, board, noise_std=2.0, rng=rng), (0, 0), 0.8)
        truth = camera.project(pose, board.object_points())
        found, rough = cv2.findChessboardCorners(
            image, (9, 6), flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        )
        if not found:
            continue
        rough = rough.reshape(-1, 2).astype(float)
        if np.linalg.norm(rough[0] - truth[0]) > np.linalg.norm(rough[-1] - truth[0]):
            rough = rough[::-1]
        away = truth - truth.mean(axis=0)
        away /= np.linalg.norm(away, axis=1)[:, None]
        windows = {
            "per_corner": corner_windows(rough, pattern),
            "per_view": np.full(len(rough), corner_window_for(rough, pattern)),
            f"fixed_{fixed}px": np.full(len(rough), fixed),
        }
        for name, window in windows.items():
            refined = refine_corners(image, rough, window)
            errors[name].append(np.linalg.norm(refined - truth, axis=1))
            outward[name].append(np.sum((refined - truth) * away, axis=1))
    out: dict[str, object] = {"benchmark": "corner_windows", "views": len(errors["per_corner"]), "seed": seed}
    for name, runs in errors.items():
        err = np.concatenate(runs)
        out[name] = {
            "rms_px": float(np.sqrt(np.mean(err**2))),
            "max_px": float(err.max()),
            "mean_outward_px": float(np.mean(np.concatenate(outward[name]))),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=12)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fixed", type=int, default=5, help="the fixed window's half-size [px]")
    args = parser.parse_args()
    print(json.dumps(measure(args.views, args.seed, args.fixed)))


if __name__ == "__main__":
    main()
