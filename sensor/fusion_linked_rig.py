"""The settings of a linked rig: a camera that looks along its unit (not a side rig) on a towed unit whose front
coupling rides on another towed unit (:attr:`~sensor.fusion_noise.FusionNoise.linked_rig`).

Such a unit is towed unit 2 or further of :class:`~vehicle_model.parameters.VehicleParams` (each further unit hangs
on the coupling of the unit ahead): a B-double's rear trailer on its lead trailer's fifth wheel, an A-double's rear
semi-trailer on its dolly (and the dolly on the lead trailer's hitch), a truck–dolly–semi's semi-trailer on its
dolly. Its kingpin moves as the unit ahead carries it, not as the tractor's fifth wheel does: the zero-slip
kinematics its filter weighs the camera against ((K1) of :mod:`sensor.fusion_model`, carried down the chain by
:mod:`sensor.unit_kinematics`) hold every coupling's articulation and every unit's slip ahead of it, while the
section's settings of the odometry's yaw error under scrub ((K6) of :mod:`sensor.fusion_slip`) were set on a
semi-trailer behind a tractor (docs/field_bias.md §6.11). A first towed unit's camera (a
tractor–semi-trailer's, a B-double's lead trailer's) never takes these; a side rig anywhere takes
:class:`~sensor.fusion_noise.SideRigFusion`'s instead (:meth:`~sensor.fusion_noise.FusionNoise.for_camera` decides).
"""

from __future__ import annotations

from pydantic import Field

from vehicle_model.settings import Settings

__all__ = ["LinkedRigFusion"]


class LinkedRigFusion(Settings):
    """The settings a linked rig's filter takes in place of the section's (``None``, the default of each: the
    section's own, so by default a linked rig's filter is the section's to the bit).

    Parameters
    ----------
    scrub_bias_release
        ``r`` of (K6) in :mod:`sensor.fusion_slip`, as :class:`~sensor.fusion_noise.FusionNoise`'s: the share of the
        odometry's estimated systematic yaw error ``β_ψ`` a frame's motion is no longer taken with at full scrub
        demand.
    vo_yaw_bias_walk
        The random walk of that yaw error per metre travelled [rad/m/√m], as
        :class:`~sensor.fusion_noise.FusionNoise`'s.
    """

    scrub_bias_release: float | None = Field(
        None, ge=0.0, le=1.0, description="share of β_ψ released at full scrub demand (K6); 1 takes none of it"
    )
    vo_yaw_bias_walk: float | None = Field(
        None, ge=0.0, le=1e-3, description="[rad/m/√m] the VO's yaw error's walk; 1e-3 forgets in a metre"
    )

    def given(self) -> dict[str, object]:
        """The settings it gives the filter (those not ``None``)."""
        return {name: value for name in type(self).model_fields if (value := getattr(self, name)) is not None}
