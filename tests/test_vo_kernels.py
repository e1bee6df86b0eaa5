"""Compiled VO kernels (numba): the same matches and inliers as a reference numpy implementation.

That implementation is not in the tree (one way to do each thing); what it produced on a synthetic sequence
is stored here as digests of the match arrays and inlier masks, computed with that implementation at
commit 0d7d437. The kernels are also checked against their own Python source, run by the interpreter
(``NUMBA_DISABLE_JIT=1``) in a subprocess on a small image, which catches differences of integer and
float semantics between numba and Python/numpy.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from vo_synthetic import StereoRig, planar_sequence

from sensor.vo import StereoOdometry

# (matches, inliers, digest of the matches, digest of the inlier mask) of frames 1–3 of
# planar_sequence(4, step=0.5) with seed 3, from the numpy implementation (commit 0d7d437).
REFERENCE = {
    "default": [
        (426, 371, "9e368c6d89375dc1", "a73ec45781682246"),
        (423, 382, "0e0b13469e02ce19", "50376e45ae64c5b4"),
        (428, 366, "695fd0400e2557f4", "bde5972f29168064"),
    ],
    "subpixel": [
        (426, 394, "0f2409eb1b8e418e", "d46835d539de29ff"),
        (423, 394, "49e9528316998928", "ed123826e98e7b9b"),
        (428, 388, "f1f0c1d7dfbf5d26", "277be9956add1964"),
    ],
    "full_resolution_single_stage": [
        (430, 399, "69b0f0091d2a5353", "d0ff647446da93d8"),
        (430, 391, "55c3982a1eeadfeb", "a64a12d7adf6f084"),
        (430, 400, "543362a16e9cb140", "e94e672d5f16f0fc"),
    ],
}
OVERRIDES = {
    "default": {},
    "subpixel": {"refinement": 2},
    "full_resolution_single_stage": {"half_resolution": False, "multi_stage": False},
}


def _digest(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()[:16]


def _fingerprints(seq, config, seed: int) -> list[tuple[int, int, str, str]]:
    vo = StereoOdometry(config, seed=seed)
    results = [vo.process(left, right) for left, right in zip(seq.left, seq.right, strict=True)]
    return [
        (r.n_matches, int(r.inliers.sum()), _digest(np.round(r.matches, 9)), _digest(np.packbits(r.inliers)))
        for r in results[1:]
    ]


@pytest.fixture(scope="module")
def sequence():
    return planar_sequence(4, step=0.5)


@pytest.mark.parametrize("variant", sorted(REFERENCE))
def test_matches_and_inliers_equal_the_numpy_reference(sequence, variant):
    # Frames 2 and 3 are matched with the previous motion as prior, frame 1 without.
    assert _fingerprints(sequence, sequence.rig.vo_config(**OVERRIDES[variant]), seed=3) == REFERENCE[variant]


_SMALL = (
    "import json, sys\n"
    "sys.path.insert(0, 'tests')\n"  # the tests' own modules (vo_synthetic), as pytest sees them
    "from test_vo_kernels import _small_fingerprints\n"
    "json.dump(_small_fingerprints(), sys.stdout)\n"
)


def _small_fingerprints() -> list[list]:
    """Fingerprints of a small sequence (fast enough for the interpreter), with every kernel involved."""
    rig = StereoRig(width=256, height=128)
    seq = planar_sequence(3, step=0.4, rig=rig)
    out = []
    for overrides in ({"ransac_iters": 40}, {"ransac_iters": 40, "refinement": 2}):
        config = rig.vo_config(quality_min_inliers=0, **overrides)
        vo = StereoOdometry(config, seed=1)
        for left, right in zip(seq.left, seq.right, strict=True):
            r = vo.process(left, right)
            motion = None if r.motion is None else r.motion.tolist()
            out.append([r.n_matches, _digest(np.round(r.matches, 9)), _digest(np.packbits(r.inliers)), motion])
    return out


def test_compiled_kernels_equal_their_python_source():
    compiled = json.loads(json.dumps(_small_fingerprints()))
    assert sum(row[0] for row in compiled) > 50  # the small images do give matches
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    run = subprocess.run([sys.executable, "-c", _SMALL], env=env, cwd=root, capture_output=True, text=True, check=True)
    interpreted = json.loads(run.stdout)
    assert [row[:3] for row in interpreted] == [row[:3] for row in compiled]
    for a, b in zip(interpreted, compiled, strict=True):  # same operations: equal up to libm's last bit
        assert (a[3] is None) == (b[3] is None)
        if a[3] is not None:
            assert np.allclose(a[3], b[3], rtol=0, atol=1e-12)


def test_the_simd_sad_equals_numpys_on_all_byte_values_and_random_rows():
    # _sad32 is LLVM IR written by hand (kernels_search): check it against numpy on rows covering all byte pairs.
    import numba

    from sensor.vo.kernels_search import _sad32

    @numba.njit
    def all_pairs(a, b):
        out = np.empty((a.shape[0], b.shape[0]), dtype=np.int64)
        for i in range(a.shape[0]):
            for j in range(b.shape[0]):
                out[i, j] = _sad32(a, i, b, j)
        return out

    rng = np.random.default_rng(0)
    values = np.arange(256, dtype=np.uint8)
    a = np.vstack([np.resize(values, (8, 32)), rng.integers(0, 256, (24, 32), dtype=np.uint8)])
    b = np.vstack([np.resize(values[::-1], (8, 32)), rng.integers(0, 256, (24, 32), dtype=np.uint8)])
    b = np.hstack([b, rng.integers(0, 256, (32, 5), dtype=np.uint8)])  # wider rows: only the first 32 bytes count
    expected = np.abs(a[:, None, :].astype(np.int64) - b[None, :, :32].astype(np.int64)).sum(axis=2)
    assert np.array_equal(all_pairs(a, np.ascontiguousarray(b)), expected)
