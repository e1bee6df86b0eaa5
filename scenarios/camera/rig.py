"""The stereo rig of a scenario, from the ``camera`` section of its configuration (degrees at this edge)."""

from __future__ import annotations

import math
from typing import Any

from sensor.camera import StereoRig
from vehicle_model.parameters import VehicleParams

from ..config import ScenarioConfig


def rig_from_config(config: ScenarioConfig | Any) -> StereoRig:
    """The stereo rig of a scenario's ``camera`` section (degrees at this edge, SI inside).

    Parameters
    ----------
    config : ScenarioConfig or CameraConfig
        A scenario configuration (its ``camera``) or the camera section itself; a configuration
        without one gives the default rig (paper §3.1).
    """
    camera = getattr(config, "camera", config)
    if camera is None or not hasattr(camera, "psi_c2v_deg"):
        return StereoRig()
    roll, pitch, yaw = getattr(camera, "right_misalignment_deg", (0.0, 0.0, 0.0))
    return StereoRig.from_degrees(
        hfov_deg=camera.hfov_deg,
        psi_c2v_deg=camera.psi_c2v_deg,
        roll_deg=roll,
        pitch_deg=pitch,
        yaw_deg=yaw,
        width=camera.width,
        height=camera.height,
        baseline=camera.baseline,
        station=camera.station,
        lateral=camera.lateral,
        mount_height=camera.mount_height,
        noise_std=getattr(camera, "noise_std", 0.0),
        exposure_std=getattr(camera, "brightness_jitter", 0.0),
    )


def rig_summary(rig: StereoRig, params: VehicleParams | None = None) -> dict[str, Any]:
    """The rig's settings with angles in degrees (for files people read)."""
    return {
        "width": rig.width,
        "height": rig.height,
        "hfov_deg": math.degrees(rig.hfov),
        "focal_px": rig.focal_length,
        "baseline_m": rig.baseline,
        "station_m": rig.resolve_station(params) if (rig.station is not None or params is not None) else None,
        "lateral_m": rig.lateral,
        "mount_height_m": rig.mount_height,
        "psi_c2v_deg": math.degrees(rig.psi_c2v),
        "misalignment_deg": {
            "roll": math.degrees(rig.misalignment.roll),
            "pitch": math.degrees(rig.misalignment.pitch),
            "yaw": math.degrees(rig.misalignment.yaw),
        },
        "noise_std": rig.noise_std,
        "exposure_std": rig.exposure_std,
    }
