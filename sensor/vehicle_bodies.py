"""The combination's own bodies in the cameras' view: every unit's box and wheels, placed at its pose each frame.

Geometry (docs/combination_view.md): each unit is drawn in its own frame — the tractor's stations from its steer
axle, a towed unit's from its kingpin (:func:`vehicle_model.geometry.unit_frame`), x forward, y left, z up — from
the unit's ``front_x``, ``rear_x``, ``width`` and axles (:class:`vehicle_model.parameters.VehicleParams`):

* a **semi-trailer or centre-axle trailer**: a closed van box from :data:`DECK_HEIGHT` to :data:`BOX_HEIGHT`; on a
  unit that tows another on a fifth wheel (a B-double's lead trailer) the box stops :data:`COUPLING_CLEARANCE`
  ahead of the next unit's front, and a low deck (:data:`CHASSIS_TOP`) carries the coupling behind it;
* a **converter dolly**: a low chassis;
* the **tractor**: a cab (:data:`CAB_LENGTH` behind its front) and a low chassis behind it;
* **wheels**: one dual-tyre wheel each side per axle, :attr:`~vehicle_model.parameters.TyreParams.unloaded_radius`.

Closed boxes also carry their inside faces (dark): a camera placed inside another unit's body is blind, as it would
be. Surfaces carry features like real bodies (:func:`body_textures`: panel seams, rivet rows, a livery and a logo;
chassis cross-members; tyre treads), shaded per face in the vertex colours (the renderer is unlit).

:func:`exclusion_masks` projects the same boxes (the known articulation: where the rig's neighbours are) into a
camera's image, for the odometry to take no features on them (:mod:`sensor.vo.masks`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from vehicle_model.geometry import ChainPose, CombinationPose, chain_pose, unit_frame
from vehicle_model.parameters import VehicleParams
from vehicle_model.terrain import Terrain
from vehicle_model.terrain_pose import is_flat, unit_attitudes

__all__ = [
    "BOX_HEIGHT",
    "CAB_HEIGHT",
    "CAB_LENGTH",
    "CHASSIS_TOP",
    "COUPLING_CLEARANCE",
    "DECK_HEIGHT",
    "BodyBox",
    "body_textures",
    "exclusion_masks",
    "unit_boxes",
    "unit_mesh",
    "unit_poses",
]

BOX_HEIGHT = 4.3
"""Top of a van body above the ground [m] (the Australian height limit; the UK's 4.0–4.9 m)."""
DECK_HEIGHT = 1.25
"""Underside of a semi-trailer's body above the ground [m] (a fifth-wheel height of about 1.2 m)."""
CHASSIS_TOP = 1.2
"""Top of a chassis or deck without a body (tractor behind the cab, dolly, a lead trailer's coupling deck) [m]."""
CHASSIS_BOTTOM = 0.6
"""Underside of a chassis [m]."""
CAB_LENGTH = 2.4
"""Length of a tractor's cab behind its front [m]."""
CAB_HEIGHT = 3.9
"""Top of a tractor's cab (with its roof fairing) [m]."""
CAB_BOTTOM = 0.5
"""Underside of a tractor's cab [m]."""
COUPLING_CLEARANCE = 0.3
"""Gap between a lead trailer's box and the front of the unit it tows on its fifth wheel [m]."""
TWIN_TYRE_WIDTH = 0.6
"""Width of a dual-tyre wheel [m]."""
WHEEL_SIDES = 16
"""Polygon sides of a wheel."""
TEXTURE_TILE = {"body": 4.0, "chassis": 2.0, "tyre": 1.0}
"""Metres covered by one repeat of each body texture (UV 0 → 1)."""


@dataclass(frozen=True)
class BodyBox:
    """An axis-aligned box in a unit's frame.

    Attributes
    ----------
    lo, hi : tuple of float
        Opposite corners (x, y, z) [m] in the unit's frame (stations as the unit's params, y left, z up).
    kind : str
        ``"body"`` (a closed van box or a cab), ``"chassis"`` (a deck or chassis) or ``"wheel"`` (the box around a
        wheel).
    """

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    kind: str


def _wheel_boxes(axles, width: float) -> list[BodyBox]:
    out = []
    for axle in axles:
        r = float(axle.tyre.unloaded_radius)
        outer = 0.5 * width
        inner = outer - (TWIN_TYRE_WIDTH if axle.n_tyres >= 4 else 0.5 * TWIN_TYRE_WIDTH)
        for sign in (1.0, -1.0):
            ys = sorted((sign * inner, sign * outer))
            out.append(BodyBox((axle.x - r, ys[0], 0.0), (axle.x + r, ys[1], 2.0 * r), "wheel"))
    return out


@functools.lru_cache(maxsize=16)
def _unit_boxes(params: VehicleParams) -> tuple[tuple[BodyBox, ...], ...]:
    return tuple(tuple(boxes) for boxes in unit_boxes(params))


def unit_boxes(params: VehicleParams) -> list[list[BodyBox]]:
    """The boxes of every unit, the tractor first (index 0), then the towed units front to rear (module docstring).

    Parameters
    ----------
    params : VehicleParams
        The combination.

    Returns
    -------
    list of list of BodyBox
        Per unit, its body, chassis and wheel boxes in the unit's frame.
    """
    t = params.tractor
    w = 0.5 * t.width
    cab_rear = max(t.rear_x, t.front_x - CAB_LENGTH)
    tractor = [BodyBox((cab_rear, -w, CAB_BOTTOM), (t.front_x, w, CAB_HEIGHT), "body")]
    if cab_rear > t.rear_x:
        tractor.append(BodyBox((t.rear_x, -w, CHASSIS_BOTTOM), (cab_rear, w, CHASSIS_TOP), "chassis"))
    units = [tractor + _wheel_boxes(t.axles, t.width)]
    trailers = params.trailers
    for k, unit in enumerate(trailers):
        w = 0.5 * unit.width
        boxes: list[BodyBox] = []
        if not unit.front_load:  # a converter dolly: a chassis under its fifth wheel
            boxes.append(BodyBox((unit.rear_x, -w, CHASSIS_BOTTOM), (unit.front_x, w, CHASSIS_TOP), "chassis"))
        else:
            box_rear = unit.rear_x
            if unit.fifth_wheel_x is not None and k + 1 < len(trailers):
                box_rear = min(unit.front_x, max(unit.rear_x, unit.fifth_wheel_x + trailers[k + 1].front_x))
                box_rear = (
                    min(unit.front_x - 0.5, box_rear + COUPLING_CLEARANCE) if box_rear > unit.rear_x else box_rear
                )
            boxes.append(BodyBox((box_rear, -w, DECK_HEIGHT), (unit.front_x, w, BOX_HEIGHT), "body"))
            if box_rear > unit.rear_x:
                boxes.append(BodyBox((unit.rear_x, -w, CHASSIS_BOTTOM), (box_rear, w, CHASSIS_TOP), "chassis"))
        units.append(boxes + _wheel_boxes(unit.axles, unit.width))
    return units


def _frame(origin: np.ndarray, heading: float) -> np.ndarray:
    c, s = math.cos(heading), math.sin(heading)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:2, 3] = origin
    return out


def unit_poses(
    params: VehicleParams, pose: CombinationPose | ChainPose, terrain: Terrain | None = None
) -> list[np.ndarray | None]:
    """``T_world←unit`` (4×4) of every unit at ``pose``, the tractor first; ``None`` for a unit the pose does not
    place (a :class:`~vehicle_model.geometry.CombinationPose` places the tractor and the first towed unit).

    On a ``terrain`` (not flat) each unit's frame is lifted to its height and turned by its kinematic pitch and roll
    (:func:`vehicle_model.terrain_pose.unit_attitudes`)."""
    out = _level_unit_poses(params, pose)
    if is_flat(terrain):
        return out
    for frame, att in zip(out, unit_attitudes(params, pose, terrain), strict=True):
        if frame is not None and att is not None:
            frame[:3, :3] = att.rotation
            frame[2, 3] = float(att.z)
    return out


def _level_unit_poses(params: VehicleParams, pose: CombinationPose | ChainPose) -> list[np.ndarray | None]:
    full = chain_pose(pose)
    x, y, psi1 = float(full.x), float(full.y), float(full.psi1)
    tractor = _frame(np.array([x, y]), psi1)
    tractor[:2, 3] -= tractor[:2, 0] * params.tractor.cg_x  # the frame's origin is the steer axle's station 0
    out: list[np.ndarray | None] = [tractor]
    for unit in range(1, len(params.trailers) + 1):
        if len(full.angles) < unit:
            out.append(None)
            continue
        origin, heading = unit_frame(params, full, unit)
        out.append(_frame(np.asarray(origin, float), float(heading)))
    return out


# -- textures ------------------------------------------------------------------------------------------------------


def _noise(rng: np.random.Generator, shape: tuple[int, int], scale: float) -> np.ndarray:
    """Seamless noise of unit std whose finest detail is about ``scale`` texels."""
    from .textures import fractal_noise

    return fractal_noise(rng, shape, 1.0, f_max=shape[0] / (2.0 * scale))


def body_textures(seed: int = 0) -> dict[str, np.ndarray]:
    """The bodies' textures, ``(512, 512, 3)`` uint8 RGB each, seamless (``body``, ``chassis``, ``tyre``).

    ``body``: a van side of vertical panels with seams and rivet rows, top and bottom rails, a livery band, a logo
    and grime; ``chassis``: dark steel with cross-members and bolts; ``tyre``: rubber with tread blocks and a hub.
    """
    rng = np.random.default_rng([seed, 0xB0D1])
    n = 512
    yy, xx = np.mgrid[0:n, 0:n]
    body = 0.86 + 0.03 * _noise(rng, (n, n), 20.0) + 0.015 * _noise(rng, (n, n), 1.5)
    for x0 in range(0, n, 64):  # panel seams every 0.5 m, rivets along them every 4 cm
        body[:, x0 : x0 + 2] -= 0.25
        body[(yy % 5 == 0) & (np.abs(xx - x0 - 5) <= 1) & (np.abs(yy % 5) == 0)] -= 0.35
    rgb = np.repeat(body[..., None], 3, axis=2) * np.array([235, 235, 228], np.float32)
    rgb[20:34] = (70, 72, 78)  # top rail (texture row 0 is the top)
    rgb[478:496] = (70, 72, 78)  # bottom rail
    rgb[300:340] = (30, 90, 170)  # livery band
    rgb[344:350] = (220, 60, 40)
    img = np.clip(rgb, 0, 255).astype(np.uint8)
    cv2.circle(img, (128, 200), 54, (220, 60, 40), -1, cv2.LINE_AA)
    cv2.circle(img, (128, 200), 30, (245, 245, 240), -1, cv2.LINE_AA)
    cv2.putText(img, "OFFTRACK", (200, 222), cv2.FONT_HERSHEY_DUPLEX, 2.0, (30, 90, 170), 5, cv2.LINE_AA)
    cv2.putText(img, "LOGISTICS 0800 42", (200, 270), cv2.FONT_HERSHEY_SIMPLEX, 1.0, (40, 40, 40), 2, cv2.LINE_AA)
    for x0 in range(0, n, 64):
        img[40:470:16, x0 + 4 : x0 + 7] = (90, 90, 90)  # rivet heads along every seam
    grime = np.clip(_noise(rng, (n, n), 6.0), 1.0, 3.0)[..., None] - 1.0
    img = np.clip(img.astype(np.float32) * (1.0 - 0.2 * grime), 0, 255).astype(np.uint8)

    steel = 45 + 8 * _noise(rng, (n, n), 4.0)
    steel[:, (xx[0] % 128) < 20] = 25  # cross-members
    steel[((yy % 64) < 10) & ((xx % 128) < 36) & ((xx % 128) > 20)] = 90  # bolts and brackets
    chassis = np.repeat(np.clip(steel, 0, 255)[..., None], 3, axis=2).astype(np.uint8)

    rubber = 28 + 6 * _noise(rng, (n, n), 2.0)
    rubber[((yy // 24 + xx // 48) % 2 == 0) & ((xx % 48) < 36)] += 22  # tread blocks
    r = np.hypot(xx - n / 2 + 0.5, yy - n / 2 + 0.5)
    hub = r < 0.36 * n
    rubber[hub] = 150 + 20 * _noise(rng, (n, n), 3.0)[hub]
    ang = np.arctan2(yy - n / 2, xx - n / 2)
    studs = (np.abs(r - 0.22 * n) < 10) & (np.cos(10 * ang) > 0.8)
    rubber[studs] = 40
    rubber[r < 0.06 * n] = 60
    tyre = np.repeat(np.clip(rubber, 0, 255)[..., None], 3, axis=2).astype(np.uint8)
    return {"body": img, "chassis": chassis, "tyre": tyre}


# -- meshes --------------------------------------------------------------------------------------------------------

_FACE_SHADE = {"X": 0.78, "x": 0.78, "Y": 0.92, "y": 0.86, "Z": 1.0, "z": 0.45}
"""Baked shade of each face of a box (front/rear, left/right, top/bottom): the renderer is unlit."""


def _box_mesh(box: BodyBox, tile: float, inside: bool) -> tuple[np.ndarray, ...]:
    from .world.mesh import box as box_faces

    lo, hi = np.asarray(box.lo, float), np.asarray(box.hi, float)
    size = tuple(hi - lo)
    base = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2])
    pos, uv, idx, col = [], [], [], []
    for face in "xXyYzZ":
        p, u, i, _ = box_faces(size, tile, base, faces=face)
        u = u.copy()
        u[:, 1] = u[:, 1] + 0.25 - (hi[2] - lo[2]) / tile  # the livery at the same height on every box side
        c = np.tile([_FACE_SHADE[face]] * 3 + [1.0], (4, 1))
        pos.append(p), uv.append(u), idx.append(i), col.append(c)
        if inside and box.kind == "body":  # the inside: the same quad wound the other way, dark
            pos.append(p), uv.append(u), idx.append(i[:, ::-1]), col.append(np.tile([0.08] * 3 + [1.0], (4, 1)))
    return _merge(pos, uv, idx, col)


def _merge(pos, uv, idx, col) -> tuple[np.ndarray, ...]:
    out_i, n = [], 0
    for p, i in zip(pos, idx, strict=True):
        out_i.append(np.asarray(i, np.int64) + n)
        n += len(p)
    return (
        np.vstack(pos).astype(np.float32),
        np.vstack(uv).astype(np.float32),
        np.vstack(out_i).astype(np.uint32),
        np.vstack(col).astype(np.float32),
    )


def _wheel_mesh(box: BodyBox) -> tuple[np.ndarray, ...]:
    """A wheel (an n-gon cylinder about the y axis with its two discs) inside its box."""
    r = 0.5 * (box.hi[0] - box.lo[0])
    cx, cz = 0.5 * (box.hi[0] + box.lo[0]), r
    th = np.linspace(0.0, 2.0 * math.pi, WHEEL_SIDES + 1)
    ring = np.column_stack([cx + r * np.cos(th), cz + r * np.sin(th)])
    y0, y1 = box.lo[1], box.hi[1]
    pos, uv, idx, col = [], [], [], []
    # tread: quads between consecutive ring points, outward
    for k in range(WHEEL_SIDES):
        (xa, za), (xb, zb) = ring[k], ring[k + 1]
        p = np.array([[xa, y1, za], [xb, y1, zb], [xb, y0, zb], [xa, y0, za]])
        u = np.array([[th[k] * r, 0.0], [th[k + 1] * r, 0.0], [th[k + 1] * r, 0.5], [th[k] * r, 0.5]])
        shade = 0.5 + 0.4 * max(0.0, math.sin(0.5 * (th[k] + th[k + 1])))
        (
            pos.append(p),
            uv.append(u),
            idx.append(np.array([[0, 1, 2], [0, 2, 3]])),
            col.append(np.tile([shade] * 3 + [1], (4, 1))),
        )
    # discs: a fan about the centre, outward on each side (+y: anticlockwise seen from +y)
    for y, outward in ((y1, 1.0), (y0, -1.0)):
        p = np.vstack([[cx, y, cz], np.column_stack([ring[:-1, 0], np.full(WHEEL_SIDES, y), ring[:-1, 1]])])
        u = 0.5 + 0.5 * np.column_stack([(p[:, 0] - cx) / r, (p[:, 2] - cz) / r])
        tri = np.array([[0, 1 + k, 1 + (k + 1) % WHEEL_SIDES] for k in range(WHEEL_SIDES)])
        if outward > 0:
            tri = tri[:, ::-1]
        pos.append(p), uv.append(u), idx.append(tri), col.append(np.tile([0.8] * 3 + [1], (len(p), 1)))
    return _merge(pos, uv, idx, col)


def unit_mesh(boxes: list[BodyBox]) -> dict[str, tuple[np.ndarray, ...]]:
    """A unit's triangles by texture (``body``, ``chassis``, ``tyre``): ``(positions, texcoords, indices, colours)``
    each, in the unit's frame; outward faces anticlockwise, a closed body's inside faces dark."""
    parts: dict[str, list[tuple[np.ndarray, ...]]] = {}
    for box in boxes:
        if box.kind == "wheel":
            parts.setdefault("tyre", []).append(_wheel_mesh(box))
        else:
            texture = "body" if box.kind == "body" else "chassis"
            parts.setdefault(texture, []).append(_box_mesh(box, TEXTURE_TILE[texture], inside=True))
    out = {}
    for texture, meshes in parts.items():
        pos, uv, idx, col = zip(*meshes, strict=True)
        out_i, n = [], 0
        for p, i in zip(pos, idx, strict=True):
            out_i.append(i.astype(np.int64) + n)
            n += len(p)
        out[texture] = (np.vstack(pos), np.vstack(uv), np.vstack(out_i).astype(np.uint32), np.vstack(col))
    return out


# -- masks ---------------------------------------------------------------------------------------------------------

_FACES = (
    (0, 2, 6, 4),  # corners indexed by (x hi?, y hi?, z hi?) bits: 4·x + 2·y + z
    (1, 3, 7, 5),
    (0, 1, 5, 4),
    (2, 3, 7, 6),
    (0, 1, 3, 2),
    (4, 5, 7, 6),
)


def _clip_near(poly: np.ndarray, z_min: float) -> np.ndarray:
    """Sutherland–Hodgman clip of a polygon ``(n, 3)`` in camera coordinates to ``z ≥ z_min``."""
    out = []
    n = len(poly)
    for k in range(n):
        a, b = poly[k], poly[(k + 1) % n]
        ina, inb = a[2] >= z_min, b[2] >= z_min
        if ina:
            out.append(a)
        if ina != inb:
            t = (z_min - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.asarray(out)


def exclusion_masks(
    params: VehicleParams,
    pose: CombinationPose | ChainPose,
    cameras: tuple[np.ndarray, ...],
    k: np.ndarray,
    size: tuple[int, int],
    *,
    skip_unit: int | None,
    margin_px: int = 8,
    z_min: float = 0.05,
    terrain: Terrain | None = None,
) -> tuple[np.ndarray, ...] | None:
    """Where the combination's units are in each camera's image: pixels the odometry should take no features from.

    Parameters
    ----------
    params : VehicleParams
        The combination.
    pose : CombinationPose or ChainPose
        Where it is (the known articulation angles); units the pose does not place are left out.
    cameras : tuple of numpy.ndarray
        ``T_world←camera`` (4×4, OpenCV axes) of each camera (e.g. the left and right of a rig).
    k : numpy.ndarray
        Camera matrix (3×3) of the images.
    size : (int, int)
        Image width and height [px].
    skip_unit : int or None
        The unit the cameras are mounted on (0: the tractor), not masked (a rig does not see its own body).
    margin_px : int
        The mask is grown by this many pixels (a feature's descriptor window reaches that far).
    z_min : float
        Faces are clipped to at least this distance in front of the camera [m].
    terrain : Terrain, optional
        The ground the units stand on (:func:`unit_poses`); ``None``: the level road.

    Returns
    -------
    tuple of numpy.ndarray or None
        One ``(height, width)`` bool mask per camera, True where a unit (or its margin) is; ``None`` when no camera
        sees any unit (nothing to exclude).
    """
    width, height = size
    boxes = _unit_boxes(params)
    frames = unit_poses(params, pose, terrain)
    masks: list[np.ndarray | None] = [None for _ in cameras]
    corners_bits = np.array([[(b >> 2) & 1, (b >> 1) & 1, b & 1] for b in range(8)], float)
    for unit, (unit_box, frame) in enumerate(zip(boxes, frames, strict=True)):
        if frame is None or unit == skip_unit:
            continue
        for box in unit_box:
            lo, hi = np.asarray(box.lo), np.asarray(box.hi)
            local = lo + corners_bits * (hi - lo)
            world = local @ frame[:3, :3].T + frame[:3, 3]
            for c, cam in enumerate(cameras):
                pc = (world - cam[:3, 3]) @ cam[:3, :3]
                if (pc[:, 2] < z_min).all():
                    continue
                mask = masks[c]
                if mask is None:
                    mask = masks[c] = np.zeros((height, width), np.uint8)
                for face in _FACES:
                    poly = _clip_near(pc[list(face)], z_min)
                    if len(poly) < 3:
                        continue
                    uv = (poly[:, :2] / poly[:, 2:3]) * [k[0, 0], k[1, 1]] + [k[0, 2], k[1, 2]]
                    uv = np.clip(uv, -4.0 * (width + height), 4.0 * (width + height))
                    cv2.fillConvexPoly(mask, np.round(uv * 16).astype(np.int32), 1, cv2.LINE_8, shift=4)
    if not any(m is not None and m.any() for m in masks):
        return None
    filled = [np.zeros((height, width), np.uint8) if m is None else m for m in masks]
    if margin_px > 0:
        kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * margin_px + 1, 2 * margin_px + 1))
        filled = [cv2.dilate(m, kernel) for m in filled]
    return tuple(m.view(bool) for m in filled)  # 0 or 1: the same bytes as bools
