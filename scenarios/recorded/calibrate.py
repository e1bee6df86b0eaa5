"""``offtrack calibrate --images DIR`` (or ``--left GLOB --right GLOB``): a real stereo camera calibrated from photos.

:func:`calibrate_from_photos` runs :func:`sensor.board_calibration.calibrate_photos` and writes into the output
directory

* ``calibration.yaml`` — the OpenCV YAML a run (``camera.calibration.mode: file``) and ``offtrack estimate
  --calibration`` load (:meth:`sensor.calibration.CalibrationResult.write`);
* ``residuals.json`` — the residual report: RMS per camera and stereo, every view with its files, whether it was
  used and why not, its RMS per camera and in the stereo calibration, the rejections counted by reason, the
  corner coverage of each image, the intrinsics and the rectified focal length, principal point and baseline;
* ``calibration.png`` — the corner coverage and the per-view errors (:mod:`.calibration_figure`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rich.markup import escape
from rich.table import Table

from sensor.board_calibration import BoardPattern, PhotoCalibration, calibrate_photos
from sensor.photo_pairs import check_images, check_photo_size, stereo_pairs
from vehicle_model.errors import InputError

from ..run.json_output import write_json
from .calibration_figure import corner_coverage, plot_calibration

CALIBRATION_FILE = "calibration.yaml"
RESIDUALS_FILE = "residuals.json"
FIGURE_FILE = "calibration.png"


def calibrate_from_photos(
    out: Path,
    pattern: BoardPattern,
    *,
    images: Path | None = None,
    left: str | None = None,
    right: str | None = None,
    min_views: int = 5,
    alpha: float = 0.0,
    corner_window: int | None = None,
    reject_outliers: bool = True,
    plots: bool = True,
) -> tuple[PhotoCalibration, dict[str, Any]]:
    """Calibrate from photos and write the calibration, the residual report and the figure into ``out``.

    Parameters
    ----------
    out : Path
        The output directory (exists).
    pattern : BoardPattern
        The board.
    images, left, right
        A folder of photos, or glob patterns of the left and the right ones
        (:func:`sensor.photo_pairs.stereo_pairs`).
    min_views, alpha, corner_window, reject_outliers
        As :func:`sensor.board_calibration.calibrate_photos`.
    plots : bool
        Draw ``calibration.png``.

    Returns
    -------
    (PhotoCalibration, dict)
        The calibration and the residual report written to ``residuals.json``.

    Raises
    ------
    InputError
        Bad input (files, sizes, pairs, too few views), one line naming the files.
    """
    pairs = stereo_pairs(images, left, right)
    calibration = calibrate_photos(
        pairs, pattern, min_views=min_views, alpha=alpha, corner_window=corner_window, reject_outliers=reject_outliers
    )
    calibration.result.write(out / CALIBRATION_FILE)
    report = calibration.summary()
    report["coverage"] = {side: corner_coverage(calibration, side)[0] for side in ("left", "right")}
    report["notes"] = calibration.notes
    write_json(out / RESIDUALS_FILE, report)
    if plots:
        plot_calibration(out / FIGURE_FILE, calibration)
    return calibration, report


def board_pattern(
    corners: str, *, pattern: str, square: float, marker: float | None = None, dictionary: str = "DICT_4X4_50"
) -> BoardPattern:
    """The board from the command line's ``--corners COLSxROWS`` and the other board options (checked)."""
    try:
        cols, rows = (int(n) for n in corners.lower().split("x"))
    except ValueError:
        raise InputError(f"--corners {corners!r}: allowed: COLSxROWS inner corners, e.g. 9x6") from None
    return BoardPattern(pattern, cols, rows, square, marker, dictionary)  # type: ignore[arg-type]


def check_photos(images: Path | None, left: str | None, right: str | None, pattern: BoardPattern) -> None:
    """Refuse bad photos before any work: no pairs, a photo without a partner, a file not a whole image, mixed
    sizes, photos too small for the board."""
    size = check_images(stereo_pairs(images, left, right))
    check_photo_size(size, pattern.cols, pattern.rows, pattern.label)


def report_lines(calibration: PhotoCalibration, report: dict[str, Any], run_dir: Path) -> list[Any]:
    """What ``offtrack calibrate`` prints: a table of the views, the residuals and intrinsics, where the files are."""
    board = calibration.pattern
    table = Table(title=escape(f"{board.label}: {report['views_used']} of {report['views_given']} views used"))
    for column in ("left", "right", "corners", "RMS left [px]", "RMS right [px]", "stereo RMS [px]", "rejected"):
        table.add_column(escape(column), justify="left" if column in ("left", "right", "rejected") else "right")
    for view in calibration.views:
        table.add_row(
            escape(view.left.name),
            escape(view.right.name),
            str(view.corners),
            f"{view.rms_left:.3f}" if view.used else "",
            f"{view.rms_right:.3f}" if view.used else "",
            f"{view.rms_stereo[0]:.3f} / {view.rms_stereo[1]:.3f}" if view.used else "",
            escape(view.reason),
        )
    rms, k = report["rms_px"], report["left"]
    lines: list[Any] = [
        table,
        f"reprojection RMS left {rms['left']:.3f} px, right {rms['right']:.3f} px, stereo {rms['stereo']:.3f} px; "
        f"left f {k['fx']:.2f} / {k['fy']:.2f} px, principal point ({k['cx']:.2f}, {k['cy']:.2f}) px; "
        f"baseline {1e3 * report['baseline_m']:.2f} mm; corner coverage left {report['coverage']['left']:.0%}, "
        f"right {report['coverage']['right']:.0%}",
    ]
    lines += [escape(f"note: {note}") for note in report["notes"]]
    lines.append(escape(f"calibration → {run_dir / CALIBRATION_FILE}; residuals → {run_dir / RESIDUALS_FILE}"))
    return lines
