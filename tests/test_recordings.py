"""Recorded sequences and what comes with them (:mod:`sensor.recordings`, :mod:`scenarios.recorded`), without rendering.

Readers (KITTI folder, video pair, ROS 1/2 bags written with rosbags' own writer), the rig file, the signals CSV,
reference poses turned into the truth, the relative pose error and the KITTI metric on constructed trajectories,
and every bad input of ``offtrack estimate`` / ``offtrack vo-eval`` refused in one line with exit 2 before any work.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.recorded.reference import reference_columns, trailer_path
from scenarios.recorded.rig import load_rig
from sensor.camera import StereoRig
from sensor.recordings.bag import BagPair
from sensor.recordings.kitti import KittiFolder, read_kitti_calib
from sensor.recordings.poses import interpolate_poses, read_tum_poses
from sensor.recordings.sequence import time_gaps
from sensor.recordings.signals import read_signals
from sensor.recordings.video import VideoPair
from sensor.recordings.vo_metrics import chain_motions, kitti_metric, relative_pose_error, true_motions
from vehicle_model.errors import InputError

W, H = 64, 48
RIG = "vehicle: lst\npsi_c2v_deg: 180\nlever_arm_m: [-14.05, 0.0, 3.0]\n"


def _images(n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(0)
    return [
        (rng.integers(0, 256, (H, W), dtype=np.uint8), rng.integers(0, 256, (H, W), dtype=np.uint8)) for _ in range(n)
    ]


def _kitti(folder: Path, n: int = 5, f: float = 50.0, baseline: float = 0.5) -> Path:
    for sub in ("image_0", "image_1"):
        (folder / sub).mkdir(parents=True)
    for k, (left, right) in enumerate(_images(n)):
        cv2.imwrite(str(folder / "image_0" / f"{k:06d}.png"), left)
        cv2.imwrite(str(folder / "image_1" / f"{k:06d}.png"), right)
    (folder / "times.txt").write_text("".join(f"{0.1 * k:.6e}\n" for k in range(n)))
    p0 = f"{f} 0 31.5 0 0 {f} 23.5 0 0 0 1 0"
    p1 = f"{f} 0 31.5 {-f * baseline} 0 {f} 23.5 0 0 0 1 0"
    (folder / "calib.txt").write_text(f"P0: {p0}\nP1: {p1}\nP2: {p0}\nP3: {p1}\n")
    (folder / "poses.txt").write_text("".join("1 0 0 0 0 1 0 0 0 0 1 " + f"{-0.5 * k}\n" for k in range(n)))
    return folder


@pytest.fixture()
def rig(tmp_path: Path) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(RIG)
    return path


# --------------------------------------------------------------------------------------------------- readers


def test_a_kitti_folder_is_read_in_order_with_its_camera_and_a_dropped_frame(tmp_path: Path) -> None:
    folder = _kitti(tmp_path / "seq")
    (folder / "image_1" / "000002.png").unlink()  # frame 2 dropped
    rec = KittiFolder(folder)
    assert rec.size == (W, H) and len(rec.slots) == 5
    assert [s.missing for s in rec.slots] == ["", "", "image_missing", "", ""]
    assert rec.camera.f == 50.0 and rec.camera.baseline == pytest.approx(0.5, rel=1e-12)
    images = _images(5)
    for slot, left, right in rec.pairs():
        if slot.index == 2:
            assert left is None and right is None
        else:
            assert np.array_equal(left, images[slot.index][0]) and np.array_equal(right, images[slot.index][1])
    assert [s.index for s, _, _ in rec.pairs(3)] == [3, 4]


def test_gaps_in_the_times_are_found_against_the_median_interval() -> None:
    times = np.array([0.0, 0.1, 0.21, 0.3, 0.5, 0.6, 0.76, 0.86])  # 0.2 s and 0.16 s intervals: dropped frames
    assert time_gaps(times) == [
        (4, pytest.approx(0.2), pytest.approx(0.1)),
        (6, pytest.approx(0.16), pytest.approx(0.1)),
    ]
    assert time_gaps(np.arange(10) * 0.1 + np.r_[0, 0.01, -0.01, 0, 0, 0.02, 0, 0, 0, 0]) == []  # jitter is no gap


def test_kitti_folders_that_cannot_work_are_refused_naming_the_file(tmp_path: Path) -> None:
    folder = _kitti(tmp_path / "seq")
    (folder / "times.txt").write_text("0\n0.1\n0.1\n0.3\n0.4\n")
    with pytest.raises(InputError, match=r"times.txt: line 3 \(0.1 s\) does not come after line 2"):
        KittiFolder(folder)
    (folder / "times.txt").write_text("0\n0.1\n0.2\n")
    with pytest.raises(InputError, match=r"image 000003 lies beyond the 3 lines of times\.txt"):
        KittiFolder(folder)
    (folder / "times.txt").write_text("0\n0.1\n0.2\n0.3\n0.4\n")
    cv2.imwrite(str(folder / "image_0" / "000001.png"), np.zeros((H + 2, W), np.uint8))
    with pytest.raises(InputError, match="mixed image sizes"):
        KittiFolder(folder)
    (folder / "calib.txt").write_text("P0: 50 0 31.5 0 0 50 23.5 0 0 0 1 0\nP1: 55 0 31.5 -25 0 55 23.5 0 0 0 1 0\n")
    with pytest.raises(InputError, match="not a rectified pair"):
        read_kitti_calib(folder / "calib.txt")


def test_a_video_pair_decodes_losslessly_and_its_count_is_checked(tmp_path: Path) -> None:
    images = _images(6)
    for side, index in (("left", 0), ("right", 1)):
        writer = cv2.VideoWriter(str(tmp_path / f"{side}.mkv"), cv2.VideoWriter_fourcc(*"FFV1"), 10, (W, H), False)
        for pair in images:
            writer.write(pair[index])
        writer.release()
    times = tmp_path / "times.txt"
    times.write_text("".join(f"{100.0 + 0.1 * k + (0.02 if k == 3 else 0.0):.3f}\n" for k in range(6)))
    rec = VideoPair(tmp_path / "left.mkv", tmp_path / "right.mkv", times)
    assert rec.t0 == 100.0 and rec.times[3] == pytest.approx(0.32) and rec.size == (W, H)
    got = list(rec.pairs())
    assert all(
        np.array_equal(left, images[s.index][0]) and np.array_equal(right, images[s.index][1]) for s, left, right in got
    )
    times.write_text("".join(f"{0.1 * k}\n" for k in range(9)))
    with pytest.raises(InputError, match="6 frames for 9 timestamps"):
        VideoPair(tmp_path / "left.mkv", tmp_path / "right.mkv", times)


def _write_bag(
    path: Path, images: list[tuple[np.ndarray, np.ndarray]], *, ros1: bool = False, skip_right: int = -1
) -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    image_type = store.types["sensor_msgs/msg/Image"]
    header, stamp = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    if ros1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
    else:
        from rosbags.rosbag2 import Writer

        writer = Writer(path, version=9)
    with writer:
        kwargs = {"typestore": store}
        left = writer.add_connection("/stereo/left/image_raw", image_type.__msgtype__, **kwargs)
        right = writer.add_connection("/stereo/right/image_raw", image_type.__msgtype__, **kwargs)
        for k, (a, b) in enumerate(images):
            ns = 1_700_000_000_000_000_000 + k * 100_000_000
            for connection, image, skew in ((left, a, 0), (right, b, 1_000)):  # the right stamped 1 µs later
                if connection is right and k == skip_right:
                    continue
                t = stamp(sec=(ns + skew) // 10**9, nanosec=(ns + skew) % 10**9)
                head = header(seq=k, stamp=t, frame_id="cam") if ros1 else header(stamp=t, frame_id="cam")
                message = image_type(
                    header=head, height=H, width=W, encoding="mono8", is_bigendian=0, step=W, data=image.ravel()
                )
                raw = (
                    store.serialize_ros1(message, image_type.__msgtype__)
                    if ros1
                    else store.serialize_cdr(message, image_type.__msgtype__)
                )
                writer.write(connection, ns + skew, raw)


@pytest.mark.parametrize("ros1", [False, True])
def test_a_bag_pairs_its_two_image_topics_by_stamp(tmp_path: Path, ros1: bool) -> None:
    images = _images(5)
    path = tmp_path / ("stereo.bag" if ros1 else "stereo")
    _write_bag(path, images, ros1=ros1, skip_right=3)
    rec = BagPair(path, "/stereo/left/image_raw", "/stereo/right/image_raw")
    assert rec.size == (W, H) and rec.t0 == pytest.approx(1.7e9)
    assert [s.missing for s in rec.slots] == ["", "", "", "no_right_image", ""]
    assert rec.times == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4])
    for slot, left, right in rec.pairs():
        if slot.index != 3:
            assert np.array_equal(left, images[slot.index][0]) and np.array_equal(right, images[slot.index][1])
    with pytest.raises(InputError, match="has no topic /stereo/depth; its image topics: /stereo/left/image_raw"):
        BagPair(path, "/stereo/left/image_raw", "/stereo/depth")


# ------------------------------------------------------------------------------------------ rig and signals


def test_the_rig_file_gives_the_cameras_pose_a_run_uses(tmp_path: Path, rig: Path) -> None:
    loaded = load_rig(rig)
    assert loaded.params.name and loaded.params.follow_point_offset == 14.05
    run_rig = StereoRig(baseline=0.5, station=-14.05, lateral=0.0, mount_height=3.0, psi_c2v=math.pi)
    assert np.array_equal(loaded.camera_in_trailer(0.5), run_rig.camera_in_trailer("left"))
    tilted = tmp_path / "tilted.yaml"
    tilted.write_text(RIG + "pitch_deg: 10\nfollow_point_offset_m: 12.0\n")
    pose = load_rig(tilted).camera_in_trailer(0.5)
    assert pose[2, 2] == pytest.approx(-math.sin(math.radians(10.0)))  # the optical axis looks down 10°
    assert pose[0, 2] == pytest.approx(-math.cos(math.radians(10.0)))  # and rearwards
    assert load_rig(tilted).params.follow_point_offset == 12.0
    np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-12)


def test_the_signals_csv_is_read_in_si_and_the_trailer_signals_derived(tmp_path: Path, rig: Path) -> None:
    path = tmp_path / "signals.csv"
    t = np.arange(0.0, 2.0, 0.02)
    rows = ["time_s,speed_m_s,yaw_rate_deg_s,articulation_deg"]
    rows += [f"{ti},{5.0},{10.0},{2.0 * ti}" for ti in t]  # articulation rising 2 °/s
    path.write_text("\n".join(rows) + "\n")
    series = read_signals(path)
    assert series.yaw_rate[0] == pytest.approx(math.radians(10.0))
    at = series.at(np.array([0.5, 1.0, 5.0]), load_rig(rig).params)
    # r2 = r1 − dΓ/dt (Γ = ψ1 − ψ2): 10 − 2 = 8 °/s
    assert at["trailer_yaw_rate"][:2] == pytest.approx([math.radians(8.0)] * 2)
    assert math.isnan(at["speed"][2])
    assert np.all(np.isnan(at["lateral_acceleration"]))  # no accelerometer column: none
    with_accelerometer = tmp_path / "with_accelerometer.csv"
    with_accelerometer.write_text("time_s,speed_m_s,yaw_rate_deg_s,articulation_deg,lateral_acceleration_m_s2\n")
    with with_accelerometer.open("a") as fh:
        fh.writelines(f"{ti},5.0,10.0,0.0,{0.5 + ti}\n" for ti in t)
    at = read_signals(with_accelerometer).at(np.array([0.5, 1.01]), load_rig(rig).params)
    assert at["lateral_acceleration"] == pytest.approx([1.0, 1.51])  # m/s², interpolated
    path.write_text("time_s,speed_m_s,articulation_deg\n0,1,2\n0.1,1,2\n")
    with pytest.raises(InputError, match="no column yaw_rate_deg_s or yaw_rate_rad_s"):
        read_signals(path)


# -------------------------------------------------------------------------------------------- the truth


def test_reference_poses_of_a_crabbing_trailer_give_its_off_tracking(rig: Path) -> None:
    # The trailer moves in a straight line at β = 5° to its own axis (de Saxe & Cebon 2018, §3's constant slip): the
    # kingpin's past path at the follow point's station lies at y = −L_fp·tan β.
    loaded = load_rig(rig)
    x_cam = loaded.camera_in_trailer(0.5)
    beta, n = math.radians(5.0), 120
    s = np.linspace(0.0, 30.0, n)
    trailer = np.tile(np.eye(4), (n, 1, 1))
    trailer[:, 0, 3] = s * math.cos(beta)
    trailer[:, 1, 3] = s * math.sin(beta)
    camera = trailer @ x_cam  # T_world←camera = T_world←trailer·T_trailer←camera
    times = np.arange(n) * 0.1
    kingpin, heading = trailer_path(camera, x_cam)
    np.testing.assert_allclose(kingpin, trailer[:, :2, 3], atol=1e-9)
    np.testing.assert_allclose(heading, 0.0, atol=1e-12)
    cols = reference_columns(times, 14.05, x_cam, (times, camera), None)
    settled = s > 14.05 / math.cos(beta) + 0.5
    expected = -14.05 * math.tan(beta)
    np.testing.assert_allclose(cols["offtracking_truth"][settled], expected, atol=1e-9)
    np.testing.assert_allclose(cols["offtracking_truth_geometric"][settled], expected, atol=1e-9)
    assert np.all(np.isnan(cols["offtracking_truth"][s < 14.0]))  # one trailer length before there is a truth


def test_tum_poses_are_interpolated_between_their_times(tmp_path: Path) -> None:
    path = tmp_path / "tum.txt"
    half = math.sin(math.radians(15.0)), math.cos(math.radians(15.0))  # 30° about z
    path.write_text(f"# t x y z qx qy qz qw\n10.0 0 0 0 0 0 0 1\n11.0 2 0 0 0 0 {half[0]} {half[1]}\n")
    times, poses = read_tum_poses(path)
    mid = interpolate_poses(times, poses, np.array([10.5, 12.0]))
    assert mid[0, 0, 3] == pytest.approx(1.0)
    assert math.degrees(math.atan2(mid[0, 1, 0], mid[0, 0, 0])) == pytest.approx(15.0)
    assert np.all(np.isnan(mid[1]))


# ----------------------------------------------------------------------------------------------- VO metrics


def _drive(n: int, step: float, yaw_per_m: float = 0.0) -> np.ndarray:
    """Camera poses T_ref←camera driving forward (+z) ``step`` per frame, turning ``yaw_per_m`` about y."""
    poses = [np.eye(4)]
    for _ in range(n - 1):
        a = yaw_per_m * step
        move = np.eye(4)
        move[:3, :3] = [[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]]
        move[2, 3] = step
        poses.append(poses[-1] @ move)
    return np.array(poses)


def test_the_relative_pose_error_and_the_kitti_metric_measure_constructed_errors() -> None:
    truth = _drive(400, 1.0, yaw_per_m=0.002)
    motions = true_motions(truth)
    assert relative_pose_error(motions[5], motions[5]) == pytest.approx((0.0, 0.0), abs=1e-15)
    assert chain_motions(motions) == pytest.approx(truth, abs=1e-9)
    exact = kitti_metric(truth, truth)
    assert exact["segments"] > 0 and exact["translation_percent"] == pytest.approx(0.0, abs=1e-9)
    # every motion 1 % too long: 1 % translation error over every segment length, no rotation error
    longer = motions.copy()
    longer[:, :3, 3] *= 1.01
    scaled = kitti_metric(truth, chain_motions(longer))
    # (a segment ends at the first frame beyond its length: up to a 1 m frame longer, so 1.0016 % here)
    assert scaled["translation_percent"] == pytest.approx(1.0, rel=5e-3)
    assert scaled["rotation_deg_per_m"] == pytest.approx(0.0, abs=1e-9)
    counts = {k: v["segments"] for k, v in scaled["per_length"].items()}
    assert counts["100"] == 30 and counts["300"] == 10 and counts["400"] == 0  # a 399 m path has no 400 m segment
    # one extra millidegree of yaw per frame: a rotation error of 1 mdeg per metre (1 m frames)
    turned = motions.copy()
    extra = np.eye(4)
    a = math.radians(1e-3)
    extra[:3, :3] = [[math.cos(a), 0, -math.sin(a)], [0, 1, 0], [math.sin(a), 0, math.cos(a)]]
    turned = turned @ extra
    assert kitti_metric(truth, chain_motions(turned))["rotation_deg_per_m"] == pytest.approx(1e-3, rel=1e-2)
    t_err, r_err = relative_pose_error(turned[0], motions[0])
    assert t_err == pytest.approx(0.0, abs=1e-12) and math.degrees(r_err) == pytest.approx(1e-3, rel=1e-6)


# -------------------------------------------------------------------------------- bad input: one line, exit 2


def _refused(args: list[str]) -> str:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_each_bad_input_of_estimate_is_one_line_and_exit_2_before_any_work(tmp_path: Path, rig: Path) -> None:
    folder = _kitti(tmp_path / "seq")
    out = tmp_path / "out"
    base = ["estimate", str(folder), "--rig", str(rig), "--out", str(out)]
    assert "not found" in _refused(["estimate", str(tmp_path / "nowhere"), "--rig", str(rig), "--out", str(out)])
    bad = tmp_path / "bad"
    shutil.copytree(folder, bad)
    (bad / "image_1" / "000003.png").write_bytes(b"\x89PNG\r\n\x1a\n but then nothing an image has")
    assert "000003.png: unreadable image" in _refused(["estimate", str(bad), "--rig", str(rig), "--out", str(out)])
    (folder / "calib.txt").write_text("P0: 50 0 31.5 0 0 50 23.5 0 0 0 1 0\n")
    assert "calib.txt: has no P1" in _refused(base)
    _kitti(tmp_path / "seq2")
    far = tmp_path / "far.yaml"
    far.write_text("vehicle: lst\npsi_c2v_deg: 180\nlever_arm_m: [-40.0, 0.0, 3.0]\n")
    line = _refused(["estimate", str(tmp_path / "seq2"), "--rig", str(far), "--out", str(out)])
    assert "lever_arm_m = [-40, 0, 3] puts the camera off the lst trailer" in line
    bag = tmp_path / "stereo"
    _write_bag(bag, _images(3))
    line = _refused(
        [
            "estimate",
            str(bag),
            "--rig",
            str(rig),
            "--left-topic",
            "/stereo/left/image_raw",
            "--right-topic",
            "/cam/right",
            "--calib",
            str(tmp_path / "seq2" / "calib.txt"),
            "--out",
            str(out),
        ]
    )
    assert "has no topic /cam/right" in line
    good = ["estimate", str(tmp_path / "seq2"), "--rig", str(rig), "--out", str(out)]
    assert "--rear-point 'centre': allowed: axle_mean, equivalent" in _refused([*good, "--rear-point", "centre"])
    signals = tmp_path / "signals.csv"
    signals.write_text("time_s,speed_m_s,yaw_rate_deg_s,articulation_deg\n0,1,0,0\n0.1,1,0,0\n")
    line = _refused([*good, "--signals", str(signals), "--rear-point", "lateral_acceleration"])
    assert "needs the tractor's accelerometer: a --signals CSV with a lateral_acceleration_m_s2 column" in line
    assert not out.exists()  # nothing was written


def test_bad_input_of_vo_eval_is_one_line_and_exit_2(tmp_path: Path) -> None:
    folder = _kitti(tmp_path / "seq")
    (folder / "poses.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
    assert "1 poses for 5 frames" in _refused(["vo-eval", str(folder)])
    (folder / "poses.txt").unlink()
    assert "has no poses.txt" in _refused(["vo-eval", str(folder)])


def test_the_motion_prior_stretches_over_a_dropped_frame() -> None:
    from vo_synthetic import planar_sequence, relative_motion

    from sensor.vo import StereoOdometry

    seq = planar_sequence(5, step=0.5)
    vo = StereoOdometry(seq.rig.vo_config(), seed=0)
    vo.scale_prior(2.0)  # no prior yet: nothing to stretch
    for k in (0, 1, 2):
        result = vo.process(seq.left[k], seq.right[k])
    prior = vo._prior.copy()
    vo.scale_prior(2.0)
    vo.scale_prior(0.5)
    np.testing.assert_allclose(vo._prior, prior, atol=1e-12)  # stretched and shrunk back
    vo.scale_prior(2.0)  # frame 3 dropped: the next motion spans two frame periods
    np.testing.assert_allclose(vo._prior[:3, 3], 2.0 * prior[:3, 3], rtol=1e-12)
    result = vo.process(seq.left[4], seq.right[4])
    t_err, r_err = relative_pose_error(result.motion, relative_motion(seq.poses[2], seq.poses[4]))
    assert result.valid and t_err < 0.02 and math.degrees(r_err) < 0.1  # 1 m and 2° over the gap
    with pytest.raises(ValueError, match="ratio"):
        vo.scale_prior(0.0)
