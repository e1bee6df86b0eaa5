"""The unit's own slip reference in (K1): the biases of the unit's measured rates enter through (T2) alone.

With ``kinematic_rear_point: trailer_lateral_acceleration`` (K1)'s ``z_c`` is formed from the unit's own gyro and
wheel speed (:meth:`sensor.unit_slip_reference.UnitSlipReference.lateral`), so their biases cancel out of eq (1)'s
``r·L_c + u·T`` and enter only through the reference's slip ``v̂_s`` (docs/field_bias.md §7.32).

* The row's ``H`` gives the measurement the biased rates form: ``z − H·x = 0`` (1e-12 m/s) for the true state with
  the gyro and wheel-speed biases in ``b_g``, ``b_w``, on a turn with steered axles and a reading.
* In the filter, a zeroed gyro bias of 2 mrad/s on a straight leaves the slip state within 1e-4 m/s of the truth
  (0); with eq (1)'s ``−L_c`` in ``H`` it read ``L_c·b_g`` ≈ 0.019 m/s.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_model import BG, BW, VS, StateLayout
from sensor.fusion_reference import OwnReference
from sensor.fusion_slip import ZeroSlipNoise
from tests.test_fusion import CAMERA, DT, PARAMS, tractor_signals

OWN = "trailer_lateral_acceleration"


def test_the_rows_h_forms_the_biased_rates_measurement() -> None:
    noise = FusionNoise(kinematic_rear_point=OWN, reference_road_friction=0.8)
    reference = OwnReference(PARAMS, 1, noise)
    fused = FusedVisoOt(PARAMS, CAMERA, noise)
    weights = fused.steer_weights
    steer = np.full(weights.size, 0.05)
    yaw_rate, speed, lateral, b_g, b_w = 0.3, 6.0, 1.5, 0.002, 0.05
    tan_steer = float(np.dot(weights, np.tan(steer)))
    true_slip = reference.slip_velocity(yaw_rate, speed, steer, lateral)
    measured = (yaw_rate + b_g, speed + b_w, tan_steer)
    z_c, _ = reference.lateral(measured[0], measured[1], steer, lateral)
    zero_slip = ZeroSlipNoise(noise, StateLayout.of(noise), fused.slip_point)
    zero_slip.rate_sensitivity = reference.rate_sensitivity(steer, lateral)
    ((h, z, _),) = zero_slip.rows(measured, z_c, DT, np.zeros(StateLayout.of(noise).size))
    x = np.zeros(h.size)
    x[VS], x[BG], x[BW] = true_slip, b_g, b_w
    assert z - h @ x == pytest.approx(0.0, abs=1e-12)


def test_a_zeroed_gyro_bias_leaves_the_slip_state_unbiased() -> None:
    bias, speed = 0.002, 5.0
    noise = FusionNoise(kinematic_rear_point=OWN)
    fused = FusedVisoOt(PARAMS, CAMERA, noise)
    fused.zero_gyro(bias, 500)
    signals = replace(tractor_signals(speed, 0.0, 0.0, "lateral_acceleration", 0.0), unit_lateral_acceleration=0.0)
    for tick in range(500):
        fused.propagate(tick, DT, bias, speed, None, signals)
    assert fused.state[BG] == pytest.approx(bias, abs=1e-5)
    assert abs(fused.state[VS]) < 1e-4  # without the reference's own H: L_c·b_g ≈ 0.019 m/s
