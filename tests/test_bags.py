"""ROS bags: write a recording as ROS 1 / ROS 2 (sqlite3, mcap) bag and read it back."""

from __future__ import annotations

import shutil
import sys

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.recording.bag.read import read_bag
from graphcal.recording.bag.reader import bag_topics, is_bag
from graphcal.recording.bag.request import BagRequest
from graphcal.recording.bag.topics import pick_joints
from graphcal.recording.streams import ImuStream, PoseStream, Recording, StreamError, WheelStream
from graphcal.simulate.bags import BagTopics, write_bag

pytest.importorskip("rosbags")

STORAGES = {"ros1": "drive.bag", "ros2": "drive", "mcap": "drive_mcap"}
ORIGIN = (47.4734, 19.0597)


def _recording(geodetic: bool = True, cumulative: bool = True, imu: bool = True) -> Recording:
    """60 s on a circle of 40 m: pose at 10 Hz, wheels and IMU at 100 Hz, own start and phase."""
    tp = 3.0123 + 0.1 * np.arange(600)
    angle = 2 * np.pi * (tp - tp[0]) / 60.0
    pose = PoseStream(
        t=tp,
        x=40.0 * np.sin(angle),  # starts at the origin: the reader's frame is the first fix's
        y=40.0 * (1.0 - np.cos(angle)),
        heading=None if geodetic else angle,  # 0 … 2π: read back wrapped
        sideslip=None,
        source="hand",
        origin=ORIGIN if geodetic else None,
    )
    tw = 2.0047 + 0.01 * np.arange(6000)
    rate = np.column_stack([4.0 + 0.2 * np.sin(tw), 4.1 + 0.2 * np.cos(tw)])  # rev/s
    left, right = (np.cumsum(rate, axis=0) * 0.01).T if cumulative else rate.T
    wheels = WheelStream(tw, left, right, cumulative=cumulative, source="hand")
    ti = 2.5031 + 0.01 * np.arange(6000)
    stream = ImuStream(ti, 2.0 * np.sin(0.3 * ti), 0.1 * np.cos(0.2 * ti), "hand") if imu else None
    return Recording(pose, wheels, stream, "hand")


def _wrapped(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


def _assert_same(read: Recording, written: Recording) -> None:
    p, q = read.pose, written.pose
    np.testing.assert_allclose(p.t, q.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(p.x, q.x, rtol=0, atol=1e-3)
    np.testing.assert_allclose(p.y, q.y, rtol=0, atol=1e-3)
    if q.heading is None:
        assert p.heading is None
        assert p.origin == pytest.approx(q.origin, abs=1e-12)
    else:
        assert p.origin is None
        np.testing.assert_allclose(_wrapped(p.heading - q.heading), 0.0, atol=1e-9)
    w, v = read.wheels, written.wheels
    assert w.cumulative == v.cumulative
    np.testing.assert_allclose(w.t, v.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(w.left, v.left, rtol=0, atol=1e-9)
    np.testing.assert_allclose(w.right, v.right, rtol=0, atol=1e-9)
    if written.imu is None:
        assert read.imu is None
        return
    np.testing.assert_allclose(read.imu.t, written.imu.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        read.imu.lateral_acceleration, written.imu.lateral_acceleration, atol=1e-12
    )
    np.testing.assert_allclose(read.imu.yaw_rate, written.imu.yaw_rate, atol=1e-12)


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The recording written once with each storage kind."""
    directory = tmp_path_factory.mktemp("bags")
    recording = _recording()
    return {s: write_bag(recording, directory / n, s) for s, n in STORAGES.items()}


@pytest.mark.parametrize("storage", list(STORAGES))
@pytest.mark.slow
def test_navsatfix_recording_round_trips(bags, storage):
    path = bags[storage]
    assert is_bag(path)
    read = read_bag(path)
    _assert_same(read, _recording())
    assert bag_topics(path) == {
        "/gnss/fix": "sensor_msgs/msg/NavSatFix",
        "/imu/data": "sensor_msgs/msg/Imu",
        "/joint_states": "sensor_msgs/msg/JointState",
    }
    assert read.pose.source.endswith(":/gnss/fix")
    assert any("rear_left_wheel_joint, rear_right_wheel_joint" in n for n in read.notes)


@pytest.mark.parametrize("storage", list(STORAGES))
@pytest.mark.slow
def test_odometry_with_heading_round_trips(tmp_path, storage):
    recording = _recording(geodetic=False)
    path = write_bag(
        recording, tmp_path / STORAGES[storage], storage, topics=BagTopics(pose="/odom")
    )
    assert bag_topics(path)["/odom"] == "nav_msgs/msg/Odometry"
    _assert_same(read_bag(path, BagRequest(pose_topic="/odom")), recording)


@pytest.mark.slow
def test_bare_mcap_file_reads_by_its_own_path(bags, tmp_path):
    directory = bags["mcap"]
    mcap = directory / f"{directory.name}.mcap"
    assert mcap.is_file() and is_bag(mcap)
    _assert_same(read_bag(mcap), _recording())
    alone = tmp_path / "only_the_file"  # a directory with the .mcap but no metadata.yaml
    alone.mkdir()
    shutil.copy(mcap, alone / "x.mcap")
    assert is_bag(alone)
    _assert_same(read_bag(alone), _recording())


def test_joint_velocities_and_no_imu(tmp_path):
    recording = _recording(cumulative=False, imu=False)
    path = write_bag(recording, tmp_path / "speeds", "ros2")
    read = read_bag(path)
    assert not read.wheels.cumulative
    _assert_same(read, recording)
    with pytest.raises(StreamError, match=r"no position .*--wheel-kind angular_speed") as error:
        read_bag(path, BagRequest(wheel_kind="angle"))
    assert "\n" not in str(error.value)


def test_rewriting_replaces_the_bag(tmp_path):
    path = tmp_path / "again"
    write_bag(_recording(imu=False), path, "mcap")
    write_bag(_recording(), path, "mcap")
    assert read_bag(path).imu is not None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again"]
    (tmp_path / "notes.bag").mkdir()
    (tmp_path / "notes.bag" / "mine.txt").write_text("keep")
    with pytest.raises(StreamError, match="not a bag"):
        write_bag(_recording(), tmp_path / "notes.bag", "ros2")


def _one_line(error: pytest.ExceptionInfo, *words: str) -> None:
    message = str(error.value)
    assert "\n" not in message
    for word in words:
        assert word in message, (word, message)


def test_missing_topic_wrong_type_and_missing_joint(bags):
    path = bags["ros2"]
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(pose_topic="/nope"))
    _one_line(error, "/nope", "--pose-topic", "/gnss/fix (sensor_msgs/msg/NavSatFix)")
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(pose_topic="/imu/data"))
    _one_line(error, "/imu/data", "sensor_msgs/msg/Imu", "NavSatFix")
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(rear_left="wheel_rl", rear_right="rear_right_wheel_joint"))
    _one_line(error, "wheel_rl", "rear_left_wheel_joint", "--rear-left/--rear-right")
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(rear_left="rear_left_wheel_joint"))
    _one_line(error, "--rear-right", "rear_right_wheel_joint")


def test_not_a_bag(tmp_path):
    text = tmp_path / "drive.csv"
    text.write_text("t,x\n0,1\n")
    for path in (text, tmp_path / "missing.bag", tmp_path):
        assert not is_bag(path)
        with pytest.raises(StreamError) as error:
            read_bag(path)
        _one_line(error, str(path))


def test_corrupt_bags(tmp_path, bags):
    garbage = tmp_path / "garbage.bag"
    garbage.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 4)
    cut = tmp_path / "cut.mcap"
    mcap = bags["mcap"] / f"{bags['mcap'].name}.mcap"
    cut.write_bytes(mcap.read_bytes()[:5000])
    for path, hint in ((garbage, "rosbag reindex"), (cut, "mcap recover")):
        with pytest.raises(StreamError) as error:
            read_bag(path)
        _one_line(error, str(path), "cannot read the bag", hint)


def test_missing_rosbags_names_the_extra(bags, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags", None)
    with pytest.raises(StreamError, match=r'pip install -e "\.\[ros\]"'):
        read_bag(bags["ros1"])


# --- bags written message by message: what write_bag does not produce ------------------------


def _write_messages(path, messages: list[tuple[str, str, int, object]]) -> None:
    """A ROS 2 bag of ``(topic, type, receive time [ns], message)``."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=9) as writer:
        connections = {}
        for topic, msgtype, _, _ in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
        for topic, msgtype, received, message in messages:
            writer.write(connections[topic], received, store.serialize_cdr(message, msgtype))


def _types():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE).types


def _header(t: float):
    types = _types()
    sec, nanosec = divmod(round(t * 1e9), 1_000_000_000)
    stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    return types["std_msgs/msg/Header"](stamp=stamp, frame_id="f")


def _fix(t: float, latitude: float, longitude: float, status: int = 0):
    types = _types()
    return types["sensor_msgs/msg/NavSatFix"](
        header=_header(t),
        status=types["sensor_msgs/msg/NavSatStatus"](status=status, service=1),
        latitude=latitude,
        longitude=longitude,
        altitude=0.0,
        position_covariance=np.zeros(9),
        position_covariance_type=0,
    )


def _joints(t: float, names: list[str], position: list[float], velocity: list[float]):
    return _types()["sensor_msgs/msg/JointState"](
        header=_header(t),
        name=names,
        position=np.array(position, dtype=float),
        velocity=np.array(velocity, dtype=float),
        effort=np.zeros(0),
    )


def _pose_stamped(t: float, x: float):
    types = _types()
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return types["geometry_msgs/msg/PoseStamped"](header=_header(t), pose=pose)


FIX, JOINTS = "sensor_msgs/msg/NavSatFix", "sensor_msgs/msg/JointState"
FOUR = ["front_left", "Rear_Left_Wheel", "front_right", "rear_right_wheel"]


def test_joints_by_name_in_any_order_stamps_status_and_duplicates(tmp_path):
    messages = []
    for k in range(20):
        t = 100.0 + 0.1 * k
        status = -1 if k in (3, 4) else 0
        messages.append(("/fix", FIX, 10**9 * k, _fix(t, 47.0 + 1e-5 * k, 19.0, status)))
    for k in range(50):
        t = 100.0 + 0.05 * k
        names = FOUR if k % 2 else FOUR[::-1]
        value = {"front_left": 0.0, "Rear_Left_Wheel": k, "front_right": 0.0}
        value["rear_right_wheel"] = 2.0 * k
        position = [value[n] for n in names]
        messages.append(("/joints", JOINTS, 10**9 * k + 1, _joints(t, names, position, [])))
    messages.append(("/joints", JOINTS, 10**11, _joints(101.0, ["front_left"], [0.0], [])))
    messages.append(("/joints", JOINTS, 10**11 + 1, _joints(100.05, FOUR, [0, 1, 0, 2], [])))
    path = tmp_path / "handmade"
    _write_messages(path, messages)
    read = read_bag(path)
    notes = " | ".join(read.notes)
    assert "Rear_Left_Wheel, rear_right_wheel picked automatically" in notes
    assert "skipped 2 NavSatFix without a fix" in notes
    assert "skipped 1 JointState message(s) without both" in notes
    assert "/joints: dropped 1 message(s) repeating the time and values" in notes
    assert len(read.pose.t) == 18 and read.imu is None
    np.testing.assert_allclose(read.wheels.t, 100.0 + 0.05 * np.arange(50), atol=1e-9)
    np.testing.assert_allclose(read.wheels.left * 2 * np.pi, np.arange(50), atol=1e-12)
    np.testing.assert_allclose(read.wheels.right * 2 * np.pi, 2.0 * np.arange(50), atol=1e-12)


def test_a_stamp_written_twice_with_other_values_is_refused_naming_both_messages(tmp_path, capsys):
    """Issue 26 row G, the rule CSV streams follow too: a stamp repeated with the same values
    is dropped with a note (above), with other values refused, naming the topic, both
    messages (1-based, in the topic's order in the bag) and the values that differ."""
    messages = []
    for k in range(20):
        messages.append(("/fix", FIX, 10**9 * k, _fix(100.0 + 0.1 * k, 47.0 + 1e-5 * k, 19.0)))
    for k in range(50):
        joints = _joints(100.0 + 0.05 * k, ["rl", "rr"], [k, 2.0 * k], [])
        messages.append(("/joints", JOINTS, 10**9 * k + 1, joints))
    messages.append(("/joints", JOINTS, 10**11, _joints(100.05, ["rl", "rr"], [9.0, 2.0], [])))
    path = tmp_path / "twice"
    _write_messages(path, messages)
    assert main(["check", str(path), "--rear-left", "rl", "--rear-right", "rr"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"{path}:/joints: message 2 and message 51 have the same time 100.05 s" in err, err
    assert "position[rl] 1.0 vs 9.0" in err and "position[rr]" not in err, err


def test_zero_stamps_use_receive_times_and_velocity_fallback(tmp_path):
    messages = []
    for k in range(10):
        pose = _pose_stamped(0.0, float(k))
        messages.append(("/pose", "geometry_msgs/msg/PoseStamped", 5 * 10**9 + 10**8 * k, pose))
        joints = _joints(0.0, ["rl", "rr"], [], [2 * np.pi, 4 * np.pi])
        messages.append(("/joints", JOINTS, 5 * 10**9 + 10**8 * k + 7, joints))
    path = tmp_path / "stampless"
    _write_messages(path, messages)
    with pytest.raises(StreamError) as error:
        read_bag(path)
    _one_line(error, "rl, rr", "--rear-left/--rear-right")
    read = read_bag(path, BagRequest(rear_left="rl", rear_right="rr"))
    assert sum("receive times" in n for n in read.notes) == 2
    np.testing.assert_allclose(read.pose.t, 5.0 + 0.1 * np.arange(10), atol=1e-9)
    np.testing.assert_allclose(read.pose.heading, 0.0)
    assert not read.wheels.cumulative
    np.testing.assert_allclose(read.wheels.left, 1.0)
    np.testing.assert_allclose(read.wheels.right, 2.0)


def test_several_candidate_topics_ask_for_the_flag(tmp_path):
    messages = []
    for k in range(5):
        t = 1.0 + 0.1 * k
        messages.append(("/fix", FIX, k + 1, _fix(t, 47.0, 19.0)))
        messages.append(("/pose", "geometry_msgs/msg/PoseStamped", k + 1, _pose_stamped(t, k)))
        messages.append(("/joints", JOINTS, k + 1, _joints(t, ["left", "right"], [k, k], [])))
    path = tmp_path / "two_poses"
    _write_messages(path, messages)
    with pytest.raises(StreamError) as error:
        read_bag(path)
    _one_line(error, "/fix (NavSatFix)", "/pose (PoseStamped)", "--pose-topic")
    assert read_bag(path, BagRequest(pose_topic="/pose")).pose.source.endswith(":/pose")


def test_pick_joints():
    assert pick_joints(["wheel_left", "wheel_right"]) == ("wheel_left", "wheel_right")
    assert pick_joints(FOUR) == ("Rear_Left_Wheel", "rear_right_wheel")
    assert pick_joints(["fl_left", "fr_right", "ml_left", "mr_right"]) is None
    assert pick_joints(["a", "b"]) is None


@pytest.mark.parametrize("storage", list(STORAGES))
@pytest.mark.slow
def test_vectorized_decoding_equals_rosbags_message_by_message(bags, storage, monkeypatch):
    import graphcal.recording.bag.reader as reader

    fast = read_bag(bags[storage])
    monkeypatch.setattr(reader, "FAST_DECODING", False)
    slow = read_bag(bags[storage])
    for role in ("pose", "wheels", "imu"):
        a, b = getattr(fast, role), getattr(slow, role)
        for name, value in vars(a).items():
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(value, getattr(b, name), err_msg=f"{role}.{name}")
    assert fast.notes == slow.notes


def test_messages_of_different_layouts_are_not_decoded_together():
    from graphcal.recording.bag.layout import IMU, decode_fixed

    assert decode_fixed([b"\x00\x01" + bytes(10), b"\x00\x01" + bytes(11)], IMU, False) is None
    assert decode_fixed([b"\x01\x00" + bytes(400)], IMU, False) is None  # big-endian CDR


def _imu(t: float, rng: np.random.Generator):
    """An Imu message whose every number changes, as a real IMU's do."""
    types = _types()

    def vector(*xyz):
        return types["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2])

    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return types["sensor_msgs/msg/Imu"](
        header=_header(t),
        orientation=types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
        orientation_covariance=rng.normal(size=9),
        angular_velocity=vector(*rng.normal(size=3)),
        angular_velocity_covariance=rng.normal(size=9),
        linear_acceleration=vector(*rng.normal(size=3)),
        linear_acceleration_covariance=rng.normal(size=9),
    )


def test_real_imu_and_joint_messages_decode_vectorized_as_rosbags_does(tmp_path, monkeypatch):
    # Every number of a real IMU changes, and a JointState carries more joints than the two
    # rear wheels: only the frame id, names and lengths are the same in every message.
    import graphcal.recording.bag.reader as reader
    from graphcal.recording.bag import layout as bag_layout

    rng = np.random.default_rng(3)
    messages = []
    for k in range(300):
        t = 50.0 + 0.01 * k
        messages.append(("/imu", "sensor_msgs/msg/Imu", 10**7 * k, _imu(t, rng)))
        position = rng.normal(size=4) + k
        messages.append(("/joints", JOINTS, 10**7 * k + 1, _joints(t, FOUR, position, position)))
        if k % 10 == 0:
            messages.append(("/fix", FIX, 10**7 * k + 2, _fix(t, 47.0 + 1e-6 * k, 19.0)))
    path = tmp_path / "real"
    _write_messages(path, messages)
    decoded = []
    original = bag_layout.decode_fixed

    def counting(*args, **kwargs):
        result = original(*args, **kwargs)
        decoded.append(result is not None)
        return result

    monkeypatch.setattr(reader, "decode_fixed", counting)
    fast = read_bag(path)
    assert decoded and all(decoded)  # the vectorized path took every chunk
    monkeypatch.setattr(reader, "FAST_DECODING", False)
    slow = read_bag(path)
    for role in ("wheels", "imu"):
        a, b = getattr(fast, role), getattr(slow, role)
        for name, value in vars(a).items():
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(value, getattr(b, name), err_msg=f"{role}.{name}")
