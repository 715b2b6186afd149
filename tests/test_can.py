"""Raw CAN logs with a DBC in a streams manifest (issue 28): decoding as cantools decodes,
candump/ASC/BLF imports equal to their decoded CSVs, and bad inputs refused in one line."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pandas as pd
import pytest

cantools = pytest.importorskip("cantools")
can = pytest.importorskip("can")

from cantools.database.can import Message, Signal  # noqa: E402
from cantools.database.conversion import BaseConversion  # noqa: E402

from graphcal.cli import main  # noqa: E402
from graphcal.pipeline.end_to_end.run import run_calibration  # noqa: E402
from graphcal.recording.can.decode import decode_signals  # noqa: E402
from graphcal.recording.can.frames import EXTENDED_FLAG  # noqa: E402
from graphcal.recording.can.reader import read_frames  # noqa: E402
from graphcal.recording.importer import import_recording  # noqa: E402
from graphcal.recording.manifest_recording import read_manifest  # noqa: E402
from graphcal.simulate.can_bus import IMU_ID, WHEEL_ID, CanFrames  # noqa: E402
from graphcal.simulate.can_log import (  # noqa: E402
    CAR_DBC,
    candump_text,
    write_can_log,
    write_can_recording,
    write_candump,
)
from graphcal.simulate.streams import StreamSettings, simulate_streams, write_streams  # noqa: E402

#: Every test here reads what a calibration or a simulated recording made, at module scope
#: (the fixtures take most of a minute).
pytestmark = pytest.mark.slow

FORMATS = ("log", "asc", "blf")


@pytest.fixture(scope="module")
def synthetic():
    """A 3 km drive with the wheels at 50 Hz, as a car's ABS sends them."""
    return simulate_streams(3.0, 1, settings=StreamSettings(wheel_rate=50.0))


@pytest.fixture(scope="module")
def recording(tmp_path_factory, synthetic):
    """The drive as a CAN log in each format, with its DBC and its decoded-CSV twins."""
    return write_can_recording(synthetic, tmp_path_factory.mktemp("can"))


@pytest.fixture()
def copy(recording, tmp_path):
    """A private copy of the recording's files, to edit."""
    shutil.copytree(recording.directory, tmp_path / "rec")
    return tmp_path / "rec"


def _one_line_exit_2(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _edit(path, old: str, new: str):
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new))
    return path


# ------------------------------------------------------------------------------ decoding


def _random_signal(rng, name: str, width: int = 8) -> Signal:
    bits = 8 * width
    is_float = rng.random() < 0.15
    length = int(rng.choice([32, 64])) if is_float else int(rng.integers(1, 65))
    big = rng.random() < 0.5
    first = int(rng.integers(0, bits - length + 1))  # LSB (Intel) or MSB position (Motorola)
    start = 8 * (first // 8) + 7 - first % 8 if big else first
    scale = float(rng.choice([1.0, 0.01, 0.25, 1e-3, 2.0, 0.1]))
    offset = float(rng.choice([0.0, -67.67, 100.0, -40.0]))
    return Signal(
        name,
        start,
        length,
        "big_endian" if big else "little_endian",
        is_signed=bool(rng.random() < 0.5) and not is_float,
        conversion=BaseConversion.factory(scale=scale, offset=offset, is_float=is_float),
    )


@pytest.mark.parametrize("width", [8, 16, 64])
def test_the_vectorized_decoder_gives_cantools_values_to_the_bit(width):
    """Random signals (either byte order, 1–64 bits anywhere in the payload, signed, IEEE
    float, scaled and offset) over random payloads: every value is cantools'."""
    rng = np.random.default_rng(width)
    n = 300
    for trial in range(60):
        signal = _random_signal(rng, f"S{trial}", width)
        message = Message(0x100, "M", width, [signal], strict=False)
        data = rng.integers(0, 256, (n, width), dtype=np.uint8)
        length = np.full(n, width)
        length[:5] = width - 1  # a wrong DLC: cantools refuses these frames
        decoded = decode_signals(message, [signal.name], data, length)
        for i in range(n):
            try:
                expected = message.decode(
                    bytes(data[i, : length[i]]), decode_choices=False, allow_truncated=False
                )[signal.name]
            except cantools.database.DecodeError:
                assert decoded.failed[i], (signal, i)
                continue
            if not math.isfinite(float(expected)):
                assert decoded.failed[i]
                continue
            assert decoded.present[signal.name][i]
            got = decoded.values[signal.name][i]
            assert got == float(expected), (signal.start, signal.length, signal.byte_order)


def test_multiplexed_signals_are_present_where_their_page_is_and_bad_pages_fail():
    database = cantools.database.load_string(CAR_DBC, strict=False)
    message = database.get_message_by_name("KINEMATICS")
    rng = np.random.default_rng(5)
    data = rng.integers(0, 256, (400, 8), dtype=np.uint8)
    names = ["YAW_RATE", "ACCEL_Y", "STEER_ANGLE"]
    decoded = decode_signals(message, names, data, np.full(400, 8))
    for i in range(400):
        try:
            expected = message.decode(bytes(data[i]), decode_choices=False)
        except cantools.database.DecodeError:
            assert decoded.failed[i]
            continue
        assert not decoded.failed[i]
        for name in names:
            assert decoded.present[name][i] == (name in expected)
            if name in expected:
                assert decoded.values[name][i] == expected[name]
    assert decoded.failed.sum() == ((data[:, 0] & 3) >= 2).sum() > 0


@pytest.mark.slow
def test_the_synthetic_frames_decode_with_cantools_to_the_decoded_csv(recording):
    """The writer's quantization is the DBC's: cantools decodes the written payloads to the
    reference CSV's values (so the reference does not share the reader's bit arithmetic)."""
    database = cantools.database.load_file(str(recording.dbc), strict=False)
    frames = recording.frames
    wheels = frames.key == WHEEL_ID
    good = wheels & ~frames.corrupt
    message = database.get_message_by_frame_id(WHEEL_ID)
    decoded = [message.decode(bytes(d), decode_choices=False) for d in frames.data[good][:2000]]
    reference = recording.decoded.wheels.iloc[:2000]
    assert np.array_equal([d["WHEEL_SPEED_RL"] for d in decoded], reference["rl"])
    assert np.array_equal([d["WHEEL_SPEED_RR"] for d in decoded], reference["rr"])
    assert message.signals[0].byte_order == "big_endian" and message.signals[0].length == 15
    assert (frames.length[wheels & frames.corrupt] == 5).all()


def test_the_numpy_candump_writer_writes_python_cans_bytes(tmp_path):
    rng = np.random.default_rng(1)
    n = 500
    frames = CanFrames(
        micros=np.sort(rng.integers(0, 2_000_000_000_000_000, n)),
        key=np.where(
            rng.random(n) < 0.3,
            rng.integers(0, 1 << 29, n) | EXTENDED_FLAG,
            rng.integers(0, 0x800, n),
        ),
        data=rng.integers(0, 256, (n, 8), dtype=np.uint8),
        length=rng.integers(0, 9, n),
        corrupt=np.zeros(n, dtype=bool),
    )
    frames.data[np.arange(8)[None, :] >= frames.length[:, None]] = 0
    write_can_log(frames, tmp_path / "python_can.log")
    write_candump(frames, tmp_path / "numpy.log", chunk=77)
    assert (tmp_path / "numpy.log").read_bytes() == (tmp_path / "python_can.log").read_bytes()
    assert candump_text(frames) == (tmp_path / "python_can.log").read_bytes()


CANDUMP = (
    b"(1700000000.000100) can0 0AA#0102030405060708\n"
    b"(1700000000.000200) can1 0AA#01020304050607 T\n"
    b"(1700000000.000300) vcan0 18DAF110#DEADBEEF R\n"
    b"\n"
    b"(1700000000.000400) can0 0AA##1112233445566778899AABBCCDDEEFF00\n"
    b"(1700000000.000500) can0 0AA#R\n"
    b"(1700000000.000600) can0 0aa#a1b2c3d4e5f60718\r\n"
    b"(1700000000.000700) can0 20000080#0000000000000000\n"
    b"(1700000000.000800) can0 123#\n"
    b"(1700000000.123456789) can0 0AA#FF\n"
)


def test_the_candump_parser_reads_what_python_can_reads(tmp_path):
    """-l and -L lines, CRLF, lower-case hex, extended ids, CAN FD, remote and error frames,
    nanosecond stamps: the frames of the wanted ids are python-can's, line numbers kept; a
    line that is not a frame is counted."""
    path = tmp_path / "mixed.log"
    path.write_bytes(CANDUMP)
    wanted = {0xAA, 0x18DAF110 | EXTENDED_FLAG, 0x123}
    frames = read_frames(path, wanted)
    expected = [
        m
        for m in can.LogReader(str(path))
        if not m.is_error_frame
        and not m.is_remote_frame
        and (m.arbitration_id | (EXTENDED_FLAG if m.is_extended_id else 0)) in wanted
    ]
    assert len(frames.t) == len(expected) == 7
    for i, message in enumerate(expected):
        assert frames.t[i] == message.timestamp
        assert frames.length[i] == len(message.data)
        assert bytes(frames.data[i, : frames.length[i]]) == bytes(message.data)
    assert frames.number.tolist() == [1, 2, 3, 5, 7, 9, 10]
    assert [frames.channels[c] for c in frames.channel] == [
        "can0",
        "can1",
        "vcan0",
        "can0",
        "can0",
        "can0",
        "can0",
    ]
    assert frames.total == 8  # every frame but the error frame, of any id
    (tmp_path / "garbled.log").write_bytes(CANDUMP + b"this is not a frame\n")
    assert read_frames(tmp_path / "garbled.log", wanted).malformed == (1, 11)


# --------------------------------------------------------------------------- acceptance


def _calibrated(log):
    return run_calibration(log, method="whole", workers=1).theta


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.slow
def test_a_can_log_imports_as_its_decoded_csv(recording, fmt):
    """candump, ASC and BLF with the DBC: the drive log equals the one of the decoded CSVs
    (the same times, the DBC's values) to 1e-9 and the corrupt frames are counted in notes
    (the calibration from it: the next test)."""
    from_can = import_recording(recording.can_manifests[fmt])
    from_csv = import_recording(recording.csv_manifests[fmt])
    a, b = from_can.log.to_dataframe(), from_csv.log.to_dataframe()
    assert list(a.columns) == list(b.columns) and len(a) == len(b) > 12_000
    for column in a.columns:
        x, y = a[column].to_numpy(float), b[column].to_numpy(float)
        assert np.array_equal(np.isnan(x), np.isnan(y)), column
        assert np.nanmax(np.abs(x - y)) <= 1e-9, column
    notes = " | ".join(from_can.resampled.notes)
    assert "3 of the 16475 frames of message WHEEL_SPEEDS (0x0AA)" in notes
    assert "5 bytes where the DBC has 8" in notes
    assert "3 of the 36284 frames of message KINEMATICS (0x130)" in notes
    assert "multiplexer MUX = 3" in notes
    wheels = from_can.resampled.streams[1]
    assert wheels.source.endswith(f"drive.{fmt}") and round(wheels.rate) == 50


@pytest.mark.slow
def test_a_can_log_calibrates_as_its_decoded_csv(recording):
    """The candump log's drive log calibrates to the same theta as its decoded CSVs' (the
    three formats give the same drive log: the test above)."""
    from_can = import_recording(recording.can_manifests["log"])
    from_csv = import_recording(recording.csv_manifests["log"])
    assert np.array_equal(_calibrated(from_can.log), _calibrated(from_csv.log))


def test_the_imu_shares_the_wheels_log_and_takes_units_from_the_dbc(recording):
    """[imu] without can/dbc reads the wheels' log and DBC; the yaw rate's deg/s and the
    wheels' km/h come from the DBC's units; each log read once."""
    recording_ = read_manifest(recording.can_manifests["log"])
    imu = recording_.imu
    assert imu.source.endswith("drive.log") and len(imu.t) == len(recording.decoded.imu)
    reference = recording.decoded.imu
    assert np.array_equal(imu.yaw_rate, reference["wz"].to_numpy() * (np.pi / 180.0))
    assert np.array_equal(imu.lateral_acceleration, reference["ay"].to_numpy())
    yaw = imu.provenance.fields["yaw_rate"]
    assert yaw.name == "KINEMATICS.YAW_RATE" and yaw.declares("yaw_rate_unit") == "deg/s"
    assert "from the DBC" in yaw.unit
    rl = recording_.wheels.provenance.fields["rear_left"]
    assert rl.declares("speed_unit") == "km/h" and rl.key == "[wheels] rear_left"


def test_signals_of_different_multiplexer_pages_are_interpolated(copy):
    """Lateral acceleration on page 1 and yaw rate on page 0 of one message: the IMU's samples
    are page 0's frames, page 1's signal interpolated at their times, said in a note."""
    _edit(copy / "car.dbc", "SG_ ACCEL_Y m0 : 26|13@1-", "SG_ ACCEL_Y m1 : 40|13@1-")
    recording_ = read_manifest(copy / "can_log.toml")
    database = cantools.database.load_file(str(copy / "car.dbc"), strict=False)
    message = database.get_message_by_name("KINEMATICS")
    t1, v1 = [], []
    for m in can.LogReader(str(copy / "drive.log")):
        if m.arbitration_id == IMU_ID and (m.data[0] & 3) == 1:
            t1.append(m.timestamp)
            v1.append(message.decode(bytes(m.data), decode_choices=False)["ACCEL_Y"])
    imu = recording_.imu
    assert imu.t[0] >= t1[0] and imu.t[-1] <= t1[-1]
    assert np.array_equal(imu.lateral_acceleration, np.interp(imu.t, t1, v1))
    assert any("different frames (multiplexer pages)" in n for n in recording_.notes)


def test_tick_counters_on_can_wrap_at_the_signals_range(tmp_path):
    """16-bit tick counters that wrap during the drive are unwrapped (at 2^16, from the DBC,
    with no ticks_wrap) and import as their unwrapped CSV does."""
    sim = simulate_streams(
        2.0, 2, settings=StreamSettings(wheel_kind="ticks", wheel_rate=50.0, imu_rate=50.0)
    )
    write_streams(sim, tmp_path)
    micros = np.round(sim.wheels["t"].to_numpy() * 1e6).astype(np.int64)
    counts = {side: sim.wheels[side].to_numpy() for side in ("rl", "rr")}
    assert counts["rl"].max() > 70_000  # the counters wrap
    data = np.zeros((len(micros), 8), dtype=np.uint8)
    for k, side in enumerate(("rl", "rr")):
        value = counts[side] % 65536
        data[:, 2 * k] = value & 0xFF  # little-endian 16-bit
        data[:, 2 * k + 1] = value >> 8
    frames = CanFrames(
        micros,
        np.full(len(micros), 0xB0),
        data,
        np.full(len(micros), 8),
        np.zeros(len(micros), bool),
    )
    write_candump(frames, tmp_path / "ticks.log")
    (tmp_path / "ticks.dbc").write_text(
        'VERSION ""\n\nBS_:\n\nBU_: ABS\n\nBO_ 176 WHEEL_TICKS: 8 ABS\n'
        ' SG_ TICKS_RL : 0|16@1+ (1,0) [0|65535] "" ABS\n'
        ' SG_ TICKS_RR : 16|16@1+ (1,0) [0|65535] "" ABS\n'
    )
    pd.DataFrame({"t": micros / 1e6, "rl": counts["rl"], "rr": counts["rr"]}).to_csv(
        tmp_path / "wheels_us.csv", index=False, float_format="%.17g"
    )
    text = (tmp_path / "manifest.toml").read_text()
    csv = _edit(tmp_path / "manifest.toml", 'file = "wheels.csv"', 'file = "wheels_us.csv"')
    (tmp_path / "can.toml").write_text(
        text.replace(
            'file = "wheels.csv"\ntime = "t"\nrear_left = "rl"\nrear_right = "rr"\n',
            'can = "ticks.log"\ndbc = "ticks.dbc"\nmessage = "WHEEL_TICKS"\n'
            'rear_left = "TICKS_RL"\nrear_right = "TICKS_RR"\n',
        )
    )
    from_can, from_csv = import_recording(tmp_path / "can.toml"), import_recording(csv)
    assert from_can.log.tick_resolution == 1 / 96
    for column in ("n_rl", "n_rr", "ay"):
        assert np.array_equal(
            from_can.log.to_dataframe()[column], from_csv.log.to_dataframe()[column]
        ), column


# ---------------------------------------------------------------------------- bad inputs


def test_a_dbc_without_the_message_names_the_dbc_and_its_messages(copy, capsys):
    manifest = _edit(copy / "can_log.toml", '"WHEEL_SPEEDS"', '"WHEEL_SPEED"')
    err = _one_line_exit_2(["check", str(manifest)], capsys)
    assert "car.dbc: no message 'WHEEL_SPEED' ([wheels] message in" in err
    assert "the DBC has WHEEL_SPEEDS, KINEMATICS, ENGINE" in err


def test_a_frame_id_the_dbc_lacks_lists_the_dbcs_ids(copy, capsys):
    manifest = _edit(copy / "can_log.toml", 'message = "WHEEL_SPEEDS"', "message = 0xAB")
    err = _one_line_exit_2(["check", str(manifest)], capsys)
    assert "no message with frame id 0xAB (171)" in err and "WHEEL_SPEEDS (0xAA)" in err


def test_a_misspelt_signal_lists_the_messages_signals(copy, capsys):
    manifest = _edit(copy / "can_log.toml", '"WHEEL_SPEED_RR"', '"WHEEL_SPEED_RX"')
    err = _one_line_exit_2(["check", str(manifest)], capsys)
    assert "message WHEEL_SPEEDS has no signal 'WHEEL_SPEED_RX' ([wheels] rear_right" in err
    for name in ("WHEEL_SPEED_RR", "WHEEL_SPEED_RL", "WHEEL_SPEED_FL", "COUNTER"):
        assert name in err


def test_a_log_without_the_message_says_which_ids_it_has(copy, capsys):
    lines = (copy / "drive.log").read_text().splitlines(keepends=True)
    (copy / "drive.log").write_text("".join(x for x in lines if " 0AA#" not in x))
    err = _one_line_exit_2(["check", str(copy / "can_log.toml")], capsys)
    assert "drive.log: no frame of message WHEEL_SPEEDS (0x0AA) of" in err
    assert "0x130 KINEMATICS, 0x1C4 ENGINE" in err and "0x2E4" in err


def test_a_dbc_that_does_not_parse_gives_cantools_reason(copy, capsys):
    _edit(copy / "car.dbc", "BO_ 170 WHEEL_SPEEDS: 8 ABS", "BO_ 170 WHEEL_SPEEDS 8 ABS")
    err = _one_line_exit_2(["check", str(copy / "can_log.toml")], capsys)
    assert "car.dbc: not a DBC cantools reads (Invalid syntax at line 15" in err
    assert "[wheels] dbc" in err


@pytest.mark.slow
def test_a_bus_without_the_message_names_the_buses_it_is_on(copy, capsys):
    manifest = _edit(copy / "can_asc.toml", 'kind = "speed"', 'kind = "speed"\nbus = 2')
    err = _one_line_exit_2(["check", str(manifest)], capsys)
    assert "on bus 2 ([wheels] bus); its frames are on 1" in err
    _edit(manifest, "bus = 2", "bus = 1")  # ASC counts its buses from 1, as the file does
    assert main(["check", str(manifest)]) == 0


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ('can = "drive.log"', 'can = "missing.log"', "missing.log: no such file (named in"),
        ('dbc = "car.dbc"', 'dbc = "car.dbc"\nfile = "wheels.csv"', "[wheels] file and can"),
        ('kind = "speed"', 'kind = "speed"\ntime = "t"', "not used with a CAN log"),
        ('kind = "speed"\n', "", "[wheels] needs kind (one of speed, angular_speed, rpm"),
        ("message = 0x130\n", "", "[imu] needs message"),
        ('can = "drive.log"', 'can = "drive.txt"', "not a CAN log format python-can reads"),
        ('"ACCEL_Y"', '"ACCEL_X"', "its signals: ACCEL_Y, MUX, YAW_RATE, STEER_ANGLE"),
    ],
)
def test_bad_can_keys_get_one_line_and_nothing_is_written(copy, capsys, old, new, expected):
    (copy / "drive.txt").write_text("not a log\n")
    manifest = _edit(copy / "can_log.toml", old, new)
    out = copy / "out.csv"
    err = _one_line_exit_2(["import", str(manifest), "--out", str(out)], capsys)
    assert expected in err, err
    assert not out.exists() and not (copy / "out.json").exists()


def test_a_speed_unit_the_dbc_contradicts_is_named_in_the_users_terms(copy, capsys):
    """speed_unit = "m/s" on the DBC's km/h signals: the wheels travel 3.6x the track; the
    message names the log, the message's signals, the keys and the unit to set."""
    manifest = _edit(copy / "can_log.toml", 'kind = "speed"', 'kind = "speed"\nspeed_unit = "m/s"')
    err = _one_line_exit_2(["check", str(manifest)], capsys)
    assert "drive.log: signals 'WHEEL_SPEEDS.WHEEL_SPEED_RL', 'WHEEL_SPEEDS.WHEEL_SPEED_RR'" in err
    assert '([wheels] rear_left, rear_right; kind = "speed", speed_unit = "m/s"' in err
    assert 'set [wheels] speed_unit = "km/h"' in err


def test_a_yaw_rate_unit_against_the_dbcs_is_named_in_the_users_terms(copy, capsys):
    manifest = _edit(
        copy / "can_log.toml", "message = 0x130", 'message = 0x130\nyaw_rate_unit = "rad/s"'
    )
    err = _one_line_exit_2(["check", str(manifest)], capsys)
    assert "drive.log: signal 'KINEMATICS.YAW_RATE' ([imu] yaw_rate" in err
    assert 'set [imu] yaw_rate_unit = "deg/s"' in err


def test_a_signal_without_a_unit_needs_speed_unit(copy, capsys):
    _edit(copy / "car.dbc", '"km/h"', '""')
    err = _one_line_exit_2(["check", str(copy / "can_log.toml")], capsys)
    assert "[wheels] needs speed_unit (m/s, km/h, mph)" in err
    assert "WHEEL_SPEED_RL, WHEEL_SPEED_RR the unit ''" in err


def test_the_imu_on_the_wheels_log_shares_its_clock_offset_and_bus(copy):
    """[wheels] time_offset and bus apply to an [imu] that reads the wheels' log (the same
    clock); an [imu] time_offset of its own wins."""
    manifest = _edit(
        copy / "can_log.toml", 'kind = "speed"', 'kind = "speed"\ntime_offset = 0.25\nbus = 0'
    )
    base = read_manifest(copy / "can_log.toml")
    reference = pd.read_csv(copy / "imu_log.csv")["t"].to_numpy()
    assert np.array_equal(base.imu.t, reference + 0.25)
    assert np.array_equal(base.wheels.t, pd.read_csv(copy / "wheels_log.csv")["t"] + 0.25)
    _edit(manifest, "message = 0x130", "message = 0x130\ntime_offset = -1.0")
    assert np.array_equal(read_manifest(manifest).imu.t, reference - 1.0)


def test_one_wheel_frame_at_an_implausible_speed_names_the_candump_line(copy, capsys):
    """Issue 35: one WHEEL_SPEEDS frame with the rear-left wheel at 259 km/h (the DBC's
    range ends at 260) amid ~40 km/h: refused at the stream, naming the candump log's line
    and the signal, in the log's time, not as a heading jump in drive-log time."""
    database = cantools.database.load_string(CAR_DBC, "dbc")
    message = database.get_message_by_name("WHEEL_SPEEDS")
    log = copy / "drive.log"
    lines = log.read_text().splitlines(keepends=True)
    wheel_lines = [i for i, line in enumerate(lines) if f" {WHEEL_ID:03X}#" in line]
    i = wheel_lines[5000]
    stamp, channel, frame, *rest = lines[i].split()  # rest: python-can's R(eceived) flag
    signals = message.decode(bytes.fromhex(frame.split("#")[1]), decode_choices=False)
    signals["WHEEL_SPEED_RL"] = 259.0
    data = message.encode(signals).hex().upper()
    lines[i] = " ".join([stamp, channel, f"{frame.split('#')[0]}#{data}", *rest]) + "\n"
    log.write_text("".join(lines))
    err = _one_line_exit_2(["check", str(copy / "can_log.toml")], capsys)
    assert f"{log}: signal 'WHEEL_SPEEDS.WHEEL_SPEED_RL'" in err, err
    assert f"line {i + 1}: implausible rear-left wheel speed at t = {stamp[1:-1][:-3]}" in err, err
    assert "remove that line" in err and "heading" not in err, err
