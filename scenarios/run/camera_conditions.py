"""Whether a run's camera was ideal or under field conditions, in words for tables and summaries.

The ideal camera is the paper's simulated one (de Saxe & Cebon 2018, §3): pinhole, an exact calibration, flat
light, the roadside world, a rigid mount and an aligned right camera, every one the configuration's default. Any
part changed from its default is a field condition (docs/camera.md), named here.
"""

from __future__ import annotations

from typing import Any

__all__ = ["CAMERA_FEEDBACKS", "FIELD_PARTS", "camera_conditions"]

CAMERA_FEEDBACKS = ("viso_ot", "viso_ot_fused")
"""The feedback sources that steer on the rendered camera."""

FIELD_PARTS: dict[str, str] = {
    "lens": "lens",
    "right_lens": "lens",
    "flex": "mount flex",
    "lighting": "low sun",
    "world": "airfield",
    "right_misalignment_deg": "misaligned right camera",
}
"""Camera fields whose change from the default is a field condition, and its name."""


def camera_conditions(camera: Any) -> str:
    """``ideal``, or ``field (…)`` naming each part that is not ideal (an estimated calibration among them).

    Parameters
    ----------
    camera : scenarios.camera_schema.CameraConfig
        A run's ``camera`` section.
    """
    default = type(camera)()
    parts = [words for field, words in FIELD_PARTS.items() if getattr(camera, field) != getattr(default, field)]
    if camera.calibration.mode != "ideal":
        parts.append(f"{camera.calibration.mode} calibration")
    return "ideal" if not parts else "field (" + ", ".join(dict.fromkeys(parts)) + ")"
