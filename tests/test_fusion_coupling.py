"""A following unit's camera as the reference of a side rig's filter (sensor/fusion_coupling.py, (C1)–(C2), and
scenarios/loop/following_camera.py).

The transport is checked against the rigid bodies' own poses; the filter on a straight where the whole combination
slides sideways at a constant slip angle (the zero-slip kinematics blind to it) while the lead unit's side camera
overstates its motion along its optical axis by a scale and a flow error (eq (3') of sensor/fusion_model.py).
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

import numpy as np
import pytest
from analytic_terrains import TiltedPlane

from scenarios.configuration.sections import FusionConfig
from scenarios.loop.following_camera import FollowingCamera, following_camera
from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, FusionNoise, TractorSignals
from sensor.fusion_coupling import CouplingReference, looks_along, transport_increment
from sensor.fusion_model import camera_increment, relative_pose
from sensor.fusion_noise import SideRigFusion
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose, unit_frame
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import VEHICLE_PRESETS
from vehicle_model.terrain_pose import unit_attitude

DT = 0.02  # control period [s]
EVERY = 5  # control ticks per camera frame


def _swinging(t: float, units: int) -> ChainPose:
    """A combination turning and swinging: every articulation changes, no unit moves as its tyres would let it."""
    angles = tuple(0.2 * math.sin(0.7 * t + k) + 0.05 * k for k in range(units))
    return ChainPose(3.0 * t + 0.4 * math.sin(t), 0.5 * t * t, 0.3 * t + 0.2 * math.sin(1.3 * t), angles)


def _increment(params, a: ChainPose, b: ChainPose, unit: int) -> np.ndarray:
    """The exact front-coupling increment of ``unit`` from pose ``a`` to ``b``, in its axes at ``a``."""
    (pa, ha), (pb, hb) = unit_frame(params, a, unit), unit_frame(params, b, unit)
    return np.array(relative_pose(np.array([*pa, ha]), np.array([*pb, hb])))


@pytest.mark.parametrize(("preset", "lead", "follower"), [("au-b-double", 1, 2), ("au-a-double", 1, 3)])
def test_the_transport_is_the_rigid_bodies_motion(preset, lead, follower):
    """(C1) gives the lead's exact kingpin increment from the follower's (to 1e-9 m, rad) over frames of a swinging
    turn, through the dolly of an A-double; from the follower's rear camera's exact motion too."""
    params = VEHICLE_PRESETS[preset]()
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=follower)
    camera = rig.camera_in_trailer("left", params)
    assert looks_along(camera)
    reference = CouplingReference(params, lead, follower, camera, FusionNoise())
    stations = [params.trailers[i - 1].fifth_wheel_x for i in range(lead, follower)]
    for t in np.arange(0.0, 6.0, 0.3):
        a, b = _swinging(t, follower), _swinging(t + 0.2, follower)
        start, end = reference.articulations(a.angles), reference.articulations(b.angles)
        truth = _increment(params, a, b, lead)
        moved = transport_increment(_increment(params, a, b, follower), stations, start, end)
        np.testing.assert_allclose(moved, truth, rtol=0.0, atol=1e-9)
        motion = np.linalg.inv(rig.camera_in_world(params, a, "left")) @ rig.camera_in_world(params, b, "left")
        z, r = reference.measurement(motion, np.eye(6) * 1e-8, start, end)
        np.testing.assert_allclose(z, truth, rtol=0.0, atol=1e-9)
        assert np.all(np.linalg.eigvalsh(r) > 0.0)
    assert np.max(np.abs(truth[:2])) > 0.3 and abs(truth[2]) > 0.01  # the frames move and turn


def test_the_followers_yaw_error_is_taken_out_as_its_filter_estimates_it():
    """(C0): with the follower's ``β̂_ψ`` the follower's increment is taken less ``d·β̂_ψ·(κc_x, κc_y, 1)`` before
    the transport (the lead's yaw increment less ``d·β̂_ψ`` exactly), its variance widens the covariance, and
    ``(0, 0)`` changes nothing to the bit."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    noise = FusionNoise()
    reference = CouplingReference(params, 1, 2, rig.camera_in_trailer("left", params), noise)
    a, b = _swinging(1.0, 2), _swinging(1.2, 2)
    motion = np.linalg.inv(rig.camera_in_world(params, a, "left")) @ rig.camera_in_world(params, b, "left")
    covariance = np.diag([1e-6, 4e-6, 1e-6, 1e-4, 1e-5, 1e-4])
    start, end = reference.articulations(a.angles), reference.articulations(b.angles)
    z, r = reference.measurement(motion, covariance, start, end)
    same = reference.measurement(motion, covariance, start, end, (0.0, 0.0))
    np.testing.assert_array_equal(same[0], z)
    np.testing.assert_array_equal(same[1], r)
    corrected, widened = reference.measurement(motion, covariance, start, end, (1e-3, 1e-6))
    follower, r_follower = camera_increment(reference.geometry, noise, motion, covariance)
    g = np.array([*(noise.vo_bias_coupling * r_follower[:2, 2] / r_follower[2, 2]), 1.0])
    taken = transport_increment(follower - follower[0] * 1e-3 * g, reference.rear_couplings, start, end)
    np.testing.assert_allclose(corrected, taken, rtol=0.0, atol=1e-12)
    assert corrected[2] - z[2] == pytest.approx(-follower[0] * 1e-3, abs=1e-12)  # the yaw error, d·β̂_ψ
    assert widened[2, 2] - r[2, 2] == pytest.approx(follower[0] ** 2 * 1e-6, rel=1e-4)  # d²·P_β on the yaw


def test_the_followers_yaw_error_is_taken_at_the_share_its_filter_applied():
    """(C0) at the follower's scrub demand ``D``: at ``D = 0`` the reference is the one without a demand to the bit;
    at ``D = 1`` with a release ``r`` the lead's yaw increment is less ``(1 − r)·d·β̂_ψ`` and the translation takes
    none of the coupled correction (closed form, 1e-12); a demand outside [0, 1] is refused."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    release = 0.7
    noise = FusionNoise(scrub_bias_release=release)
    reference = CouplingReference(params, 1, 2, rig.camera_in_trailer("left", params), noise)
    a, b = _swinging(1.0, 2), _swinging(1.2, 2)
    motion = np.linalg.inv(rig.camera_in_world(params, a, "left")) @ rig.camera_in_world(params, b, "left")
    covariance = np.diag([1e-6, 4e-6, 1e-6, 1e-4, 1e-5, 1e-4])
    start, end = reference.articulations(a.angles), reference.articulations(b.angles)
    beta, p_beta = 1e-3, 1e-6
    old = reference.measurement(motion, covariance, start, end, (beta, p_beta))
    still = reference.measurement(motion, covariance, start, end, (beta, p_beta, 0.0))
    np.testing.assert_array_equal(still[0], old[0])
    np.testing.assert_array_equal(still[1], old[1])
    follower, _ = camera_increment(reference.geometry, noise, motion, covariance)
    d = follower[0]
    scrubbed, _ = reference.measurement(motion, covariance, start, end, (beta, p_beta, 1.0))
    corrected = follower - np.array([0.0, 0.0, (1.0 - release) * d * beta])
    taken = transport_increment(corrected, reference.rear_couplings, start, end)
    np.testing.assert_allclose(scrubbed, taken, rtol=0.0, atol=1e-12)
    bare = reference.measurement(motion, covariance, start, end)[0]
    assert scrubbed[2] - bare[2] == pytest.approx(-(1.0 - release) * d * beta, abs=1e-12)
    assert abs(d * beta) > 1e-4  # the frame moves enough for the share to show
    with pytest.raises(InputError, match="yaw_bias"):
        reference.measurement(motion, covariance, start, end, (beta, p_beta, 1.5))


def test_a_reference_needs_a_follower_behind_with_couplings():
    params = VEHICLE_PRESETS["au-b-double"]()
    camera = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2).camera_in_trailer("left", params)
    with pytest.raises(InputError, match="follower"):
        CouplingReference(params, 2, 2, camera, FusionNoise())
    with pytest.raises(InputError, match="articulation"):
        transport_increment((1.0, 0.0, 0.0), [-8.0], [0.0, 0.0], [0.0])


# ------------------------------------------------------------------------------------------- the filter

SPEED, SLIP = 5.0, 0.05  # the mean forward speed [m/s] and the lateral over the forward velocity of every unit
SCALE, FLOW = 0.03, 0.03  # the lead camera's injected axial scale and flow [1/m] errors, eq (3')
SIDE = SideRigFusion(
    vo_axial_flow=0.05,
    vo_axial_scale=0.04,
    vo_axial_scale_walk=0.001,
    kinematic_rear_point="speed_compensated",
    kinematic_error_model="state",
    coupling_reference=True,
)


def _crab(t: float) -> ChainPose:
    """A B-double on a straight, every unit sliding sideways at ``SLIP`` of its varying forward speed."""
    x = SPEED * t - 2.0 * math.cos(0.5 * t) / 0.5  # u = SPEED + 2 sin(t/2)
    return ChainPose(x, SLIP * x, 0.0, (0.0, 0.0))


def _speed(t: float) -> float:
    return SPEED + 2.0 * math.sin(0.5 * t)


def _shot(tick: int, motion: np.ndarray | None) -> SimpleNamespace:
    """A released frame as the loop's camera gives it (``None``: its odometry failed)."""
    vo = SimpleNamespace(camera_motion=motion, covariance=np.eye(6) * 1e-8)
    return SimpleNamespace(tick=tick, frame=SimpleNamespace(valid=motion is not None, vo=vo))


REAR_ERROR_PERIOD = 4.0  # [s] of the follower camera's injected error across it
FAILED = range(100, 120)  # the frames whose following odometry fails (4 s mid-run)


def _drive(reference: bool, failed: range = FAILED, ticks: int = 1500, rear_error: float = 0.0, scale: float = 1.0):
    """The lead unit's filter over the sliding straight (the follower's frames ``failed`` fail; its camera's motion
    off by ``rear_error`` [m] across it in every frame; ``k_c`` of (C2) ``scale``); its errors, its estimated s_z and
    s_f, and the filter (read only). Computed once per case, however the arguments are given."""
    return _drive_case(reference, failed, ticks, rear_error, scale)


@functools.cache
def _drive_case(reference: bool, failed: range, ticks: int, rear_error: float, scale: float):
    """:func:`_drive` with every argument given by position (one cache entry per case)."""
    params = VEHICLE_PRESETS["au-b-double"]()
    side = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=1, station=-4.0)
    rear = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    noise = FusionNoise(side_rig=SIDE if reference else SIDE.replace(coupling_reference=None))
    fused = FusedVisoOt(params, side.camera_in_trailer("left", params), noise)
    mount = fused.geometry.mount_rotation
    across_sign = math.copysign(1.0, float(mount[:2, 0] @ np.array([fused._optical_axis[1], -fused._optical_axis[0]])))
    follower = SimpleNamespace(released=[], camera_in_trailer=rear.camera_in_trailer("left", params))
    reference_ = CouplingReference(params, 1, 2, follower.camera_in_trailer, fused.noise, covariance_scale=scale)
    following = FollowingCamera(reference_, follower)
    truth = OfftrackingBuffer(params.follow_point_offset_of(1))
    errors, previous, last = [], None, None
    for k in range(ticks):
        t = k * DT
        pose = _crab(t)
        frame = unit_frame(params, pose, 1)
        if previous is not None:
            truth.push(*increments_from_poses(np.vstack([previous[0], frame[0]]), np.array([previous[1], frame[1]]))[0])
        previous = frame
        u = _speed(t)
        fused.propagate(k, DT, 0.0, u, None, TractorSignals(u, 0.0, 0.0))
        follower.released, own = [], None
        if k % EVERY == 0:
            worlds = (side.camera_in_world(params, pose, "left"), rear.camera_in_world(params, pose, "left"))
            if last is not None:
                own = np.linalg.inv(last[0]) @ worlds[0]
                across = across_sign * own[0, 3]
                own[2, 3] += SCALE * own[2, 3] + FLOW * across * abs(across)  # eq (3')'s errors
                rear_motion = None if k // EVERY in failed else np.linalg.inv(last[1]) @ worlds[1]
                if rear_motion is not None:
                    # the follower camera's own error, slowly varying: correlated over the frames of a swing
                    rear_motion[0, 3] += rear_error * math.sin(2.0 * math.pi * t / REAR_ERROR_PERIOD)
                follower.released = [_shot(k, rear_motion)]
            last = worlds
        following.observe(k, {"articulation": np.zeros(1), "rear_articulation": np.zeros(1)})
        if own is not None:
            fused.measure(k, own, np.eye(6) * 1e-6, coupling=following.take(k))
        value = truth.offtracking()
        if fused.estimate is not None and value is not None:
            errors.append(fused.estimate - value)
    state = fused.state
    return np.array(errors), state[fused._sz], state[fused._sf], fused


def _axial(scale: float, flow: float, speed: float) -> float:
    """The error along the optical axis of one frame's motion at ``speed`` on the sliding straight [m], eq (3')."""
    across = speed * DT * EVERY
    return scale * SLIP * across + flow * across * across


def test_a_following_camera_makes_the_axial_errors_observable_under_slip():
    """On the sliding straight the lead's filter without the reference takes the slide for its camera's axial error:
    its off-tracking is 0.2 m off and more. With the rear trailer's camera carried forward (its odometry failing for
    4 s mid-run) it finds the injected axial error per frame within 1 mm at every speed of the run, and its
    off-tracking error stays under 2 cm."""
    errors, sz, sf, fused = _drive(reference=True)
    plain, sz_plain, sf_plain, other = _drive(reference=False)
    late = slice(-300, None)
    assert fused.coupling_updates > 200 and other.coupling_updates == 0
    assert np.max(np.abs(errors[late])) < 0.02
    assert np.sqrt(np.mean(plain[late] ** 2)) > 0.2
    for speed in (3.0, 5.0, 7.0):
        injected = _axial(SCALE, FLOW, speed)
        assert abs(_axial(sz, sf, speed) - injected) < 1e-3, speed
        assert abs(_axial(sz_plain, sf_plain, speed) - injected) > 5e-3, speed


def test_the_reference_covariance_scale_scales_c2_and_is_the_reference_setting():
    """``k_c`` of (C2): the increment unchanged to the bit, the covariance ``k_c`` times the mapped one (to 1e-15
    relative); 1 is the mapped covariance itself; outside [1, 100] or NaN refused. ``fusion.side_rig``'s
    ``coupling_covariance_scale`` reaches the loop's reference, not the filter's settings."""
    params = VEHICLE_PRESETS["au-b-double"]()
    camera = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2).camera_in_trailer("left", params)
    a, b = _swinging(1.0, 2), _swinging(1.2, 2)
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    motion = np.linalg.inv(rig.camera_in_world(params, a, "left")) @ rig.camera_in_world(params, b, "left")
    covariance = np.diag([1e-6, 4e-6, 1e-6, 1e-4, 1e-5, 1e-4])
    plain = CouplingReference(params, 1, 2, camera, FusionNoise())
    start, end = plain.articulations(a.angles), plain.articulations(b.angles)
    z, r = plain.measurement(motion, covariance, start, end, (1e-3, 1e-6))
    z4, r4 = CouplingReference(params, 1, 2, camera, FusionNoise(), covariance_scale=4.0).measurement(
        motion, covariance, start, end, (1e-3, 1e-6)
    )
    np.testing.assert_array_equal(z4, z)
    np.testing.assert_allclose(r4, 4.0 * r, rtol=1e-15, atol=0.0)
    for bad in (0.5, 101.0, math.nan):
        with pytest.raises(InputError, match="covariance_scale"):
            CouplingReference(params, 1, 2, camera, FusionNoise(), covariance_scale=bad)
    side = SIDE.replace(coupling_covariance_scale=4.0)
    assert "coupling_covariance_scale" not in side.given()
    noise = FusionNoise(side_rig=side).for_camera((0.0, 1.0))
    cameras = {"viso_ot3": SimpleNamespace(camera_in_trailer=camera, released=[])}
    assert following_camera(params, 1, cameras, noise, "planar").reference.covariance_scale == 4.0
    assert following_camera(params, 1, cameras, FusionNoise(), "planar").reference.covariance_scale == 1.0


def test_a_runs_side_rig_takes_the_reference_covariance_as_mapped_unless_set():
    """A run's ``fusion.side_rig.coupling_covariance_scale`` is unset by default, so its reference keeps (C2)'s
    covariance as mapped (``k_c`` 1; docs/field_bias.md §7.13 says why); a scenario's value reaches the reference."""
    default = FusionConfig().side_rig
    assert default.coupling_covariance_scale is None and default.reference_covariance_scale == 1.0
    assert FusionConfig(side_rig={"coupling_covariance_scale": 4.0}).side_rig.reference_covariance_scale == 4.0


def test_a_wider_reference_takes_less_of_the_followers_own_error():
    """The follower's camera off across it by up to 2 mm a frame, swinging over 4 s (40 frames), an error correlated
    over frames that its covariance takes as white: the lead's off-tracking takes it (over 5 mm RMS late in the run,
    against the same filter without it); with ``k_c`` = 4 it takes under 0.75 of that."""
    late = slice(-300, None)
    taken = []
    for scale in (1.0, 4.0):
        off, *_ = _drive(True, FAILED, 1500, 2e-3, scale)
        clean, *_ = _drive(True) if scale == 1.0 else _drive(True, FAILED, 1500, 0.0, scale)
        n = min(len(off), len(clean))
        taken.append(float(np.sqrt(np.mean((off[:n] - clean[:n])[late] ** 2))))
    assert taken[0] > 0.005
    assert taken[1] < 0.75 * taken[0]


def test_the_lead_runs_on_when_the_following_frames_fail():
    """The follower's odometry fails for 4 s (20 frames) mid-run: those frames give no measurement (nor the first
    after them, whose interval starts at a failed frame: it is taken), the lead's filter runs on on its own frame and
    is within 2 cm again by the end."""
    errors, _, _, fused = _drive(reference=True)
    assert fused.frames == 1500 // EVERY - 1
    assert 200 < fused.coupling_updates <= fused.frames - 20
    assert len(errors) > 1000 and np.all(np.isfinite(errors))
    assert np.max(np.abs(errors[-100:])) < 0.02


def test_the_follower_is_the_nearest_unit_behind_whose_camera_looks_along_it():
    """The A-double's lead trailer skips the dolly's side rig for the rear trailer's rear rig; the dolly takes the
    rear trailer's; the last unit, a run off the level road, or no camera behind give none."""
    params = VEHICLE_PRESETS["au-a-double"]()

    def camera(unit: int, psi: float) -> SimpleNamespace:
        rig = StereoRig.from_degrees(psi_c2v_deg=psi, lateral=1.275 if psi == 270.0 else 0.0, unit=unit)
        return SimpleNamespace(camera_in_trailer=rig.camera_in_trailer("left", params), released=[])

    cameras = {"viso_ot3": camera(2, 270.0), "viso_ot4": camera(3, 180.0)}
    noise = FusionNoise()
    lead = following_camera(params, 1, cameras, noise, "planar")
    assert lead is not None and lead.camera is cameras["viso_ot4"] and lead.reference.follower == 3
    assert following_camera(params, 2, cameras, noise, "planar").reference.lead == 2  # the dolly
    assert following_camera(params, 3, cameras, noise, "planar") is None
    assert following_camera(params, 1, cameras, noise, "accelerometer") is None
    assert following_camera(params, 1, {"viso_ot3": cameras["viso_ot3"]}, noise, "planar") is None


# ------------------------------------------------------------------------------------------- off the level road


def _normal_articulations(params, pose: ChainPose, terrain, lead: int, follower: int) -> tuple[float, ...]:
    """``Γ_{j+1} … Γ_m`` as a sensor turning about the coupling's axis reads them: the angle between the two units'
    body x axes about the follower's normal (the units' common normal on a plane)."""
    out = []
    for k in range(lead, follower):
        ahead, behind = (unit_attitude(params, pose, terrain, u).rotation for u in (k, k + 1))
        x_ahead, x_behind, normal = ahead[:, 0], behind[:, 0], behind[:, 2]
        out.append(math.atan2(float(normal @ np.cross(x_behind, x_ahead)), float(x_behind @ x_ahead)))
    return tuple(out)


@pytest.mark.parametrize("fall_line", [0.0, 0.7, 2.0])
def test_on_a_tilted_plane_the_reference_is_the_leads_level_frame_increment(fall_line):
    """On a 15 % plane (inclination ``α = atan 0.15``) the follower's rear camera motion, made horizontal with its
    tilts at the frame's start and end and carried forward by (C1), is the lead's kingpin increment in its level
    frame (the yaw-plane model's, which the lead's filter measures) to 1e-9 m, rad, with the articulations as the
    model has them (the headings' difference about the vertical). With the articulations about the plane's normal
    instead the error stays within what ``|δΓ| ≤ (1/cos α − 1)·|Γ|`` allows: ``|d_m|·|δΓ⁰| + |x5|·|δΓ¹ − δΓ⁰|``
    in position, ``|δΓ¹ − δΓ⁰|`` in yaw."""
    grade = 0.15
    plane = TiltedPlane(grade * math.cos(fall_line), grade * math.sin(fall_line), 1.0)
    slack = 1.0 / math.cos(math.atan(grade)) - 1.0
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    reference = CouplingReference(params, 1, 2, rig.camera_in_trailer("left", params), FusionNoise(), "accelerometer")
    x5 = abs(float(params.trailers[0].fifth_wheel_x))
    normal_error = 0.0
    for t in np.arange(0.0, 6.0, 0.6):
        a, b = _swinging(t, 2), _swinging(t + 0.2, 2)
        tilts = tuple((float(u.pitch), float(u.roll)) for u in (unit_attitude(params, p, plane, 2) for p in (a, b)))
        motion = np.linalg.inv(rig.camera_in_world(params, a, "left", plane)) @ rig.camera_in_world(
            params, b, "left", plane
        )
        truth = _increment(params, a, b, 1)
        start, end = reference.articulations(a.angles), reference.articulations(b.angles)
        z, r = reference.measurement(motion, np.eye(6) * 1e-8, start, end, None, tilts)
        np.testing.assert_allclose(z, truth, rtol=0.0, atol=1e-9)
        assert np.all(np.linalg.eigvalsh(r) > 0.0)
        g0, g1 = (_normal_articulations(params, p, plane, 1, 2) for p in (a, b))
        z_n, _ = reference.measurement(motion, None, g0, g1, None, tilts)
        d_m = math.hypot(*_increment(params, a, b, 2)[:2])
        yaw_bound = slack * (abs(start[0]) + abs(end[0]))
        assert abs(z_n[2] - truth[2]) <= yaw_bound + 1e-9
        assert math.hypot(*(z_n - truth)[:2]) <= slack * d_m * abs(start[0]) + x5 * yaw_bound + 1e-9
        normal_error = max(normal_error, math.hypot(*(z_n - truth)[:2]))
    assert normal_error > 1e-5  # the articulation about the normal is not the horizontal one: the bound is tested


def test_off_the_level_road_the_reference_needs_the_accelerometers_tilts():
    """With ``accelerometer`` the follower's start and end tilts are required (one line naming them); ``planar``
    refuses tilts; the odometry's integrated tilt is refused, and so is a follower whose level differs from the
    lead's; a follower with the accelerometer gives the lead on it a reference, whose frames without a tilt give
    no measurement."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    camera = rig.camera_in_trailer("left", params)
    level = CouplingReference(params, 1, 2, camera, FusionNoise(), "accelerometer")
    motion = np.eye(4)
    motion[2, 3] = -1.0
    with pytest.raises(InputError, match="tilts"):
        level.measurement(motion, None, (0.1,), (0.1,))
    with pytest.raises(InputError, match="tilt"):
        level.measurement(motion, None, (0.1,), (0.1,), None, ((0.0, math.nan), (0.0, 0.0)))
    with pytest.raises(InputError, match="tilts"):
        CouplingReference(params, 1, 2, camera, FusionNoise()).measurement(
            motion, None, (0.1,), (0.1,), None, ((0.0, 0.0), (0.0, 0.0))
        )
    with pytest.raises(InputError, match="level_reference"):
        CouplingReference(params, 1, 2, camera, FusionNoise(), "odometry")

    def follower(level_reference: str, tilts: list) -> SimpleNamespace:
        feed = SimpleNamespace(level_reference=level_reference)
        return SimpleNamespace(camera_in_trailer=camera, released=[], feed=feed, tilts=tilts)

    noise = FusionNoise()
    assert following_camera(params, 1, {"viso_ot3": follower("odometry", [])}, noise, "odometry") is None
    assert following_camera(params, 1, {"viso_ot3": follower("planar", [])}, noise, "accelerometer") is None
    cam = follower("accelerometer", [])
    found = following_camera(params, 1, {"viso_ot3": cam}, noise, "accelerometer")
    assert found is not None and found.reference.geometry.level_reference == "accelerometer"
    frame = SimpleNamespace(valid=True, vo=SimpleNamespace(camera_motion=motion, covariance=None))
    measured = {"articulation": np.array([0.0]), "rear_articulation": np.array([0.05])}
    for tick, tilt in ((5, (0.01, 0.0)), (10, None), (15, (0.01, 0.0)), (20, (0.012, 0.001))):
        cam.released = [SimpleNamespace(tick=tick, frame=frame, tilt=tilt)]
        found.observe(tick, measured)
    assert found.measurements == 1 and found.take(20) is not None  # 10 and 15 start or end without a tilt
