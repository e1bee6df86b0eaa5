"""Refuse camera configurations that cannot give a visual-odometry estimate, before anything runs.

:func:`check_camera` is part of validating a scenario that runs a camera (:func:`scenarios.config.validate_config`),
so it runs once, before any work, whoever loads the configuration. :func:`check_camera_feasible` looks only at the
geometry of the ``camera`` section (it imports no renderer, no OpenGL and not the odometry itself);
:func:`check_lenses` refuses a lens model that folds over inside the image. Each raises
:class:`~vehicle_model.errors.InputError` with one line naming the field.

Reasoning
---------
The rig is a level pinhole pair (no tilt, :mod:`sensor.camera`) at height ``h`` = ``mount_height``,
focal length ``f = (width/2)/tan(hfov/2)``, principal row ``cv = (height − 1)/2``. Image row ``v``
below the horizon sees the ground at depth ``Z(v) = f·h/(v − cv)``; the nearest ground is on the
bottom row, ``Z_near = f·h/cv`` (8.7 m for the default 1344×391, 100°, 3 m rig), and its stereo
disparity is

    d_near = f·b/Z_near = b·cv/h        (independent of the focal length),

the largest disparity the road shows anywhere in the image (32.5 px for the default 0.5 m baseline).
Scenery is optional (``scenery_density`` 0 leaves only road, verges and fields), so the road must
carry the translation: its depth — and with it the scale of the motion — comes from the disparity
alone, with a relative error ``σ_d/d``. The matches are located to the pixel (``refinement`` 1 at full
resolution after matching at half resolution), so a disparity, the difference of two such
positions, has ``σ_d ≈ sqrt(2/12) ≈ 0.4 px``. The off-tracking target (0.10 m RMS over a 12–14 m
trailer) needs the translation's scale to better than about 1 %; averaged over the ~100 ground
matches of a frame that asks for ``σ_d/d ≤ 10 %`` per match, i.e.

    d ≥ MIN_ROAD_DISPARITY_PX = 4 px

over the near road. Below about 1 px a disparity cannot be told from zero at all (0.65 px for a
0.01 m baseline: every point is "at infinity" and the translation is a guess). The check asks the
bottom row for 4 px, so ``baseline ≥ 4·h/cv`` (0.062 m for the default rig).

The second check is the number of matches the image can hold at all: bucketing keeps at most 2
matches per 50×50 px bucket, and the odometry refuses a motion with fewer than 30 inliers; an image
whose buckets cannot hold twice that (half the image is sky or gets lost to outliers) cannot work.

Large baselines are not refused: near-road disparities then exceed the stereo search range, but far
ground and scenery still match (the paper's sweep goes to 2.5–5 m). A world without any texture is
not refused either — that is not a property of the camera; such a run reports its frames as refused
(``too_few_matches``) and gives no estimate. In this world the ground is always textured (road,
verges and fields are textured even at ``scenery_density`` 0), so density 0 runs normally.
"""

from __future__ import annotations

import math

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from .camera_schema import MAX_RENDER_PX, CameraConfig, StereoRigConfig, rig_configs

__all__ = [
    "MIN_ROAD_DISPARITY_PX",
    "check_camera",
    "check_camera_feasible",
    "check_lenses",
    "check_rigs",
    "nearest_road_disparity",
]

#: Disparity [px] the odometry needs on the nearest visible road (module notes).
MIN_ROAD_DISPARITY_PX = 4.0
#: Bucketing of the final matches (``VOConfig`` defaults: 50×50 px buckets, 2 matches each).
_BUCKET_PX, _PER_BUCKET = 50.0, 2
#: Inliers the odometry needs to accept a motion (``VOConfig.quality_min_inliers``).
_MIN_INLIERS = 30


def nearest_road_disparity(width: int, height: int, hfov_deg: float, baseline: float, mount_height: float) -> float:
    """Stereo disparity [px] of the ground seen by the bottom image row of a level rig.

    Parameters
    ----------
    width, height : int
        Image size [px].
    hfov_deg : float
        Horizontal field of view [deg].
    baseline : float
        Stereo baseline [m].
    mount_height : float
        Height of the cameras above the ground [m].

    Returns
    -------
    float
        ``f·b/Z_near`` with ``Z_near = f·h/cv``, i.e. ``b·cv/h`` (``cv = (height − 1)/2``).
    """
    f = 0.5 * width / math.tan(math.radians(0.5 * hfov_deg))
    cv = 0.5 * (height - 1)
    z_near = f * mount_height / cv
    return f * baseline / z_near


def check_camera(camera: CameraConfig, params: VehicleParams | None = None) -> None:
    """Refuse a camera that cannot work: :func:`check_rigs` (with the combination), then every rig's
    :func:`check_camera_feasible` and :func:`check_lenses` (the section itself without ``params``)."""
    if params is None:
        check_camera_feasible(camera)
        check_lenses(camera)
        return
    check_rigs(camera, params)
    for index, rig in enumerate(rig_configs(camera, params)):
        field = "camera" if camera.rigs is None else f"camera.rigs[{index}]"
        check_camera_feasible(rig, field)
        check_lenses(rig, field)


def check_rigs(camera: CameraConfig, params: VehicleParams) -> None:
    """Refuse rigs the combination cannot carry, in one line naming the field: a unit it does not have, two rigs on
    one unit (each unit's camera estimate is its one rig's), or none on the first towed unit (whose estimate every
    camera estimator gives).

    Raises
    ------
    InputError
        ``camera.rigs[i].unit`` out of range or taken, or ``camera.rigs`` without unit 1.
    """
    towed = params.n_units - 1
    seen: dict[int, int] = {}
    for index, rig in enumerate(camera.rigs or ()):
        if not 1 <= rig.unit <= towed:
            raise InputError(f"camera.rigs[{index}].unit = {rig.unit}: a towed unit of {params.name!r}, 1 to {towed}")
        if rig.unit in seen:
            raise InputError(
                f"camera.rigs[{index}].unit = {rig.unit}: unit {rig.unit} has a rig already (camera.rigs"
                f"[{seen[rig.unit]}]); one rig per towed unit"
            )
        seen[rig.unit] = index
        side = max(rig.width or camera.width, rig.height or camera.height)
        samples = rig.supersample or camera.supersample
        if side * samples > MAX_RENDER_PX:
            raise InputError(
                f"camera.rigs[{index}].supersample = {samples}: width and height × supersample ≤ {MAX_RENDER_PX} px "
                f"(the rendered size), here {side} px"
            )
    if camera.rigs is not None and 1 not in seen:
        raise InputError("camera.rigs: no rig on towed unit 1; the camera estimators need one on the first towed unit")


def check_lenses(camera: StereoRigConfig, field: str = "camera") -> None:
    """Refuse a lens whose model folds over inside the image (one line naming ``camera.lens`` or ``right_lens``)."""
    left, right = camera.lens_pair()
    if left.is_zero and right.is_zero:
        return
    from sensor.camera import StereoRig  # numeric checks only when there is a lens
    from sensor.lens import check_invertible

    k = StereoRig.from_degrees(hfov_deg=camera.hfov_deg, width=camera.width, height=camera.height).intrinsics()
    named = ((left, f"{field}.lens"), (right, f"{field}.right_lens" if camera.right_lens else f"{field}.lens"))
    for lens, name in named:
        if not lens.is_zero:
            check_invertible(k, lens, camera.width, camera.height, name)


def check_camera_feasible(camera: StereoRigConfig, field: str = "camera") -> None:
    """Raise :class:`InputError` if the stereo camera cannot support visual odometry.

    Parameters
    ----------
    camera : StereoRigConfig
        The scenario's ``camera`` section, or one of its rigs (module notes give the reasoning).
    field : str
        Its name in the configuration (``camera``, ``camera.rigs[1]``).

    Raises
    ------
    InputError
        One line naming the field, the value, what it gives and what is needed.
    """
    cam = camera
    cv = 0.5 * (cam.height - 1)
    f = 0.5 * cam.width / math.tan(math.radians(0.5 * cam.hfov_deg))
    z_near = f * cam.mount_height / cv
    disparity = nearest_road_disparity(cam.width, cam.height, cam.hfov_deg, cam.baseline, cam.mount_height)
    capacity = _PER_BUCKET * math.ceil(cam.width / _BUCKET_PX) * math.ceil(cam.height / _BUCKET_PX)
    if capacity < 2 * _MIN_INLIERS:
        raise InputError(
            f"{field}.width × {field}.height = {cam.width}×{cam.height} px holds at most {capacity} matches "
            f"({_PER_BUCKET} per {_BUCKET_PX:g} px bucket); VO needs ≥ {_MIN_INLIERS} inliers: use an image of "
            f"at least {2 * _MIN_INLIERS // _PER_BUCKET} buckets, e.g. 400×200 px"
        )
    if disparity < MIN_ROAD_DISPARITY_PX:
        need = MIN_ROAD_DISPARITY_PX * cam.mount_height / cv
        raise InputError(
            f"{field}.baseline = {cam.baseline:g} m gives at most {disparity:.2g} px of disparity on the road "
            f"{z_near:.1f} m behind the camera; VO needs ≥ {MIN_ROAD_DISPARITY_PX:g} px: use a baseline "
            f"≥ {math.ceil(need * 1000.0) / 1000.0:g} m (or a lower {field}.mount_height)"
        )
