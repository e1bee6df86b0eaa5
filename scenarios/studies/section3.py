"""The ``paper-section3`` study: de Saxe & Cebon 2018 §3, the constant-slip straight under the camera sweeps.

The constant-slip straight (5 m/s, 10 fps, 100 m, the 14.05 m LST as the paper's 14 m trailer) over the baseline
sweep for rear and side cameras at 14° slip (Fig 6), the slip sweep at baselines 0.5/1.5/2.5 m (Fig 7) and the
scenery densities 100/50/0 % (Fig 8). Each case is a plain :func:`~scenarios.studies.cases.run_case`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .records import CaseSpec

# de Saxe & Cebon 2018 §3.2, values stated in the text (the figures themselves are not reproduced there).
PAPER_SECTION3 = {
    "rms_error_m": "0.01–0.04 for baselines < 2.5 m (rear and side); 0.02–0.04 at 2.5 m (rear, slip < 16°)",
    "mean_error_m": "≈ 0.01 (≤ 0.01 at 0.5 and 1.5 m; up to 0.035 at 2.5 m)",
    "mean_matches": "≈ 380 at 0.5 m, ≈ 325 at 1.5 m, ≈ 250 at 2.5 m (rear); fewer for side cameras",
}

SECTION3_COLUMNS = (
    "status",
    "viso_ot_rms_error_m",
    "viso_ot_mean_error_m",
    "viso_ot_max_abs_error_m",
    "mean_matches",
    "mean_inliers",
    "inlier_percent",
    "viso_ot_valid_fraction",
    "failed_frames",
)
"""The study's terminal columns: VISO-OT's error against the truth and the matches and inliers behind it (the
quantities of the paper's Figs 6–8); the true off-tracking of the crabbing straight is the same in every case and
is left to ``table.md``."""


def _camera(kind: str) -> tuple[tuple[str, Any], ...]:
    # Rear: centred on the rear edge, looking back (ψ_c2v 180°). Side: on the left edge at the rear,
    # looking left (ψ_c2v 270°, as in the paper's field tests).
    if kind == "rear":
        return (("camera.psi_c2v_deg", 180.0), ("camera.lateral", 0.0))
    return (("camera.psi_c2v_deg", 270.0), ("camera.lateral", 1.275))


def paper_section3_cases(full: bool = False) -> list[CaseSpec]:
    """Cases of the reproduction of the paper's §3 (a subset unless ``full``)."""
    baselines = np.round(np.arange(0.5, 5.01, 0.5), 2) if full else (0.5, 1.5, 2.5)
    slips = (0, 2, 4, 6, 8, 10, 12, 14, 16, 20, 25, 30, 40, 50, 60) if full else (0, 14, 30)
    slip_baselines = (0.5, 1.5, 2.5) if full else (0.5,)
    densities = (1.0, 0.5, 0.0)
    cameras = ("rear", "side")
    cases: list[CaseSpec] = []
    base = (("estimators.viso_ot", True), ("estimators.zero_slip", False))

    def add(sweep: str, camera: str, baseline: float, slip: float, density: float) -> None:
        overrides = (
            *base,
            *_camera(camera),
            ("camera.baseline", float(baseline)),
            ("path.slip_deg", float(slip)),
            ("camera.scenery_density", float(density)),
        )
        labels = (
            ("sweep", sweep),
            ("camera", camera),
            ("baseline", float(baseline)),
            ("slip", float(slip)),
            ("density", float(density)),
        )
        cases.append(CaseSpec("paper-section3", "constant-slip", overrides, labels))

    for camera in cameras:
        for b in baselines:
            add("baseline", camera, b, 14.0, 1.0)
    for b in slip_baselines:
        for slip in slips:
            add("slip", "rear", b, slip, 1.0)
    for camera in cameras if full else ("rear",):
        for d in densities:
            add("scenery", camera, 0.5, 14.0, d)
    return cases
