"""Scenery density 0 keeps the rear camera's visual odometry unbiased.

The constant-slip case of de Saxe & Cebon 2018, §3, with no roadside objects: without the landscape and the
ground detail (:mod:`sensor.world.landscape`, :mod:`sensor.world.detail`) the rear camera sees only near
ground, and VISO2's per-frame motion carries a yaw bias of about −0.46 mrad and a lateral bias of +5.3 mm
(≈ 4 % of the lateral motion) that nearly cancel in the image but add up to −0.24 m of
off-tracking error. With distant features the yaw is pinned.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

FRAMES = 40
"""Frame pairs (4 s of the 10 fps camera)."""

MAX_YAW_BIAS = 0.2e-3
"""Bound on the mean per-frame yaw error [rad] (about half the bias without the landscape)."""

MAX_LATERAL_BIAS = 2.5e-3
"""Bound on the mean per-frame lateral (camera x) translation error [m] (the true motion is ~0.12 m)."""


@pytest.mark.rendering
def test_density_zero_rear_camera_vo_bias_is_bounded() -> None:
    from scenarios.camera.build import rig_from_config, world_for_scenario
    from scenarios.config import load_scenario
    from scenarios.loop.trailer_steer import UnsteeredTrailer, trailer_axles
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario
    from sensor.renderer import StereoRenderer
    from sensor.vo import StereoOdometry, VOConfig
    from vehicle_model.geometry import CombinationPose

    # The overrides of the paper-section3 study's rear-camera slip case (scenarios.studies.definitions).
    overrides = {
        "estimators.viso_ot": False,  # the poses come from the kinematic run; VO is run here
        "estimators.zero_slip": False,
        "camera.psi_c2v_deg": 180.0,
        "camera.lateral": 0.0,
        "camera.baseline": 0.5,
        "path.slip_deg": 14.0,
        "camera.scenery_density": 0.0,
    }
    config = load_scenario("constant-slip", overrides)
    setup = build_scenario(config)
    _, cols = simulate(setup, UnsteeredTrailer(trailer_axles(setup)))
    rig = rig_from_config(config)
    renderer = StereoRenderer(world_for_scenario(setup), rig, setup.params, seed=config.seed)
    ticks = np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)[: FRAMES + 1]
    state = CombinationPose(*(np.asarray(cols[k])[ticks] for k in ("X", "Y", "psi1", "gamma")))
    left = rig.camera_in_world(setup.params, state, "left")
    right = rig.camera_in_world(setup.params, state, "right")
    vo = StereoOdometry(VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline), seed=0)
    errors = []
    for k in range(len(ticks)):
        pair = renderer.render_poses(left[k], right[k], frame=k)
        result = vo.process(pair.left, pair.right)
        if k == 0 or not result.valid:
            continue
        true = np.linalg.inv(np.linalg.solve(left[k], left[k - 1]))  # camera motion, frame k−1 → k
        est = np.linalg.inv(result.motion)
        yaw = cv2.Rodrigues(est[:3, :3])[0][1, 0] - cv2.Rodrigues(true[:3, :3])[0][1, 0]
        errors.append((yaw, est[0, 3] - true[0, 3]))
    assert len(errors) >= FRAMES - 2
    yaw_bias, lateral_bias = np.mean(errors, axis=0)
    assert abs(yaw_bias) < MAX_YAW_BIAS, (yaw_bias, lateral_bias)
    assert abs(lateral_bias) < MAX_LATERAL_BIAS, (yaw_bias, lateral_bias)
