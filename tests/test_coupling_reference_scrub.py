"""(C2') of sensor/fusion_coupling.py: the following unit's measurement's covariance widened by the follower's own
scrub demand ``D`` (``fusion.side_rig.coupling_scrub_scale``, ``k_s``).

On a hand-made frame: without the setting, with ``k_s`` = 0 or at ``D`` = 0 the increment and the covariance are
(C2)'s to the bit; the increment never changes; the covariance is ``(1 + k_s·D)`` times (C2)'s (1e-15 relative) and
grows strictly with ``D``; a bad ``k_s`` is refused naming the field, before any work; the setting is the
reference's (not given to the filter) and reaches the loop's reference.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from scenarios.configuration.sections import FusionConfig
from scenarios.loop.following_camera import following_camera
from sensor.camera import StereoRig
from sensor.fusion_coupling import CouplingReference
from sensor.fusion_noise import FusionNoise, SideRigFusion
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose
from vehicle_model.presets import VEHICLE_PRESETS

PARAMS = VEHICLE_PRESETS["au-b-double"]()
RIG = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
CAMERA = RIG.camera_in_trailer("left", PARAMS)
COVARIANCE = np.diag([1e-6, 4e-6, 1e-6, 1e-4, 1e-5, 1e-4])  # the follower camera's odometry covariance


def _pose(t: float) -> ChainPose:
    """A B-double turning and swinging (every articulation changes)."""
    angles = tuple(0.2 * math.sin(0.7 * t + k) + 0.05 * k for k in range(2))
    return ChainPose(3.0 * t + 0.4 * math.sin(t), 0.5 * t * t, 0.3 * t + 0.2 * math.sin(1.3 * t), angles)


def _frame(reference: CouplingReference, demand: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(C1)–(C2) of one frame with the follower's yaw error and, unless ``None``, its scrub demand."""
    a, b = _pose(1.0), _pose(1.2)
    motion = np.linalg.inv(RIG.camera_in_world(PARAMS, a, "left")) @ RIG.camera_in_world(PARAMS, b, "left")
    start, end = reference.articulations(a.angles), reference.articulations(b.angles)
    yaw_bias = (1e-3, 1e-6) if demand is None else (1e-3, 1e-6, demand)
    return reference.measurement(motion, COVARIANCE, start, end, yaw_bias)


def test_without_a_demand_or_a_scale_the_covariance_is_c2s_to_the_bit() -> None:
    """No setting (any ``D``), ``k_s`` = 0, or ``k_s`` = 5 at ``D`` = 0 or without a demand: the increment and the
    covariance equal those of a reference built without the setting, bit for bit."""
    plain = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise())
    assert plain.scrub_scale == 0.0
    for demand in (None, 0.0, 0.6, 1.0):
        z0, r0 = _frame(plain, demand)
        for scale in (0.0, 5.0):
            if scale > 0.0 and demand not in (None, 0.0):
                continue
            z, r = _frame(CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), scrub_scale=scale), demand)
            np.testing.assert_array_equal(z, z0)
            np.testing.assert_array_equal(r, r0)


def test_the_covariance_grows_with_the_followers_demand() -> None:
    """``k_s`` = 3: the increment unchanged to the bit; the covariance ``(1 + 3·D)`` times that of the reference
    without the setting at the same ``D`` (1e-15 relative), so 4 times at ``D`` = 1; its lateral variance grows
    strictly over ``D`` = 0, 0.1, …, 1."""
    plain = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise())
    wide = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), scrub_scale=3.0)
    lateral = []
    for demand in np.linspace(0.0, 1.0, 11):
        z0, r0 = _frame(plain, float(demand))
        z, r = _frame(wide, float(demand))
        np.testing.assert_array_equal(z, z0)
        np.testing.assert_allclose(r, (1.0 + 3.0 * demand) * r0, rtol=1e-15, atol=0.0)
        lateral.append(r[1, 1])
    assert np.all(np.diff(lateral) > 0.0)
    assert lateral[-1] / _frame(plain, 1.0)[1][1, 1] == pytest.approx(4.0, rel=1e-15)


def test_a_bad_scrub_scale_is_refused_naming_the_field() -> None:
    """``k_s`` below 0, above 100 or NaN: refused by the reference and by the settings, naming the field."""
    for bad in (-0.1, 101.0, math.nan):
        with pytest.raises(InputError, match="scrub_scale"):
            CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), scrub_scale=bad)
        with pytest.raises(ValidationError, match="coupling_scrub_scale"):
            SideRigFusion(coupling_scrub_scale=bad)


def test_the_scrub_scale_is_the_references_setting_and_reaches_the_loop() -> None:
    """``fusion.side_rig.coupling_scrub_scale`` is unset by default (``k_s`` = 0); set, it is not among the filter's
    settings, and the loop's reference takes it (from the section's noise, as ``coupling_covariance_scale``)."""
    assert FusionConfig().side_rig.reference_scrub_scale == 0.0
    side = SideRigFusion(coupling_reference=True, coupling_scrub_scale=2.0)
    assert "coupling_scrub_scale" not in side.given()
    assert FusionConfig(side_rig={"coupling_scrub_scale": 2.0}).side_rig.reference_scrub_scale == 2.0
    cameras = {"viso_ot3": SimpleNamespace(camera_in_trailer=CAMERA, released=[])}
    noise = FusionNoise(side_rig=side).for_camera((0.0, 1.0))
    assert following_camera(PARAMS, 1, cameras, noise, "planar").reference.scrub_scale == 2.0
    assert following_camera(PARAMS, 1, cameras, FusionNoise(), "planar").reference.scrub_scale == 0.0
