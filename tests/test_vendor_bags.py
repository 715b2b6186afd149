"""Bags whose wheels (heading, IMU) are fields of other messages: vendor wheel-speed messages
recognised by type, any numeric field named TOPIC:FIELD, and what goes wrong.

The message types are defined here, as a vendor's package defines them, and registered in
rosbags' typestore; the bags carry their definitions (ROS 1 connection headers, ROS 2
metadata), which is all the reader knows of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.evaluation import Truth, evaluate
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.recording.bag import reader as bag_reader
from graphcal.recording.bag.layout import decode_fields
from graphcal.recording.bag.read import read_bag
from graphcal.recording.bag.request import BagRequest
from graphcal.recording.importer import import_recording
from graphcal.recording.streams import Recording, StreamError
from graphcal.simulate.bags import _Messages, _stamps, _write, write_bag
from graphcal.simulate.streams import simulate_streams

pytest.importorskip("rosbags")

#: Every test here writes and reads vendor bags (most of a minute in all).
pytestmark = pytest.mark.slow

DATASPEED = "dbw_mkz_msgs/msg/WheelSpeedReport"
PACMOD = "pacmod3_msgs/msg/WheelSpeedRpt"
# As dataspeedinc/dbw_mkz_ros and astuff/pacmod3_msgs define them (wheel speeds in rad/s).
DEFINITIONS = {
    DATASPEED: "std_msgs/Header header\n\n# Wheel speeds (rad/s)\nfloat32 front_left\n"
    "float32 front_right\nfloat32 rear_left\nfloat32 rear_right\n",
    PACMOD: "std_msgs/Header header\n\nfloat64 front_left_wheel_speed\n"
    "float64 front_right_wheel_speed\nfloat64 rear_left_wheel_speed\n"
    "float64 rear_right_wheel_speed\n",
}
#: A made-up car's messages: wheels in a sequence of nested messages, a fixed array, a string,
#: and a message without a header.
CUSTOM = {
    "my_car_msgs/msg/Wheel": "float64 speed_kmh\nuint8 valid\n",
    "my_car_msgs/msg/Wheels": "std_msgs/Header header\nstring label\nmy_car_msgs/Wheel[] wheels\n"
    "float32[4] rpm\n",
    "my_car_msgs/msg/Dynamics": "float64 yaw_rate_dps\nfloat64 lateral_acceleration\n"
    "float64 azimuth_deg\n",
}
STORAGES = {"ros1": "drive.bag", "ros2": "drive_ros2"}
VENDOR_TOPIC = {DATASPEED: "/vehicle/wheel_speed_report", PACMOD: "/pacmod/wheel_speed_rpt"}


def _typestore(ros1: bool, definitions: dict[str, str]):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    for msgtype, text in definitions.items():
        store.register(get_types_from_msg(text, msgtype))
    return store


@pytest.fixture(scope="module")
def sim():
    """A 2 km synthetic drive (seed 3): wheel speeds [rev/s] at 100 Hz on a jittered clock."""
    return simulate_streams(2.0, 3)


def _write_drive(
    recording: Recording,
    path: Path,
    storage: str,
    extra: list,
    definitions: dict[str, str],
    joint_states: bool = False,
) -> Path:
    """``recording``'s pose (Odometry) and IMU as write_bag writes them, plus the ``extra``
    topics ``(topic, type, times [ns], k-th message)`` built with the typestore."""
    ros1 = storage == "ros1"
    store = _typestore(ros1, definitions)
    messages = _Messages(store, ros1)
    topics = [
        ("/odom", *messages.pose(recording, as_fix=False)),
        ("/imu/data", *messages.imu(recording, as_fix=False)),
    ]
    if joint_states:
        topics.append(("/joint_states", *messages.wheels(recording, "rl_joint", "rr_joint")))
    topics.extend(extra(store, messages) if callable(extra) else extra)
    _write(path, storage, store, topics)
    return path


def _vendor_topic(recording: Recording, msgtype: str):
    """The rear wheels' speeds [rev/s] as the vendor's rad/s, the front ones made up."""

    def build(store, messages):
        wheels = recording.wheels
        ns, sec, nanosec = _stamps(wheels.t)
        left, right = 2 * np.pi * wheels.left, 2 * np.pi * wheels.right
        names = {
            DATASPEED: ("front_left", "front_right", "rear_left", "rear_right"),
            PACMOD: tuple(
                f"{w}_wheel_speed" for w in ("front_left", "front_right", "rear_left", "rear_right")
            ),
        }[msgtype]

        def message(k: int):
            values = (1.01 * left[k], 0.99 * right[k], left[k], right[k])
            return store.types[msgtype](
                header=messages._header(sec[k], nanosec[k], "base_link", k),
                **{name: float(v) for name, v in zip(names, values, strict=True)},
            )

        return [(VENDOR_TOPIC[msgtype], msgtype, ns, message)]

    return build


@pytest.fixture(scope="module")
def written(sim, tmp_path_factory):
    """For each storage: the JointState bag of the drive, and one bag per vendor message."""
    directory = tmp_path_factory.mktemp("vendor")
    found = {}
    for storage, name in STORAGES.items():
        found[storage, "joints"] = write_bag(
            sim.recording, directory / f"joints_{name}", storage, pose_message="odometry"
        )
        for msgtype in (DATASPEED, PACMOD):
            vendor = msgtype.split("_", 1)[0]
            path = directory / f"{vendor}_{name}"
            found[storage, msgtype] = _write_drive(
                sim.recording, path, storage, _vendor_topic(sim.recording, msgtype), DEFINITIONS
            )
    return found


@pytest.mark.parametrize("storage", list(STORAGES))
@pytest.mark.parametrize("msgtype", [DATASPEED, PACMOD])
def test_a_vendor_wheel_speed_message_is_read_without_flags(written, storage, msgtype):
    joints = read_bag(written[storage, "joints"]).wheels
    read = read_bag(written[storage, msgtype])
    wheels = read.wheels
    assert not wheels.cumulative and wheels.source.endswith(VENDOR_TOPIC[msgtype])
    np.testing.assert_allclose(wheels.t, joints.t, rtol=0, atol=1e-9)
    # Dataspeed's speeds are float32: equal to its precision; PACMod's float64: to rounding.
    rtol = 1e-7 if msgtype == DATASPEED else 1e-14
    np.testing.assert_allclose(wheels.left, joints.left, rtol=rtol, atol=1e-12)
    np.testing.assert_allclose(wheels.right, joints.right, rtol=rtol, atol=1e-12)
    if msgtype == DATASPEED:
        assert np.abs(wheels.left / joints.left - 1).max() > 1e-9  # float32 was really read
    note = f"wheel topic {VENDOR_TOPIC[msgtype]} ({msgtype.rsplit('/', 1)[1]}: "
    assert any(n.startswith(note) and "picked automatically" in n for n in read.notes), read.notes
    field = wheels.provenance.fields["rear_left"]
    assert "rad/s" in field.unit and field.declares("kind") == "angular_speed"


@pytest.mark.parametrize(("storage", "msgtype"), [("ros1", DATASPEED), ("ros2", PACMOD)])
def test_a_vendor_bag_calibrates_within_3_sigma_as_its_joint_state_twin(
    written, sim, storage, msgtype, tmp_path, capsys
):
    out = tmp_path / "drive.csv"
    assert main(["import", str(written[storage, msgtype]), "--out", str(out)]) == 0
    assert "picked automatically" in capsys.readouterr().out
    theta = sim.drive.theta_true
    runs = {}
    for name in (msgtype, "joints"):
        log = import_recording(written[storage, name]).log
        runs[name] = run = run_calibration(log, method="whole", workers=1)
        sigma = np.sqrt(np.diag(run.covariance))
        error = evaluate(run, Truth(theta)).theta_error
        assert np.all(np.abs(error) < 3 * sigma), error / sigma
    difference = runs[msgtype].theta - runs["joints"].theta
    assert np.all(np.abs(difference) < 1e-3 * np.sqrt(np.diag(runs["joints"].covariance)))


def test_a_vendor_message_is_preferred_to_a_joint_state_and_two_ask_for_the_flag(sim, tmp_path):
    recording = sim.recording
    both = _write_drive(
        recording,
        tmp_path / "both",
        "ros2",
        _vendor_topic(recording, PACMOD),
        DEFINITIONS,
        joint_states=True,
    )
    read = read_bag(both)
    assert read.wheels.source.endswith(VENDOR_TOPIC[PACMOD])
    assert any("rather than the JointState /joint_states" in n for n in read.notes), read.notes
    # --wheel-topic picks the JointState, its joints named as before.
    joints = read_bag(
        both, BagRequest(wheel_topic="/joint_states", rear_left="rl_joint", rear_right="rr_joint")
    )
    assert joints.wheels.source.endswith("/joint_states")
    np.testing.assert_allclose(joints.wheels.left, read.wheels.left, rtol=1e-14)

    def two(store, messages):
        return [
            *_vendor_topic(recording, PACMOD)(store, messages),
            *_vendor_topic(recording, DATASPEED)(store, messages),
        ]

    path = _write_drive(recording, tmp_path / "two", "ros2", two, DEFINITIONS)
    with pytest.raises(StreamError) as error:
        read_bag(path)
    _one_line(
        error,
        "2 wheel-speed topics",
        VENDOR_TOPIC[PACMOD],
        VENDOR_TOPIC[DATASPEED],
        "--wheel-topic",
    )
    read = read_bag(path, BagRequest(wheel_topic=VENDOR_TOPIC[DATASPEED]))
    assert read.wheels.source.endswith(VENDOR_TOPIC[DATASPEED])


# --- any field: nested, indexed, headerless -----------------------------------------------------


CIRCUMFERENCE = 2.0  # [m] the made-up ECU's


def _custom_topics(recording: Recording, short_from: int | None = None):
    """``/car/wheels`` (``Wheels``: the rear wheels at ``wheels[2]``, ``wheels[3]`` in km/h with
    the ECU's circumference, and in ``rpm[2]``, ``rpm[3]``) and ``/car/dynamics`` (no header:
    yaw rate in deg/s, lateral acceleration, compass azimuth in degrees). From message
    ``short_from`` on, ``wheels`` has only two elements."""

    def build(store, messages):
        types = store.types
        wheels = recording.wheels
        ns, sec, nanosec = _stamps(wheels.t)
        kmh = 3.6 * CIRCUMFERENCE * np.column_stack([wheels.left, wheels.right])
        rpm = (60.0 * np.column_stack([wheels.left, wheels.right])).astype(np.float32)

        def wheel_message(k: int):
            count = 2 if short_from is not None and k >= short_from else 4
            entries = [
                types["my_car_msgs/msg/Wheel"](speed_kmh=float(v), valid=1)
                for v in (0.0, 0.0, kmh[k, 0], kmh[k, 1])[:count]
            ]
            return types["my_car_msgs/msg/Wheels"](
                header=messages._header(sec[k], nanosec[k], "base_link", k),
                label="rear axle",
                wheels=entries,
                rpm=np.array([0.0, 0.0, rpm[k, 0], rpm[k, 1]], dtype=np.float32),
            )

        imu, pose = recording.imu, recording.pose
        assert imu is not None and pose.heading is not None
        ins, _, _ = _stamps(imu.t)
        azimuth = np.mod(90.0 - np.degrees(np.interp(imu.t, pose.t, np.unwrap(pose.heading))), 360)

        def dynamics(k: int):
            return types["my_car_msgs/msg/Dynamics"](
                yaw_rate_dps=float(np.degrees(imu.yaw_rate[k])),
                lateral_acceleration=float(imu.lateral_acceleration[k]),
                azimuth_deg=float(azimuth[k]),
            )

        return [
            ("/car/wheels", "my_car_msgs/msg/Wheels", ns, wheel_message),
            ("/car/dynamics", "my_car_msgs/msg/Dynamics", ins, dynamics),
        ]

    return build


@pytest.fixture(scope="module")
def custom(sim, tmp_path_factory):
    """The drive with the custom messages, as a ROS 1 and a ROS 2 bag."""
    directory = tmp_path_factory.mktemp("custom")
    return {
        storage: _write_drive(
            sim.recording, directory / name, storage, _custom_topics(sim.recording), CUSTOM
        )
        for storage, name in STORAGES.items()
    }


@pytest.mark.parametrize("storage", list(STORAGES))
def test_wheels_from_a_nested_indexed_field_in_km_h_and_from_an_rpm_array(custom, written, storage):
    joints = read_bag(written[storage, "joints"]).wheels
    read = read_bag(
        custom[storage],
        BagRequest(
            rear_left="/car/wheels:wheels[2].speed_kmh",
            rear_right="wheels[3].speed_kmh",
            wheel_kind="speed",
            speed_unit="km/h",
            circumference=CIRCUMFERENCE,
        ),
    )
    np.testing.assert_allclose(read.wheels.t, joints.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(read.wheels.left, joints.left, rtol=1e-13)
    np.testing.assert_allclose(read.wheels.right, joints.right, rtol=1e-13)
    field = read.wheels.provenance.fields["rear_right"]
    assert (field.name, field.key) == ("wheels[3].speed_kmh", "--rear-right")
    assert field.declares("speed_unit") == "km/h" and "--circumference 2 m" in field.unit
    rpm = read_bag(
        custom[storage],
        BagRequest(
            wheel_topic="/car/wheels", rear_left="rpm[2]", rear_right="rpm[3]", wheel_kind="rpm"
        ),
    )
    np.testing.assert_allclose(rpm.wheels.left, joints.left, rtol=1e-7)


@pytest.mark.parametrize("storage", list(STORAGES))
def test_imu_signals_and_the_heading_from_fields_of_a_message_without_a_header(
    custom, sim, storage
):
    recording = sim.recording
    read = read_bag(
        custom[storage],
        BagRequest(
            rear_left="/car/wheels:rpm[2]",
            rear_right="/car/wheels:rpm[3]",
            wheel_kind="rpm",
            yaw_rate="/car/dynamics:yaw_rate_dps",
            yaw_rate_unit="deg/s",
            lateral_acceleration="/car/dynamics:lateral_acceleration",
            heading="/car/dynamics:azimuth_deg",
            heading_unit="deg",
            heading_convention="compass",
        ),
    )
    imu = read.imu
    # No header: the times are the bag's receive times (the sample times, to the ns, and to
    # a double's resolution of a Unix time: 0.24 µs).
    np.testing.assert_allclose(imu.t, recording.imu.t, rtol=0, atol=5e-7)
    np.testing.assert_allclose(imu.yaw_rate, recording.imu.yaw_rate, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(imu.lateral_acceleration, recording.imu.lateral_acceleration)
    assert any("no header, used the bag's receive times" in n for n in read.notes)
    # The compass azimuth [deg] back as the ENU heading [rad] at the pose's times.
    error = np.angle(np.exp(1j * (read.pose.heading - recording.pose.heading)))
    # (interpolated twice: the fixes' noisy headings at 100 Hz, those at the fixes' times)
    assert np.abs(error).max() < np.radians(0.3) and np.abs(error).mean() < np.radians(0.05)
    assert read.pose.provenance.fields["heading"].key == "--heading"


def test_fields_decoded_from_raw_bytes_equal_rosbags_message_by_message(
    custom, written, monkeypatch
):
    args = {
        "rear_left": "/car/wheels:wheels[2].speed_kmh",
        "rear_right": "/car/wheels:rpm[3]",  # another field, same topic: both read
        "wheel_kind": "angle",
        "yaw_rate": "/car/dynamics:yaw_rate_dps",
    }
    decoded = []

    def spy(*args, **kwargs):
        result = decode_fields(*args, **kwargs)
        decoded.append(result is not None)
        return result

    monkeypatch.setattr(bag_reader, "decode_fields", spy)
    for path in [*custom.values(), *(written[s, DATASPEED] for s in STORAGES)]:
        decoded.clear()
        fast = read_bag(path, BagRequest(**args)) if path in custom.values() else read_bag(path)
        assert decoded and all(decoded)  # every chunk of every field topic, vectorized
        monkeypatch.setattr(bag_reader, "FAST_DECODING", False)
        slow = read_bag(path, BagRequest(**args)) if path in custom.values() else read_bag(path)
        monkeypatch.setattr(bag_reader, "FAST_DECODING", True)
        for a, b in ((fast.wheels.left, slow.wheels.left), (fast.wheels.t, slow.wheels.t)):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(fast.imu.yaw_rate, slow.imu.yaw_rate)
        np.testing.assert_array_equal(fast.wheels.right, slow.wheels.right)


def test_the_layout_is_found_through_the_definition_and_refused_when_it_changes(sim, tmp_path):
    from rosbags.highlevel import AnyReader

    path = _write_drive(
        sim.recording, tmp_path / "short", "ros2", _custom_topics(sim.recording, 50), CUSTOM
    )
    with AnyReader([path]) as reader:
        store = reader.typestore
        (connection,) = [c for c in reader.connections if c.topic == "/car/wheels"]
        raws = [raw for _, _, raw in reader.messages(connections=[connection])]
    msgtype = "my_car_msgs/msg/Wheels"
    paths = [("wheels", 2, "speed_kmh"), ("rpm", 3)]
    stamp, values = decode_fields(raws[:50], msgtype, store.fielddefs, paths, False, True)
    expected = [store.deserialize_cdr(raw, msgtype) for raw in raws[:50]]
    np.testing.assert_array_equal(values[:, 0], [m.wheels[2].speed_kmh for m in expected])
    np.testing.assert_array_equal(values[:, 1], [m.rpm[3] for m in expected])
    np.testing.assert_array_equal(stamp[:, 1], [m.header.stamp.nanosec for m in expected])
    assert decode_fields(raws[40:60], msgtype, store.fielddefs, paths, False, True) is None
    # Read message by message, the messages without wheels[2] are skipped and said so.
    read = read_bag(
        path,
        BagRequest(
            rear_left="/car/wheels:wheels[2].speed_kmh",
            rear_right="wheels[3].speed_kmh",
            wheel_kind="speed",
            speed_unit="km/h",
            circumference=CIRCUMFERENCE,
        ),
    )
    assert len(read.wheels.t) == 50
    assert any("skipped" in n and "without wheels[2].speed_kmh" in n for n in read.notes)


# --- what goes wrong: one line, exit 2 ----------------------------------------------------------


def _one_line(error: pytest.ExceptionInfo, *words: str) -> None:
    message = str(error.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, (word, message)


FIELDS = ["--rear-left", "/car/wheels:wheels[2].speed_kmh", "--rear-right", "wheels[3].speed_kmh"]
SPEED = ["--wheel-kind", "speed", "--speed-unit", "km/h", "--circumference", "2"]


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (  # an unknown topic: the bag's topics listed
            ["--rear-left", "/car/wheelz:wheels[2].speed_kmh", "--rear-right", "x", *SPEED],
            [
                "--rear-left /car/wheelz:wheels[2].speed_kmh",
                "no topic /car/wheelz",
                "/car/wheels (my_car_msgs/msg/Wheels)",
                "/odom (nav_msgs/msg/Odometry)",
            ],
        ),
        (  # a misspelt field: the fields at that level listed
            [
                "--rear-left",
                "/car/wheels:wheels[2].speed",
                "--rear-right",
                "wheels[3].speed_kmh",
                *SPEED,
            ],
            [
                "--rear-left /car/wheels:wheels[2].speed",
                "wheels[2] (my_car_msgs/msg/Wheel) has no field 'speed'",
                "its fields: speed_kmh (float64), valid (uint8)",
            ],
        ),
        (
            [
                "--rear-left",
                "/car/wheels:wheel[2].speed_kmh",
                "--rear-right",
                "wheels[3].speed_kmh",
                *SPEED,
            ],
            [
                "my_car_msgs/msg/Wheels has no field 'wheel'",
                "label (string)",
                "wheels (my_car_msgs/msg/Wheel[])",
                "rpm (float32[4])",
            ],
        ),
        (  # not a number: a string, a message, an array
            ["--rear-left", "/car/wheels:label", "--rear-right", "rpm[3]", *SPEED],
            [
                "--rear-left /car/wheels:label",
                "label (string) is not a number",
                "numeric fields of my_car_msgs/msg/Wheels",
                "wheels[i].speed_kmh",
                "rpm[i]",
            ],
        ),
        (
            ["--rear-left", "/car/wheels:header.stamp", "--rear-right", "rpm[3]", *SPEED],
            [
                "header.stamp (builtin_interfaces/msg/Time) is not a number",
                "its fields: sec (int32)",
            ],
        ),
        (
            ["--rear-left", "/car/wheels:rpm", "--rear-right", "rpm[3]", *SPEED],
            ["rpm (float32[4]) is not a number; index it: rpm[0]"],
        ),
        (
            ["--rear-left", "/car/wheels:rpm[4]", "--rear-right", "rpm[3]", *SPEED],
            ["rpm (float32[4]) has 4 elements; index 0 to 3, not 4"],
        ),
        (
            ["--rear-left", "/car/wheels:wheels[x]", "--rear-right", "rpm[3]", *SPEED],
            ["'wheels[x]' is not a field path"],
        ),
        (  # what the fields hold, and its units
            FIELDS,
            ["--rear-left /car/wheels:wheels[2].speed_kmh: pass --wheel-kind", "speed [with "],
        ),
        (
            [*FIELDS, "--wheel-kind", "speed"],
            ["--wheel-kind speed needs --circumference"],
        ),
        (
            [*FIELDS, *SPEED[:4]],
            ["--wheel-kind speed needs --circumference"],
        ),
        (
            ["--rear-left", "/car/wheels:rpm[2]"],
            ["--rear-left /car/wheels:rpm[2] names a field; pass --rear-right too"],
        ),
        (
            [
                "--rear-left",
                "/car/wheels:rpm[2]",
                "--rear-right",
                "/car/dynamics:yaw_rate_dps",
                "--wheel-kind",
                "rpm",
            ],
            ["on different topics"],
        ),
        (
            ["--wheel-topic", "/car/wheels"],
            [
                "wheel topic /car/wheels is my_car_msgs/msg/Wheels, neither JointState nor a known "
                "wheel-speed message",
                "--rear-left FIELD",
                "its fields: header (std_msgs/msg/Header)",
            ],
        ),
        (
            ["--yaw-rate", "yaw_rate_dps", *FIELDS, *SPEED],
            ["--yaw-rate yaw_rate_dps: name its topic too (--yaw-rate TOPIC:yaw_rate_dps)"],
        ),
        (
            ["--heading", "/car/dynamics:azimuth", *FIELDS, *SPEED],
            ["--heading /car/dynamics:azimuth", "has no field 'azimuth'", "azimuth_deg (float64)"],
        ),
    ],
)
def test_bad_field_paths_get_one_line_naming_what_exists(custom, tmp_path, capsys, flags, expected):
    out = tmp_path / "drive.csv"
    assert main(["import", str(custom["ros2"]), "--out", str(out), *flags]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for word in expected:
        assert word in err, (word, err)
    assert not out.exists()


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (
            [*FIELDS, "--wheel-kind", "speed", "--speed-unit", "m/s", "--circumference", "2"],
            [
                "/car/wheels: fields 'wheels[2].speed_kmh', 'wheels[3].speed_kmh' (--rear-left, "
                "--rear-right; --wheel-kind speed, --speed-unit m/s, --circumference 2 m)",
                'the speeds are apparently in km/h: pass --speed-unit km/h (now "m/s")',
            ],
        ),
        (
            [*FIELDS, *SPEED[:4], "--circumference", "4"],
            ["check --circumference (2.0", "--wheel-kind, --speed-unit"],
        ),
        (
            [*FIELDS, *SPEED, "--yaw-rate", "/car/dynamics:yaw_rate_dps"],
            [
                "/car/dynamics: field 'yaw_rate_dps' (--yaw-rate, --yaw-rate-unit rad/s by "
                "default)",
                "it is apparently in deg/s: pass --yaw-rate-unit deg/s",
            ],
        ),
        (
            [*FIELDS, *SPEED, "--heading", "/car/dynamics:azimuth_deg"],
            [
                "field '/car/dynamics:azimuth_deg' (--heading, --heading-unit rad",
                "apparently degrees; check --heading-unit (deg | rad)",
            ],
        ),
        (
            [*FIELDS, *SPEED, "--heading", "/car/dynamics:azimuth_deg", "--heading-unit", "deg"],
            ["the heading turns opposite", "check --heading-convention (compass"],
        ),
    ],
)
def test_a_wrong_unit_of_a_field_names_the_field_and_the_flag_to_change(
    custom, tmp_path, capsys, flags, expected
):
    out = tmp_path / "drive.csv"
    assert main(["import", str(custom["ros1"]), "--out", str(out), *flags]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    for word in expected:
        assert word in err, (word, err)
    assert "[wheels]" not in err and "[gnss]" not in err and "[imu]" not in err


def test_a_joint_state_keeps_its_kinds_and_the_unit_flags_need_fields(written):
    path = written["ros2", "joints"]
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(wheel_kind="speed"))
    _one_line(error, "--wheel-kind speed", "a JointState gives angle (position) or angular_speed")
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(circumference=2.0))
    _one_line(error, "--circumference applies to wheels read from fields")
    with pytest.raises(StreamError) as error:
        read_bag(path, BagRequest(wheel_kind="knots"))
    _one_line(error, "--wheel-kind 'knots' is unknown", "speed, angular_speed, rpm, ticks, angle")


def test_a_ros2_bag_without_definitions_reads_vendor_messages_by_their_published_one(
    written, custom, tmp_path
):
    # A ROS 2 bag recorded before Iron stores no message definitions (simulated: deleted).
    import shutil
    import sqlite3

    def without_definitions(path: Path, name: str) -> Path:
        copy = tmp_path / name
        shutil.copytree(path, copy)
        (db,) = copy.glob("*.db3")
        with sqlite3.connect(db) as connection:
            connection.execute("DELETE FROM message_definitions")
        return copy

    bare = without_definitions(written["ros2", PACMOD], "pacmod")
    read, full = read_bag(bare), read_bag(written["ros2", PACMOD])
    np.testing.assert_array_equal(read.wheels.left, full.wheels.left)
    assert any(f"no definition of {PACMOD}; read with the vendor's" in n for n in read.notes)
    with pytest.raises(StreamError) as error:
        read_bag(
            without_definitions(custom["ros2"], "custom"),
            BagRequest(rear_left="/car/wheels:rpm[2]", rear_right="rpm[3]", wheel_kind="rpm"),
        )
    _one_line(error, "--rear-left /car/wheels:rpm[2]", "no definition of my_car_msgs/msg/Wheels")


def test_an_autoware_velocity_report_is_no_wheel_stream_and_says_so(sim, tmp_path):
    msgtype = "autoware_auto_vehicle_msgs/msg/VelocityReport"
    definition = {
        msgtype: "std_msgs/Header header\nfloat32 longitudinal_velocity\n"
        "float32 lateral_velocity\nfloat32 heading_rate\n"
    }

    def velocity(store, messages):
        wheels = sim.recording.wheels
        ns, sec, nanosec = _stamps(wheels.t)

        def message(k: int):
            return store.types[msgtype](
                header=messages._header(sec[k], nanosec[k], "base_link", k),
                longitudinal_velocity=float(wheels.left[k] + wheels.right[k]),
                lateral_velocity=0.0,
                heading_rate=0.0,
            )

        return [("/vehicle/status/velocity_status", msgtype, ns, message)]

    path = _write_drive(sim.recording, tmp_path / "autoware", "ros2", velocity, definition)
    for flags in ({}, {"wheel_topic": "/vehicle/status/velocity_status"}):
        with pytest.raises(StreamError) as error:
            read_bag(path, BagRequest(**flags))
        _one_line(
            error, "/vehicle/status/velocity_status (VelocityReport)", "longitudinal speed only"
        )
