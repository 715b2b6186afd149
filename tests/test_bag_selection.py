"""Which topics, joints and fields of a bag are read: plain Python data, no rosbags.

The bag is a :class:`BagContents` written by hand (topics, counts, message definitions in
rosbags' ``fielddefs`` form); rosbags is made unimportable to show that choosing what to read
never needs it.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from graphcal.recording.bag.fields import FieldRef, field_ref, parse_steps, resolve_field
from graphcal.recording.bag.layout import ARRAY, BASE, NAME, SEQUENCE
from graphcal.recording.bag.request import BagRequest
from graphcal.recording.bag.selection import select_streams
from graphcal.recording.bag.topics import (
    IMU,
    JOINT_STATE,
    NAVSATFIX,
    ODOMETRY,
    BagContents,
    pick_joints,
    pick_topic,
    resolve_joints,
)
from graphcal.recording.streams import StreamError

DATASPEED = "dbw_mkz_msgs/msg/WheelSpeedReport"
VELOCITY = "autoware_auto_vehicle_msgs/msg/VelocityReport"
WHEELS = "car_msgs/msg/Wheels"
HEADER = "std_msgs/msg/Header"


def _number(name: str = "float32") -> tuple:
    return (BASE, (name, 0))


FIELDDEFS = {
    HEADER: (
        [],
        [("stamp", (NAME, "builtin_interfaces/msg/Time")), ("frame_id", _number("string"))],
    ),
    "builtin_interfaces/msg/Time": (
        [],
        [("sec", _number("int32")), ("nanosec", _number("uint32"))],
    ),
    DATASPEED: (
        [],
        [("header", (NAME, HEADER))]
        + [(f"{end}_{side}", _number()) for end in ("front", "rear") for side in ("left", "right")],
    ),
    "car_msgs/msg/Wheel": ([], [("speed_kmh", _number("float64")), ("label", _number("string"))]),
    WHEELS: (
        [],
        [
            ("header", (NAME, HEADER)),
            ("wheels", (ARRAY, ((NAME, "car_msgs/msg/Wheel"), 4))),
            ("rpm", (SEQUENCE, (_number("float64"), 0))),
        ],
    ),
}
TOPICS = {
    "/fix": NAVSATFIX,
    "/joints": JOINT_STATE,
    "/imu": IMU,
    "/car/wheels": WHEELS,
    "/car/trailer": WHEELS,
}


@pytest.fixture(autouse=True)
def no_rosbags(monkeypatch):
    """Every ``import rosbags...`` fails, as without the ``ros`` extra."""
    for name in [n for n in sys.modules if n == "rosbags" or n.startswith("rosbags.")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "rosbags", None)


def _bag(topics: dict[str, str] | None = None, counts: dict[str, int] | None = None):
    return BagContents(
        "drive.bag", dict(TOPICS if topics is None else topics), counts or {}, FIELDDEFS
    )


def _error(call, *args, **kwargs) -> str:
    with pytest.raises(StreamError) as error:
        call(*args, **kwargs)
    message = str(error.value)
    assert "\n" not in message
    return message


def test_choosing_what_to_read_imports_no_rosbags():
    code = (
        "import sys; sys.modules['rosbags'] = None\n"
        "import graphcal.recording.bag.selection, graphcal.recording.bag.topics\n"
        "import graphcal.recording.bag.fields, graphcal.recording.bag.request\n"
        "import graphcal.recording.bag.vendors, graphcal.recording.bag.rows\n"
        "import graphcal.recording.bag.streams\n"
        "print(sorted(n for n in sys.modules if n.startswith('rosbags.')))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_the_only_topic_of_a_type_is_picked_and_said():
    topic, note = pick_topic(_bag(), None, (NAVSATFIX, ODOMETRY), "pose", "--pose-topic", True)
    assert topic == "/fix"
    assert note == "pose topic /fix (NavSatFix) picked automatically"
    assert pick_topic(_bag(), "/fix", (NAVSATFIX,), "pose", "--pose-topic", True) == ("/fix", None)
    assert pick_topic(_bag({"/fix": NAVSATFIX}), None, (IMU,), "IMU", "--imu-topic", False) == (
        None,
        None,
    )


def test_a_topic_absent_ambiguous_or_of_another_type_is_one_line_naming_the_flag():
    two = _bag({"/fix": NAVSATFIX, "/odom": ODOMETRY})
    message = _error(pick_topic, two, None, (NAVSATFIX, ODOMETRY), "pose", "--pose-topic", True)
    assert message == (
        "drive.bag: 2 pose topics (/fix (NavSatFix), /odom (Odometry)); pass --pose-topic with "
        "the one to use"
    )
    message = _error(pick_topic, _bag(), "/gps", (NAVSATFIX,), "pose", "--pose-topic", True)
    assert message.startswith("drive.bag: pose topic /gps is not in the bag; pass --pose-topic")
    assert "/fix (sensor_msgs/msg/NavSatFix)" in message  # the bag's topics are listed
    message = _error(pick_topic, _bag(), "/imu", (NAVSATFIX,), "pose", "--pose-topic", True)
    assert message.startswith("drive.bag: pose topic /imu is sensor_msgs/msg/Imu, not NavSatFix")
    message = _error(pick_topic, _bag({}), None, (JOINT_STATE,), "wheel", "--wheel-topic", True)
    assert message == (
        "drive.bag: no wheel topic (JointState) in the bag; the bag has no topics; record one, "
        "or pass --wheel-topic if it has another type"
    )


def test_the_rear_wheel_joints_are_picked_from_their_names():
    names = ["front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel"]
    assert pick_joints(names) == ("rear_left_wheel", "rear_right_wheel")
    notes: list[str] = []
    joints = resolve_joints("drive.bag:/joints", None, None, lambda: sorted(names), notes)
    assert joints == ("rear_left_wheel", "rear_right_wheel")
    assert notes == [
        "drive.bag:/joints: rear wheel joints rear_left_wheel, rear_right_wheel picked "
        "automatically"
    ]


def test_named_joints_are_taken_without_looking_at_the_messages():
    def unread() -> list[str]:
        raise AssertionError("the messages were scanned")

    assert resolve_joints("b:/j", "wheel_l", "wheel_r", unread, []) == ("wheel_l", "wheel_r")
    message = _error(resolve_joints, "b:/j", "wheel_l", "wheel_l", unread, [])
    assert message == (
        "b:/j: rear-left and rear-right joint are both 'wheel_l'; pass --rear-left/--rear-right "
        "with two different joints"
    )


def test_joints_that_cannot_be_told_or_half_named_are_one_line_listing_the_names():
    names = ["fl_left", "fr_right", "ml_left", "mr_right"]
    message = _error(resolve_joints, "b:/j", None, None, lambda: names, [])
    assert message == (
        "b:/j: cannot tell the rear wheel joints from the joint names (fl_left, fr_right, "
        "ml_left, mr_right); pass --rear-left/--rear-right"
    )
    message = _error(resolve_joints, "b:/j", "ml_left", None, lambda: names, [])
    assert message == (
        "b:/j: only one rear wheel joint given (ml_left); pass --rear-right too (joint names: "
        "fl_left, fr_right, ml_left, mr_right)"
    )


def test_field_paths_parse_into_names_and_indices():
    assert parse_steps("wheels[2].speed_kmh") == ("wheels", 2, "speed_kmh")
    assert parse_steps("rpm[3]") == ("rpm", 3)
    for bad in ("wheels[x]", "2wheels", "wheels..speed", ""):
        with pytest.raises(ValueError):
            parse_steps(bad)


def test_a_field_is_checked_against_the_bags_definition():
    bag = _bag()
    ref = field_ref(bag, "--rear-left", "/car/wheels:wheels[2].speed_kmh")
    assert ref == FieldRef(
        "/car/wheels", "wheels[2].speed_kmh", ("wheels", 2, "speed_kmh"), "--rear-left"
    )
    assert resolve_field(bag, ref) == "float64"
    assert resolve_field(bag, FieldRef("/car/wheels", "rpm[7]", ("rpm", 7))) == "float64"


@pytest.mark.parametrize(
    ("text", "says"),
    [
        (
            "/car/wheels:wheel[2].speed_kmh",
            "car_msgs/msg/Wheels has no field 'wheel'; its fields: header (std_msgs/msg/Header), "
            "wheels (car_msgs/msg/Wheel[4]), rpm (float64[])",
        ),
        (
            "/car/wheels:wheels[4].speed_kmh",
            "wheels (car_msgs/msg/Wheel[4]) has 4 elements; index 0 to 3, not 4",
        ),
        ("/car/wheels:wheels.speed_kmh", "wheels (car_msgs/msg/Wheel[4]) has no fields; index it"),
        ("/car/wheels:wheels[0].label", "wheels[0].label (string) is not a number; the numeric"),
        ("/car/wheels:wheels[0]", "wheels[0] (car_msgs/msg/Wheel) is not a number; its fields"),
        (
            "/car/wheel:speed",
            "no topic /car/wheel in the bag; topics: /car/trailer (car_msgs/msg/Wheels), "
            "/car/wheels",
        ),
        ("/car/wheels:wheels[", "'wheels[' is not a field path; write TOPIC:FIELD"),
    ],
)
def test_a_wrong_field_says_what_exists(text, says):
    message = _error(field_ref, _bag(), "--rear-left", text)
    assert message.startswith(f"drive.bag: --rear-left {text}: ")
    assert says in message


def test_not_a_number_lists_the_numeric_fields():
    message = _error(field_ref, _bag(), "--yaw-rate", "/car/wheels:header.frame_id")
    assert message.endswith(
        "the numeric fields of car_msgs/msg/Wheels: header.stamp.sec, header.stamp.nanosec, "
        "wheels[i].speed_kmh, rpm[i]"
    )


def test_a_vendor_wheel_speed_message_is_preferred_to_a_joint_state():
    notes: list[str] = []
    bag = _bag({**TOPICS, "/vehicle/wheel_speed_report": DATASPEED})
    selection = select_streams(bag, BagRequest(), notes)
    assert selection.pose == "/fix" and selection.imu == "/imu"
    assert selection.wheels is not None and selection.joint_topic is None
    assert (selection.wheels.left.path, selection.wheels.right.path) == ("rear_left", "rear_right")
    assert selection.wheels.kind == "angular_speed"
    assert notes == [
        "pose topic /fix (NavSatFix) picked automatically",
        "IMU topic /imu (Imu) picked automatically",
        "wheel topic /vehicle/wheel_speed_report (WheelSpeedReport: Dataspeed wheel speeds, "
        "rad/s) picked automatically, rather than the JointState /joints (pass --wheel-topic to "
        "use it)",
    ]


def test_without_a_vendor_message_the_joint_state_is_read():
    notes: list[str] = []
    selection = select_streams(_bag(), BagRequest(), notes)
    assert selection.wheels is None and selection.joint_topic == "/joints"
    assert selection.streams == [
        ("/fix", "pose", "--pose-topic"),
        ("/joints", "wheel", "--wheel-topic"),
        ("/imu", "IMU", "--imu-topic"),
    ]
    assert "wheel topic /joints (JointState) picked automatically" in notes


def test_named_fields_are_the_wheels_and_the_imu():
    request = BagRequest(
        rear_left="/car/wheels:wheels[2].speed_kmh",
        rear_right="wheels[3].speed_kmh",  # a bare field: on the other one's topic
        wheel_kind="speed",
        circumference=2.0,
        speed_unit="km/h",
        yaw_rate="rpm[0]",
        imu_topic="/car/wheels",
    )
    selection = select_streams(_bag(), request, [])
    assert selection.wheels is not None
    assert selection.wheels.right == FieldRef(
        "/car/wheels", "wheels[3].speed_kmh", ("wheels", 3, "speed_kmh"), "--rear-right"
    )
    assert [ref.written for ref in selection.imu_fields] == ["/car/wheels:rpm[0]"]
    assert selection.imu is None


@pytest.mark.parametrize(
    ("request_", "message"),
    [
        (
            BagRequest(rear_left="/car/wheels:rpm[0]"),
            "drive.bag: --rear-left /car/wheels:rpm[0] names a field; pass --rear-right too "
            "(TOPIC:FIELD, or a field of the same topic)",
        ),
        (
            BagRequest(rear_left="/car/wheels:rpm[0]", rear_right="/car/wheels:rpm[1]"),
            "drive.bag: --rear-left /car/wheels:rpm[0]: pass --wheel-kind, what the fields hold: "
            "speed [with --speed-unit and --circumference], angular_speed [rad/s], rpm, ticks "
            "[cumulative, with --ticks-per-revolution], angle [rad, cumulative]",
        ),
        (
            BagRequest(rear_left="/car/wheels:rpm[0]", rear_right="/car/trailer:rpm[1]"),
            "drive.bag: --rear-left /car/wheels:rpm[0] and --rear-right /car/trailer:rpm[1] are "
            "on different topics; name two fields of one topic",
        ),
        (
            BagRequest(rear_left="/car/wheels:rpm[0]", rear_right="/imu:angular_velocity.z"),
            "drive.bag: --rear-right /imu:angular_velocity.z: the bag carries no definition of "
            "sensor_msgs/msg/Imu (a ROS 2 bag recorded before Iron stores none), so its fields "
            "cannot be read; record with a newer ROS 2",
        ),
        (
            BagRequest(wheel_kind="rpm"),
            "drive.bag: --wheel-kind rpm: a JointState gives angle (position) or angular_speed "
            "(velocity); the other kinds apply to fields (--rear-left TOPIC:FIELD)",
        ),
        (
            BagRequest(heading="yaw"),
            "drive.bag: --heading yaw: write TOPIC:FIELD (a topic of the bag, a colon, the "
            "field); topics: ",
        ),
    ],
)
def test_options_that_do_not_go_together_are_one_line(request_, message):
    assert _error(select_streams, _bag(), request_, []).startswith(message)


def test_a_speed_only_message_is_refused_as_wheels():
    bag = _bag({"/fix": NAVSATFIX, "/vehicle/status/velocity": VELOCITY})
    assert _error(select_streams, bag, BagRequest(), []) == (
        "drive.bag: /vehicle/status/velocity (VelocityReport) has the vehicle's longitudinal "
        "speed only, not each rear wheel's that the calibration needs; record the wheel speeds "
        "(a JointState, the vehicle's wheel-speed report) and name them"
    )


def test_a_chosen_topic_without_messages_is_refused_when_the_bag_counts_them():
    counts = {"/fix": 10, "/joints": 0, "/imu": 5, "/car/wheels": 3}
    assert _error(select_streams, _bag(counts=counts), BagRequest(), []).startswith(
        "drive.bag: wheel topic /joints has no messages; pass --wheel-topic with a recorded topic"
    )
