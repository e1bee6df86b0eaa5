"""The pyrender scene of a world: draw groups in a fixed order, instancing, per-view culling, one scene per world."""

from __future__ import annotations

import dataclasses
import weakref
from typing import Any

import numpy as np

from .gl_context import import_pyrender
from .world import World

__all__ = ["BAKE_MAX_INSTANCES", "BodyNodes", "InstanceCuller", "body_nodes", "build_scene", "scene_for"]


BAKE_MAX_INSTANCES = 32
"""Instanced parts with at most this many copies are baked into static geometry (fewer draw calls)."""

_RANK = {"scenery": 0, "roundabout": 1, "road": 2, "ground": 3, "shadow": 4}


def _draw_groups(world: World) -> list[tuple[float, str, Any]]:
    """Group the world's parts into draw calls: ``(rank, texture, part)``, in draw order.

    Parts without instancing (and those with few copies, transformed to world coordinates) are
    merged per texture; widely instanced parts stay instanced. Order: objects, roundabout, road,
    blended road lines, ground — roughly near to far, so hidden ground fails the depth test early,
    and the lines blend onto the asphalt drawn before them.
    """
    static: dict[str, list] = {}
    ranks: dict[str, float] = {}
    out: list[tuple[float, str, Any]] = []
    for part in world.parts:
        rank = float(_RANK.get(part.category, 0))
        if world.textures[part.texture].shape[2] == 4:
            rank = 2.5
        if part.poses is not None and part.instances > BAKE_MAX_INSTANCES:
            out.append((rank, part.texture, part))
            continue
        poses = [np.eye(4)] if part.poses is None else list(part.poses)
        for pose in poses:
            pos = part.positions.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
            static.setdefault(part.texture, []).append((pos, part.texcoords, part.colors, part.indices))
        ranks[part.texture] = min(ranks.get(part.texture, rank), rank)
    for texture, chunks in static.items():
        n, idx = 0, []
        for pos, _, _, ind in chunks:
            idx.append(ind.astype(np.int64) + n)
            n += len(pos)
        merged = dataclasses.replace(
            world.parts[0],
            name=f"static_{texture}",
            texture=texture,
            positions=np.vstack([c[0] for c in chunks]).astype(np.float32),
            texcoords=np.vstack([c[1] for c in chunks]).astype(np.float32),
            colors=np.vstack([c[2] for c in chunks]).astype(np.float32),
            indices=np.vstack(idx).astype(np.uint32),
            poses=None,
        )
        out.append((ranks[texture], texture, merged))
    out.sort(key=lambda g: g[0])  # stable: world order within a rank
    return out


def build_scene(world: World) -> tuple[Any, Any]:
    """The pyrender scene of a world and its camera node (intrinsics set per render).

    Parameters
    ----------
    world : World
        The procedural world.

    Returns
    -------
    scene, camera_node
        A ``pyrender.Scene`` (static geometry merged per texture, widely repeated objects
        instanced) and the node of its ``IntrinsicsCamera``. The scene carries its fixed draw
        order (``offtrack_draw_order``) and the per-view instance culler (``offtrack_culler``).
    """
    pyrender = import_pyrender()
    sampler = pyrender.Sampler(wrapS=pyrender.GLTF.REPEAT, wrapT=pyrender.GLTF.REPEAT)
    materials = {}
    for name, img in world.textures.items():
        rgba = img.shape[2] == 4  # road lines: soft-edged, blended onto the asphalt
        tex = pyrender.Texture(source=img, source_channels="RGBA" if rgba else "RGB", sampler=sampler)
        tex.offtrack_mipmaps = world.mipmaps.get(name)  # uploaded by the fast renderer (sensor.fast_renderer)
        materials[name] = pyrender.MetallicRoughnessMaterial(
            baseColorTexture=tex, metallicFactor=0.0, roughnessFactor=1.0, alphaMode="BLEND" if rgba else "OPAQUE"
        )
    # Clear alpha 0 marks the sky (surfaces write alpha 1; the grey image ignores alpha).
    scene = pyrender.Scene(bg_color=[*world.sky_rgb, 0.0], ambient_light=[1.0, 1.0, 1.0])
    nodes, instanced = [], []
    for _, texture, part in _draw_groups(world):
        prim = pyrender.Primitive(
            positions=part.positions,
            texcoord_0=part.texcoords,
            color_0=part.colors,
            indices=part.indices,
            material=materials[texture],
            poses=part.poses,
        )
        node = scene.add(pyrender.Mesh([prim], name=part.name))
        node.offtrack_alpha_only = part.category == "shadow"  # shadow decals: written to alpha only
        nodes.append(node)
        if part.poses is not None:
            instanced.append((prim, part))
    scene.offtrack_draw_order = nodes
    camera = pyrender.IntrinsicsCamera(1.0, 1.0, 0.0, 0.0)
    camera_node = scene.add(camera, pose=np.eye(4))
    scene.offtrack_culler = InstanceCuller(instanced)
    return scene, camera_node


class InstanceCuller:
    """Draws only the instances whose bounding spheres meet the view frustum.

    pyrender draws every instance of an instanced primitive; llvmpipe shades their vertices on the
    CPU whether or not they are on screen. Before each view, the visible instances' poses are
    written to the front of the primitive's instance buffer and the primitive's pose array is cut
    to them (pyrender draws ``len(primitive.poses)`` instances). Relies on pyrender 1.0.x's layout
    of a primitive's buffers (vertex buffer, then the instance buffer); disables itself otherwise.

    Parameters
    ----------
    items : list of (pyrender.Primitive, part)
        Each instanced primitive and the world part it was made from (its local positions and
        instance poses).
    """

    def __init__(self, items: list[tuple[Any, Any]]) -> None:
        self.items = []
        for prim, part in items:
            pos = part.positions.astype(np.float64)
            c0 = 0.5 * (pos.min(axis=0) + pos.max(axis=0))
            r0 = float(np.linalg.norm(pos - c0, axis=1).max())
            poses = np.asarray(part.poses, dtype=np.float64)
            centres = poses[:, :3, :3] @ c0 + poses[:, :3, 3]
            scale = np.linalg.norm(poses[:, :3, 0], axis=1)
            full = np.ascontiguousarray(np.transpose(poses, (0, 2, 1)).astype(np.float32))  # column-major rows
            self.items.append(
                {
                    "prim": prim,
                    "poses": prim.poses,
                    "gl": full,
                    "centres": centres,
                    "radius": r0 * scale,
                    "last": None,
                    "buffer": None,
                }
            )
        self.enabled = True

    def reset(self) -> None:
        """Forget the cut (before pyrender uploads the primitives again, e.g. after a scene switch)."""
        for it in self.items:
            it["prim"]._poses = it["poses"]
            it["last"] = it["buffer"] = None

    def apply(self, pose_cv: np.ndarray, half_h: float, half_v: float, far: float) -> None:
        """Cut every instanced primitive to the instances in the view frustum of one camera.

        Parameters
        ----------
        pose_cv : numpy.ndarray
            ``(4, 4)`` camera pose ``T_world←camera`` (OpenCV axes).
        half_h, half_v : float
            Half the horizontal and vertical field of view [rad].
        far : float
            Farthest distance along the optical axis that is drawn [m].
        """
        if not self.enabled:
            return
        from OpenGL import GL

        r, t = pose_cv[:3, :3], pose_cv[:3, 3]
        ch, sh, cv, sv = np.cos(half_h), np.sin(half_h), np.cos(half_v), np.sin(half_v)
        for it in self.items:
            prim = it["prim"]
            if not prim._in_context() or len(prim._buffers) < 2:
                continue
            p = (it["centres"] - t) @ r  # camera frame (OpenCV)
            rad = it["radius"]
            x, y, z = p[:, 0], p[:, 1], p[:, 2]
            vis = (z > -rad) & (z < far + rad)
            vis &= (ch * x + sh * z >= -rad) & (-ch * x + sh * z >= -rad)
            vis &= (cv * y + sv * z >= -rad) & (-cv * y + sv * z >= -rad)
            key = vis.tobytes()
            buffer = prim._buffers[1]
            if key == it["last"] and buffer == it["buffer"]:
                continue
            sel = np.flatnonzero(vis)
            if len(sel) == 0:
                sel = np.array([0])  # keep one instance (a zero count is not drawable by pyrender)
            try:
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, buffer)
                if buffer != it["buffer"]:  # first cut since pyrender (re)created the buffer
                    GL.glBufferData(GL.GL_ARRAY_BUFFER, it["gl"].nbytes, it["gl"], GL.GL_DYNAMIC_DRAW)
                GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, it["gl"][sel].nbytes, np.ascontiguousarray(it["gl"][sel]))
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
            except Exception:  # an unexpected pyrender layout: draw everything from now on
                self.enabled = False
                self.restore()
                return
            it["last"], it["buffer"] = key, buffer
            prim._poses = it["poses"][sel]

    def restore(self) -> None:
        """Draw every instance again (full instance buffers)."""
        from OpenGL import GL

        for it in self.items:
            prim = it["prim"]
            prim._poses = it["poses"]
            it["last"] = None
            if prim._in_context() and it["buffer"] is not None and prim._buffers[1] == it["buffer"]:
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, prim._buffers[1])
                GL.glBufferData(GL.GL_ARRAY_BUFFER, it["gl"].nbytes, it["gl"], GL.GL_DYNAMIC_DRAW)
                GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)


_SCENES: dict[int, tuple[weakref.ref, Any, Any]] = {}
"""pyrender scenes by world (id → (weak reference, scene, camera node)): renderers of one world share
its scene, so switching between them does not upload the textures again."""


def scene_for(world: World) -> tuple[Any, Any]:
    """The scene of a world and its camera node, built on first use and shared while the world lives.

    Parameters
    ----------
    world : World
        The procedural world.

    Returns
    -------
    scene, camera_node
        As :func:`build_scene`; the same objects for every call with the same world.
    """
    entry = _SCENES.get(id(world))
    if entry is not None and entry[0]() is world:
        return entry[1], entry[2]
    for key in [k for k, (ref, _, _) in _SCENES.items() if ref() is None]:
        del _SCENES[key]
    scene, node = build_scene(world)
    _SCENES[id(world)] = (weakref.ref(world), scene, node)
    return scene, node


class BodyNodes:
    """The combination's units as dynamic nodes of a world's scene: built once per scene and vehicle, posed per view.

    The static world stays as :func:`build_scene` made it; each unit (:func:`sensor.vehicle_bodies.unit_mesh`) is one
    node drawn before the world (opaque and near: the ground behind it then fails the depth test early).
    :meth:`place` sets every node's pose and visibility before a view; a hidden or unplaced unit draws nothing.

    Parameters
    ----------
    scene : pyrender.Scene
        A scene of :func:`build_scene` (its ``offtrack_draw_order`` gets the nodes in front).
    params : VehicleParams
        The combination.
    """

    def __init__(self, scene: Any, params: Any) -> None:
        from .vehicle_bodies import TEXTURE_TILE, body_textures, unit_boxes, unit_mesh

        pyrender = import_pyrender()
        sampler = pyrender.Sampler(wrapS=pyrender.GLTF.REPEAT, wrapT=pyrender.GLTF.REPEAT)
        materials = {
            name: pyrender.MetallicRoughnessMaterial(
                baseColorTexture=pyrender.Texture(source=img, source_channels="RGB", sampler=sampler),
                metallicFactor=0.0,
                roughnessFactor=1.0,
            )
            for name, img in body_textures().items()
            if name in TEXTURE_TILE
        }
        self.params = params
        self.nodes = []
        for k, boxes in enumerate(unit_boxes(params)):
            prims = [
                pyrender.Primitive(positions=p, texcoord_0=u, color_0=c, indices=i, material=materials[texture])
                for texture, (p, u, i, c) in unit_mesh(boxes).items()
            ]
            mesh = pyrender.Mesh(prims, name=f"vehicle_unit_{k}")
            mesh.is_visible = False
            self.nodes.append(scene.add(mesh, pose=np.eye(4)))
        scene.offtrack_draw_order = [*self.nodes, *scene.offtrack_draw_order]
        self.scene = scene

    def place(self, poses: list[np.ndarray | None] | None, hidden: int | None = None) -> None:
        """Pose every unit (``T_world←unit`` of :func:`sensor.vehicle_bodies.unit_poses`, ``None``: not drawn) and
        hide unit ``hidden`` (the rig's own); ``poses=None`` hides them all."""
        for k, node in enumerate(self.nodes):
            pose = None if poses is None or k == hidden else poses[k]
            node.mesh.is_visible = pose is not None
            if pose is not None:
                self.scene.set_pose(node, pose)


def body_nodes(scene: Any, params: Any) -> BodyNodes:
    """The :class:`BodyNodes` of ``params`` in ``scene``, added on first use and shared by every renderer of it."""
    table = getattr(scene, "offtrack_bodies", None)
    if table is None:
        table = scene.offtrack_bodies = {}
    entry = table.get(id(params))
    if entry is None or entry.params is not params:
        entry = table[id(params)] = BodyNodes(scene, params)
    return entry
