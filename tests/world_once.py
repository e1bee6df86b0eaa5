"""One procedural world per road and settings inside a block, for fixtures that build the same scenario's world
several times (a camera run and ``offtrack render`` of the same scenario, two rigs' exports of one run).

A scenario's camera builds its world with :func:`sensor.world.build_world` through
:func:`scenarios.camera.build.world_for_scenario`; the world is a function of the road path and the settings (the
same seed gives the same world: ``test_rendering.py``), so inside :func:`one_world_per_road` the second build of the
same road and settings is the first's world. A world on a terrain is built every time.
"""

from __future__ import annotations

import contextlib
import hashlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

import scenarios.camera.build as camera_build


def _road_key(path: Any) -> str:
    """A digest of the road path's geometry (its centre line, loop centres and curvature)."""
    digest = hashlib.sha256()
    for name in ("x", "y", "heading", "centres", "curvature"):
        value = getattr(path, name, None)
        digest.update(name.encode() + (b"-" if value is None else np.ascontiguousarray(value, float).tobytes()))
    return digest.hexdigest()


@contextlib.contextmanager
def one_world_per_road() -> Iterator[dict[tuple, object]]:
    """Within the block, the scenario cameras' worlds are built once per road and settings (the worlds made, by key,
    are yielded)."""
    build = camera_build.build_world
    made: dict[tuple, object] = {}

    def once(path: Any, config: Any = None, terrain: Any = None, **overrides: Any) -> object:
        if terrain is not None or config is not None:
            return build(path, config, terrain, **overrides)
        key = (_road_key(path), tuple(sorted((k, repr(v)) for k, v in overrides.items())))
        if key not in made:
            made[key] = build(path, **overrides)
        return made[key]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(camera_build, "build_world", once)
        yield made
