"""(C0'') of sensor/fusion_coupling.py: the following (rear) camera's along-axis error ``ŝ``, its filter's ``s_z``,
taken out of its increment before (C1) (``fusion.side_rig.coupling_axial_scale``).

A follower increment with a known scale error along its camera's axis and articulations far from 0: the lead's
reference is the one of the true increment (1e-12 m), and ``P_s`` reaches the lead's lateral variance as
``sin²Γ⁰·d²/(1 + ŝ)²·P_s`` (1e-9 relative); without the setting, without ``ŝ`` or at ``ŝ = P_s = 0`` the reference is
(C0)–(C2)'s to the bit; a follower filter without ``s_z`` is refused (by the settings and by the loop's read of the
follower's filter), as is a bad ``(ŝ, P_s)``; the setting is the reference's and reaches the loop's reference.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

import sensor.fusion_coupling as coupling
from scenarios.configuration.sections import FusionConfig
from scenarios.loop.following_camera import filter_axial_scale, following_camera
from sensor.camera import StereoRig
from sensor.fusion_coupling import CouplingReference, transport_increment
from sensor.fusion_model import camera_displacement
from sensor.fusion_noise import FusionNoise, SideRigFusion
from vehicle_model.errors import InputError
from vehicle_model.geometry import ChainPose
from vehicle_model.presets import VEHICLE_PRESETS

PARAMS = VEHICLE_PRESETS["au-b-double"]()
RIG = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
CAMERA = RIG.camera_in_trailer("left", PARAMS)
COVARIANCE = np.diag([1e-6, 4e-6, 1e-6, 1e-4, 1e-5, 1e-4])  # the follower camera's odometry covariance
AXIAL = FusionNoise(vo_axial_scale=0.04, side_rig=SideRigFusion(coupling_axial_scale=True))
TRUE = np.array([0.41, 0.012, 0.021])  # the follower's true front-coupling increment over a frame [m, m, rad]
START, END = (0.70,), (0.72,)  # Γ⁰, Γ¹ [rad]: 40° of articulation


def _frame(reference: CouplingReference, axial: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """(C0)–(C2) of one frame of a turning, swinging B-double (a rendered-free camera motion)."""
    poses = []
    for t in (1.0, 1.2):
        angles = tuple(0.2 * math.sin(0.7 * t + k) + 0.05 * k for k in range(2))
        poses.append(ChainPose(3.0 * t + 0.4 * math.sin(t), 0.5 * t * t, 0.3 * t + 0.2 * math.sin(1.3 * t), angles))
    a, b = poses
    motion = np.linalg.inv(RIG.camera_in_world(PARAMS, a, "left")) @ RIG.camera_in_world(PARAMS, b, "left")
    start, end = reference.articulations(a.angles), reference.articulations(b.angles)
    return reference.measurement(motion, COVARIANCE, start, end, (1e-3, 1e-6, 0.3), None, axial)


def _scaled(monkeypatch: pytest.MonkeyPatch, reference: CouplingReference, s: float) -> None:
    """The follower's camera reports ``TRUE`` with the error ``s`` along its axis, eq (3') of sensor/fusion_model.py:
    ``z_xy = Δ_xy + s·a(Δ)·o``."""
    o = reference.optical_axis
    along = camera_displacement(TRUE, reference.geometry.camera_position, o)[0]
    measured = TRUE.copy()
    measured[:2] += s * along * o
    monkeypatch.setattr(coupling, "camera_increment", lambda *args: (measured.copy(), 1e-6 * np.eye(3)))


def test_a_known_scale_error_is_taken_out_exactly(monkeypatch: pytest.MonkeyPatch) -> None:
    """The follower's increment 5 % short along its (rear-facing) axis, ``ŝ`` = −0.05: the lead's reference equals
    (C1) of the true increment to 1e-12 m; without (C0'') it is off laterally by about ``sin Γ⁰`` of the error."""
    reference = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), axial_scale=True)
    assert abs(reference.optical_axis[0] + 1.0) < 1e-12  # a rear rig looks back along its unit
    _scaled(monkeypatch, reference, -0.05)
    truth = transport_increment(TRUE, reference.rear_couplings, START, END)
    z, _ = reference.measurement(np.eye(4), None, START, END, None, None, (-0.05, 0.0))
    np.testing.assert_allclose(z, truth, rtol=0.0, atol=1e-12)
    uncorrected, _ = reference.measurement(np.eye(4), None, START, END)
    along = camera_displacement(TRUE, reference.geometry.camera_position, reference.optical_axis)[0]
    assert uncorrected[1] - truth[1] == pytest.approx(-math.sin(START[0]) * 0.05 * along, rel=0.05)


def test_the_scale_variance_reaches_the_leads_lateral_by_sin_gamma(monkeypatch: pytest.MonkeyPatch) -> None:
    """``P_s`` = 0.03²: the reference's covariance less the one at ``P_s`` = 0 (same ``ŝ``) is
    ``(d/(1 + ŝ))²·P_s·R(−Γ⁰)·o·oᵀ·R(Γ⁰)``: its lateral entry ``sin²Γ⁰·(d/(1 + ŝ))²·P_s`` (1e-9 relative), ``d`` the
    corrected travel along the axis; its yaw row 0."""
    reference = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), axial_scale=True)
    s, variance = -0.05, 0.03**2
    _scaled(monkeypatch, reference, s)
    _, r0 = reference.measurement(np.eye(4), None, START, END, None, None, (s, 0.0))
    _, r1 = reference.measurement(np.eye(4), None, START, END, None, None, (s, variance))
    d = camera_displacement(TRUE, reference.geometry.camera_position, reference.optical_axis)[0]
    added = r1 - r0
    assert added[1, 1] == pytest.approx(math.sin(START[0]) ** 2 * (d / (1.0 + s)) ** 2 * variance, rel=1e-9)
    assert added[0, 0] == pytest.approx(math.cos(START[0]) ** 2 * (d / (1.0 + s)) ** 2 * variance, rel=1e-9)
    np.testing.assert_allclose(added[2], 0.0, atol=1e-18)


def test_off_or_without_an_estimate_the_reference_is_unchanged_to_the_bit() -> None:
    """Without the setting (any ``ŝ`` given), with it and no ``ŝ``, or with ``ŝ = P_s = 0``: the increment and the
    covariance equal those of a reference built without the setting, bit for bit; with ``ŝ`` = 0.05 they differ."""
    z0, r0 = _frame(CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise()), None)
    on = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), axial_scale=True)
    for reference, axial in (
        (CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise()), (0.05, 1e-3)),
        (on, None),
        (on, (0.0, 0.0)),
    ):
        z, r = _frame(reference, axial)
        np.testing.assert_array_equal(z, z0)
        np.testing.assert_array_equal(r, r0)
    z, r = _frame(on, (0.05, 1e-3))
    assert abs(z[0] - z0[0]) > 1e-3 and r[0, 0] > r0[0, 0]


def test_a_follower_without_the_axial_state_is_refused() -> None:
    """The setting with the section's ``vo_axial_scale`` 0 (the following rear rig's filter without ``s_z``): refused
    by the settings naming both fields; a follower filter without ``s_z`` read by the loop: refused naming the
    setting; a bad ``(ŝ, P_s)``: refused naming it."""
    for make in (
        lambda: FusionNoise(side_rig=SideRigFusion(coupling_axial_scale=True)),
        lambda: FusionConfig(side_rig={"coupling_axial_scale": True}),
    ):
        with pytest.raises(ValidationError, match=r"coupling_axial_scale = true needs .*vo_axial_scale = 0"):
            make()
    plain = SimpleNamespace(noise=FusionNoise(), unit=2, state=np.zeros(7), covariance=np.eye(7))
    with pytest.raises(InputError, match="coupling_axial_scale needs the following unit 2's filter to hold s_z"):
        filter_axial_scale(plain)
    state = SimpleNamespace(noise=AXIAL, unit=2, state=np.arange(8.0) / 100.0, covariance=np.diag(np.arange(1.0, 9.0)))
    assert filter_axial_scale(state) == (0.07, 8.0)
    assert filter_axial_scale(None) is None
    on = CouplingReference(PARAMS, 1, 2, CAMERA, FusionNoise(), axial_scale=True)
    for bad in ((-1.0, 0.0), (0.05, -1e-6), (math.nan, 0.0), (0.05,)):
        with pytest.raises(InputError, match="axial"):
            _frame(on, bad)  # type: ignore[arg-type]


def test_the_setting_is_the_references_and_reaches_the_loop() -> None:
    """Unset by default; set, not among the filter's settings, and the loop's reference takes it."""
    assert not FusionConfig().side_rig.reference_axial_scale
    assert "coupling_axial_scale" not in AXIAL.side_rig.given()
    assert FusionConfig(vo_axial_scale=0.04, side_rig={"coupling_axial_scale": True}).side_rig.reference_axial_scale
    cameras = {"viso_ot3": SimpleNamespace(camera_in_trailer=CAMERA, released=[])}
    noise = AXIAL.for_camera((0.0, 1.0))
    assert following_camera(PARAMS, 1, cameras, noise, "planar").reference.axial_scale
    assert not following_camera(PARAMS, 1, cameras, FusionNoise(), "planar").reference.axial_scale
