"""VISO-OT and the fused filter on any towed unit: a B-double's rear trailer, an A-double's dolly and rear trailer.

The combination turns steadily without slip, built kinematically: the tractor's rear point (the rear axles' mean
station) on a circle, every towed unit at the heading that puts its zero-slip point (``L_c`` of eq (1) of
:mod:`sensor.fusion`) on the radius, so the whole chain turns rigidly about the centre. The cameras' motions are
exact (the rig's poses at successive :class:`~vehicle_model.geometry.ChainPose`), the signals too; the truth is the
path buffer fed with the unit's true front-coupling increments (de Saxe & Cebon 2018, eqs (3)–(7)).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import ChainSignals, FusedVisoOt, FusionNoise, TractorSignals
from sensor.unit_kinematics import ChainKinematics, slip_kinematics
from sensor.viso_ot import VisoOtEstimator
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose, unit_frame
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import VEHICLE_PRESETS

DT = 0.02  # control period [s]
EVERY = 5  # control ticks per camera frame
RADIUS = 20.0  # the tractor's rear point [m]
SPEED = 3.0  # the tractor's rear point [m/s]


def _heading(origin: np.ndarray, slip_point: float) -> float:
    """The heading that puts the point ``slip_point`` behind ``origin`` on the radius through the centre (0, 0)."""
    return math.atan2(origin[1], origin[0]) + math.acos(slip_point / math.hypot(*origin))


_SLIP_POINTS: dict[tuple[str, int], float] = {}


def _slip_point(params, unit: int) -> float:
    """``L_c`` of the unit (eq (1) of :mod:`sensor.fusion_model`), computed once per preset."""
    key = (params.name, unit)
    if key not in _SLIP_POINTS:
        _SLIP_POINTS[key] = slip_kinematics(params, unit)[0]
    return _SLIP_POINTS[key]


def steady_pose(params, t: float) -> ChainPose:
    """The combination at time ``t`` of a steady left turn about (0, 0) without slip (module notes)."""
    r = SPEED / RADIUS
    psi1 = r * t
    ahead = params.tractor_wheelbase()  # the rear point, behind the steer axle
    rear = RADIUS * np.array([math.sin(psi1), -math.cos(psi1)])
    forward = np.array([math.cos(psi1), math.sin(psi1)])
    cg = rear + (params.tractor.cg_x + ahead) * forward
    origin = rear + (params.tractor.fifth_wheel_x + ahead) * forward
    heading, angles = psi1, []
    for unit, towed in enumerate(params.trailers, start=1):
        psi = _heading(origin, _slip_point(params, unit))
        angles.append(heading - psi)
        heading = psi
        if towed.fifth_wheel_x is not None:
            origin = origin + towed.fifth_wheel_x * np.array([math.cos(psi), math.sin(psi)])
    return ChainPose(float(cg[0]), float(cg[1]), psi1, tuple(angles))


def unit_speed(params, pose: ChainPose, unit: int) -> float:
    """The unit's forward speed: ``r`` times the distance of its front coupling from the centre, across its axis."""
    origin, psi = unit_frame(params, pose, unit)
    return SPEED / RADIUS * float(origin[0] * math.sin(psi) - origin[1] * math.cos(psi))


def drive(
    params,
    unit: int,
    rig: StereoRig,
    fused: bool,
    ticks: int = 500,
    signals: bool = True,
    noise: FusionNoise | None = None,
    axial_scale: float = 1.0,
):
    """Estimates and truths of ``unit`` per tick over the steady turn (NaN: none); the truth's path has the
    estimator's resolution: every tick for the fused filter, every frame for VISO-OT. ``axial_scale`` multiplies
    the camera's translation along its optical axis (a depth-scale error of the odometry)."""
    camera = rig.camera_in_trailer("left", params)
    estimator = FusedVisoOt(params, camera, noise, unit=unit) if fused else VisoOtEstimator(params, camera, unit=unit)
    truth = OfftrackingBuffer(params.follow_point_offset_of(unit))
    r = SPEED / RADIUS
    est, std, ref = [], [], []
    previous = last_world = value = None
    for k in range(ticks):
        pose = steady_pose(params, k * DT)
        frame = unit_frame(params, pose, unit)
        if previous is not None and (fused or k % EVERY == 0):  # VISO-OT's path has the camera's chords
            truth.push(*increments_from_poses(np.vstack([previous[0], frame[0]]), np.array([previous[1], frame[1]]))[0])
        if fused or k % EVERY == 0:
            previous = frame
        if fused:
            chain = ChainSignals(SPEED, r, pose.angles, math.nan, (r,) * (unit - 1)) if signals else None
            estimator.propagate(k, DT, r, unit_speed(params, pose, unit), None, chain)
        if k % EVERY == 0:
            world = rig.camera_in_world(params, pose, "left")
            if last_world is not None:
                motion = np.linalg.inv(last_world) @ world
                motion[2, 3] *= axial_scale
                if fused:
                    estimator.measure(k, motion, np.eye(6) * 1e-10)
                else:
                    value = estimator.update(motion)
            last_world = world
        if fused:
            est.append(math.nan if estimator.estimate is None else estimator.estimate)
            std.append(estimator.std)
        else:
            est.append(math.nan if value is None else value)
        value_truth = truth.offtracking()
        ref.append(math.nan if value_truth is None else value_truth)
    return np.array(est), np.array(std), np.array(ref), estimator


CASES = [("au-b-double", 2, 180.0), ("au-b-double", 2, 270.0), ("au-a-double", 2, 180.0), ("au-a-double", 3, 180.0)]


@pytest.mark.parametrize(("preset", "unit", "psi_c2v"), CASES)
def test_viso_ot_of_a_rear_unit_is_its_geometric_offtracking(preset, unit, psi_c2v):
    """Exact camera motions of a rig on unit ``unit`` give that unit's off-tracking to 1e-9 m (as the first
    unit's test), in a turn where it is at least 0.2 m."""
    params = VEHICLE_PRESETS[preset]()
    lateral = 0.0 if psi_c2v == 180.0 else 1.275
    rig = StereoRig.from_degrees(psi_c2v_deg=psi_c2v, lateral=lateral, unit=unit, station=-4.0)
    est, _, ref, _ = drive(params, unit, rig, fused=False, ticks=400)
    frames = np.arange(len(est)) % EVERY == 0
    both = frames & np.isfinite(est) & np.isfinite(ref)
    assert both.sum() > 30 and np.min(np.abs(ref[both])) > 0.2
    assert np.max(np.abs(est[both] - ref[both])) < 1e-9


def test_the_a_doubles_lead_trailer_default_side_rig_gives_its_geometric_offtracking():
    """Unit 1 of a four-unit combination through its default rig (a left rig midway along the lead trailer,
    at its edge, as :func:`scenarios.camera_schema.rig_configs` resolves it): exact camera motions give the lead
    trailer's off-tracking to 1e-9 m, its follow point, kingpin and lever arm being the unit's own."""
    from scenarios.camera.build import rig_from_config
    from scenarios.camera_schema import CameraConfig, rig_configs

    params = VEHICLE_PRESETS["au-a-double"]()
    resolved = rig_configs(CameraConfig(), params)[0]
    rig = rig_from_config(resolved)
    assert rig.unit == 1 and rig.psi_c2v == pytest.approx(1.5 * math.pi) and rig.lateral == pytest.approx(1.25)
    assert params.trailers[0].rear_x < rig.station < params.trailers[0].front_x
    est, _, ref, _ = drive(params, 1, rig, fused=False, ticks=400)
    both = (np.arange(len(est)) % EVERY == 0) & np.isfinite(est) & np.isfinite(ref)
    assert both.sum() > 30 and np.min(np.abs(ref[both])) > 0.2
    assert np.max(np.abs(est[both] - ref[both])) < 1e-9


@pytest.mark.parametrize(("preset", "unit"), [("au-b-double", 2), ("au-a-double", 3)])
def test_the_fused_filter_of_a_rear_unit_converges_to_its_offtracking(preset, unit):
    """Exact motions and exact signals: the fused estimate of unit ``unit`` equals the truth to 1e-6 m, its σ (over
    0 and below 5 cm) covers the error, and the chain's kinematics found no slip (``v_s`` within 1 mm/s)."""
    params = VEHICLE_PRESETS[preset]()
    est, std, ref, fused = drive(params, unit, StereoRig(unit=unit), fused=True)
    both = np.isfinite(est) & np.isfinite(ref)
    assert both.sum() > 150 and np.min(np.abs(ref[both])) > 0.2
    assert np.max(np.abs(est[both] - ref[both])) < 1e-6
    assert np.all(std[both] > 0.0) and np.all(std[both] < 0.05)
    assert np.all(np.abs(est[both] - ref[both]) <= 2.0 * std[both])
    assert abs(fused.state[3]) < 1e-3
    assert fused.kinematic_std == pytest.approx(fused.noise.tractor_slip)  # no evidence of slip


def _chain_motion(params, t: float) -> ChainPose:
    """A tractor whose rear point has no lateral velocity (a circle) with articulations that change in time."""
    r1 = SPEED / RADIUS
    psi1 = 0.3 + r1 * t
    rear = RADIUS * np.array([math.sin(psi1), -math.cos(psi1)])
    forward = np.array([math.cos(psi1), math.sin(psi1)])
    cg = rear + (params.tractor.cg_x + params.tractor_wheelbase()) * forward
    angles = tuple(0.2 * math.sin(0.7 * t + k) + 0.05 * k for k in range(len(params.trailers)))
    return ChainPose(float(cg[0]), float(cg[1]), psi1, angles)


@pytest.mark.parametrize("preset", ["au-b-double", "au-a-double"])
def test_the_chains_zero_slip_velocity_is_the_rigid_bodies_velocity(preset):
    """``z_c`` of every unit equals the lateral velocity of its front coupling (central difference of its frame,
    to 1e-6 m/s) while the articulations change, with the units' gyros; derived from the articulations' rates it
    is within the backward difference's lag (half a tick of ``Γ̈ ≈ 0.1 rad/s²`` on each fifth wheel's lever of up to
    12 m: 0.02 m/s)."""
    params = VEHICLE_PRESETS[preset]()
    t, h = 1.3, 1e-5
    pose = _chain_motion(params, t)
    r1 = SPEED / RADIUS
    for unit in range(1, params.n_units):
        (a, _), (b, _) = (unit_frame(params, _chain_motion(params, t + s), unit) for s in (-h, h))
        velocity = (b - a) / (2 * h)
        psi = unit_frame(params, pose, unit)[1]
        true_lateral = -math.sin(psi) * velocity[0] + math.cos(psi) * velocity[1]
        rates = tuple(
            (
                unit_frame(params, _chain_motion(params, t + h), j)[1]
                - unit_frame(params, _chain_motion(params, t - h), j)[1]
            )
            / (2 * h)
            for j in range(1, unit)
        )
        signals = ChainSignals(SPEED, r1, pose.angles, math.nan, rates)
        assert ChainKinematics(params, unit, "axle_mean").lateral(signals, DT) == pytest.approx(true_lateral, abs=1e-6)
        derived = ChainKinematics(params, unit, "axle_mean")
        derived.remember(ChainSignals(SPEED, r1, _chain_motion(params, t - DT).angles))
        value = derived.lateral(ChainSignals(SPEED, r1, pose.angles), DT)
        assert value == pytest.approx(true_lateral, abs=0.02)


def test_the_first_unit_takes_tractor_and_chain_signals_alike():
    """On the first unit :class:`TractorSignals` and its :class:`ChainSignals` give the same filter, bit for bit."""
    params = VEHICLE_PRESETS["au-b-double"]()
    camera = StereoRig().camera_in_trailer("left", params)
    filters = [FusedVisoOt(params, camera), FusedVisoOt(params, camera, unit=1)]
    for k in range(300):
        pose = steady_pose(params, k * DT)
        tractor = TractorSignals(SPEED, SPEED / RADIUS + 1e-3, pose.angles[0])
        for fused, signals in zip(filters, (tractor, tractor.chain), strict=True):
            fused.propagate(k, DT, SPEED / RADIUS, unit_speed(params, pose, 1), None, signals)
    np.testing.assert_array_equal(filters[0].state, filters[1].state)
    np.testing.assert_array_equal(filters[0].covariance, filters[1].covariance)


def test_a_unit_is_checked_before_any_work():
    params = VEHICLE_PRESETS["au-b-double"]()
    camera = StereoRig(unit=2).camera_in_trailer("left", params)
    with pytest.raises(InputError, match="unit = 3"):
        VisoOtEstimator(params, camera, unit=3)
    with pytest.raises(InputError, match="unit = 0"):
        FusedVisoOt(params, camera, unit=0)
    fused = FusedVisoOt(params, camera, unit=2)
    fused.propagate(0, DT, 0.1, 3.0, None, None)
    with pytest.raises(InputError, match="ChainSignals"):
        fused.propagate(1, DT, 0.1, 3.0, None, TractorSignals(3.0, 0.1, 0.1))
    with pytest.raises(InputError, match="2 articulation"):
        fused.propagate(2, DT, 0.1, 3.0, None, ChainSignals(3.0, 0.1, (0.1,)))


def _swinging(params, t: float) -> ChainPose:
    """The steady turn of :func:`steady_pose` with every articulation swinging by ±0.02 rad (the tractor's rear point
    still without lateral velocity; the towed units' axles slip)."""
    pose = steady_pose(params, t)
    return pose._replace(angles=tuple(g + 0.02 * math.sin(0.4 * t + k) for k, g in enumerate(pose.angles)))


def test_a_blinded_rear_unit_is_carried_by_the_chains_kinematics():
    """The B-double's rear trailer in a turn whose articulations swing (its own axles slip, ``v_s`` changes by
    about 0.1 m/s), camera blind for 4 s: with the chain's signals the estimate stays within 0.15 m of the truth
    (the kinematics are weighed as a slowly varying error, eq (K1) of :mod:`sensor.fusion_model`, so they follow a
    changing slip with a lag); without them it drifts more than three times as far."""
    params = VEHICLE_PRESETS["au-b-double"]()
    unit, h = 2, 1e-5
    rig = StereoRig(unit=unit)
    camera = rig.camera_in_trailer("left", params)
    filters = {"chain": FusedVisoOt(params, camera, unit=unit), "alone": FusedVisoOt(params, camera, unit=unit)}
    for fused in filters.values():  # the estimate is read in the gap only (the state does not depend on it)
        fused._read = lambda: None
    truth = OfftrackingBuffer(params.follow_point_offset_of(unit))
    r1 = SPEED / RADIUS
    errors: dict[str, list[float]] = {name: [] for name in filters}
    previous = last_world = None
    for k in range(700):
        t = k * DT
        pose = _swinging(params, t)
        origin, psi = unit_frame(params, pose, unit)
        (a, psi_a), (b, psi_b) = (unit_frame(params, _swinging(params, t + s), unit) for s in (-h, h))
        velocity, rate = (b - a) / (2 * h), (psi_b - psi_a) / (2 * h)
        speed = math.cos(psi) * velocity[0] + math.sin(psi) * velocity[1]
        rates = (r1 - 0.008 * math.cos(0.4 * t),)  # ψ_2 = ψ_1 − Γ_1, the swing's rate
        if previous is not None:
            truth.push(*increments_from_poses(np.vstack([previous[0], origin]), np.array([previous[1], psi]))[0])
        previous = (origin, psi)
        world = rig.camera_in_world(params, pose, "left") if k % EVERY == 0 else None
        for name, fused in filters.items():
            chain = ChainSignals(SPEED, r1, pose.angles, math.nan, rates) if name == "chain" else None
            fused.propagate(k, DT, rate, speed, None, chain)
            if world is not None and last_world is not None:
                blind = 450 <= k < 650
                fused.measure(k, None if blind else np.linalg.inv(last_world) @ world, np.eye(6) * 1e-10)
            if 450 <= k < 650:
                FusedVisoOt._read(fused)
            if 450 <= k < 650 and fused.estimate is not None and truth.offtracking() is not None:
                errors[name].append(abs(fused.estimate - truth.offtracking()))
        if world is not None:
            last_world = world
    assert len(errors["chain"]) == 200
    assert max(errors["chain"]) < 0.15
    assert max(errors["alone"]) > 3.0 * max(errors["chain"])


def test_the_std_carries_an_odometry_scale_error_along_a_side_cameras_axis():
    """A side camera on the rear unit whose odometry overstates its motion along the optical axis by 3 %: the
    estimate is off by centimetres; with ``vo_axial_scale_uncertainty`` 3 % the std covers it (2σ on every tick),
    without it it does not; with the default (0) the std is that of a filter without the term, bit for bit."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=270.0, lateral=1.275, unit=2)
    runs = {
        u: drive(
            params, 2, rig, fused=True, signals=False, noise=FusionNoise(vo_axial_scale_uncertainty=u), axial_scale=1.03
        )
        for u in (0.0, 0.03)
    }
    est, std_plain, ref, _ = runs[0.0]
    std_axial = runs[0.03][1]
    both = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) > 300)
    error = np.abs(est[both] - ref[both])
    assert 0.02 < np.max(error) < 0.2
    assert np.mean(error <= 2.0 * std_plain[both]) < 0.5
    assert np.all(error <= 2.0 * std_axial[both])
    np.testing.assert_array_equal(runs[0.03][0], est)  # the term widens the std only
