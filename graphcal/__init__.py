"""graphcal: wheel-odometry calibration with noise compensation, as GTSAM factor graphs.

The public surface is ``graphcal.__all__``; each name is importable from ``graphcal``
directly (loaded on first use, so ``import graphcal`` stays light)::

    import graphcal

    log = graphcal.load_drive_log("drive.csv")
    run = graphcal.run_calibration(log)            # joint method: theta, covariance, verdicts
    pim = graphcal.preintegrate(inputs, theta)     # wheel steps between two keyframes
    factor = graphcal.WheelOdometryFactor(x0, x1, theta_key, pim).factor()
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_PUBLIC = {
    # Drive logs, synthetic drives and trajectory files.
    "DriveLog": "graphcal.log.drive_log",
    "load_drive_log": "graphcal.log.load",
    "write_drive_log": "graphcal.log.drive_log",
    "open_log": "graphcal.recording.open_log",  # a CSV or a recording, by path
    "recording_path": "graphcal.recording.open_log",  # a recording's directory as its manifest
    "log_distance_line": "graphcal.report.log_summary",  # a log described, as `check` says
    "log_check_lines": "graphcal.report.log_summary",
    "log_excitation_lines": "graphcal.report.log_summary",
    "log_masked_lines": "graphcal.report.log_summary",
    "simulate_drive": "graphcal.simulate.drive",
    "write_synthetic_drive": "graphcal.simulate.drive",  # the CSV, its truth and sidecar
    "THETA_TRUE_DEFAULT": "graphcal.simulate.drive",  # the synthetic car's theta [SI]
    "NoiseLevels": "graphcal.simulate.drive",
    "ThetaStep": "graphcal.simulate.drive",
    "parse_defects": "graphcal.simulate.defects",  # defects of real logs, added to a drive
    "degrade": "graphcal.simulate.defects",
    "DEFECT_NAMES": "graphcal.simulate.defects",
    "DEFECTS_IN_ALL": "graphcal.simulate.defects",  # the defects "all" adds
    "simulate_robot": "graphcal.simulate.robot",  # a robot's runs, spins and stops
    "RobotSettings": "graphcal.simulate.robot_settings",
    "theta_true_for": "graphcal.simulate.robot",
    "write_tum": "graphcal.log.tum",
    "read_tum": "graphcal.log.tum",
    # Recordings: streams manifests and ROS bags, resampled into drive logs.
    "import_recording": "graphcal.recording.importer",
    "ImportedLog": "graphcal.recording.importer",
    "BagOptions": "graphcal.recording.importer",
    "read_recording": "graphcal.recording.importer",
    "is_recording": "graphcal.recording.importer",  # a manifest or a bag, not a drive-log CSV
    "MANIFEST_SUFFIXES": "graphcal.recording.importer",
    "write_import": "graphcal.recording.import_output",
    "check_import_output": "graphcal.recording.import_output",  # before an import, not after
    "manifest_help": "graphcal.recording.manifest.help",  # every manifest key with its default
    "Recording": "graphcal.recording.streams",
    "resample": "graphcal.recording.resampling",
    "read_bag": "graphcal.recording.bag.read",
    "BagRequest": "graphcal.recording.bag.request",  # what read_bag reads (BagOptions: alias)
    "read_manifest": "graphcal.recording.manifest_recording",
    "Section": "graphcal.recording.section",  # a section's keys, as every source reads them
    "WHEEL_KINDS": "graphcal.recording.vocabulary",  # [wheels] kind: each kind of wheel signal
    "SPEED_UNITS": "graphcal.recording.vocabulary",
    "simulate_streams": "graphcal.simulate.streams",
    "StreamSettings": "graphcal.simulate.streams",
    "write_streams": "graphcal.simulate.streams",
    "check_simulate_output": "graphcal.simulate.outputs",  # before simulating, not after
    "write_raw_logs": "graphcal.simulate.raw_logs",  # a recording as candump + DBC, NMEA
    "write_bag": "graphcal.simulate.bags",  # a recording as a ROS 1/2 bag or MCAP file
    "BagTopics": "graphcal.simulate.bags",  # the topics write_bag writes
    # The odometry model (eqs. 1-3).
    "THETA_NOMINAL": "graphcal.model",
    "PARAMETER_NAMES": "graphcal.model",
    "integrate": "graphcal.model",
    # Calibration of a drive log.
    "Settings": "graphcal.pipeline.configuration.settings",
    "load_settings": "graphcal.pipeline.configuration.settings_file",
    "VehicleProfile": "graphcal.vehicle",
    "load_vehicle": "graphcal.pipeline.configuration.settings_file",
    "apply_vehicle": "graphcal.pipeline.configuration.vehicle_settings",
    # what a settings file keeps
    "vehicle_settings_in": "graphcal.pipeline.configuration.settings_file",
    # defaults, file, vehicle, options
    "configure_settings": "graphcal.pipeline.configuration.configure",
    "calibrate_file": "graphcal.pipeline.end_to_end.calibrate_file",  # open a log and calibrate it
    "METHODS": "graphcal.pipeline.end_to_end.run",
    "default_workers": "graphcal.pipeline.solvers.parallel",
    # the exit status of an untrusted result
    "EXIT_UNTRUSTED": "graphcal.pipeline.end_to_end.trust",
    "check_output_directory": "graphcal.report.result_set",  # before a run, not after
    "summary_text": "graphcal.report.results",
    "run_calibration": "graphcal.pipeline.end_to_end.run",
    "CalibrationRun": "graphcal.pipeline.end_to_end.calibration_run",
    "wheel_model": "graphcal.pipeline.end_to_end.localization_inputs",
    "prepare_localization": "graphcal.pipeline.end_to_end.localization_inputs",
    "write_results": "graphcal.report.results",
    "calibrate_joint": "graphcal.pipeline.solvers.joint",
    "solve_joint": "graphcal.pipeline.solvers.joint",
    # iterations, tolerance, workers, progress
    "SolveOptions": "graphcal.graph.optimization.solve_options",
    # how a solve ended: status, iterations
    "SolveOutcome": "graphcal.graph.optimization.solve_options",
    "SolveStatus": "graphcal.graph.optimization.solve_options",
    "solve_joint_batches": "graphcal.pipeline.methods.joint_batches",
    "JointSettings": "graphcal.pipeline.solvers.joint_settings",
    "assess_observability": "graphcal.graph.solution.observability",
    "Observability": "graphcal.graph.solution.observability",
    # Validation on data the calibration did not see: another log, or held-apart windows.
    "validation_errors": "graphcal.pipeline.end_to_end.held_apart",
    "HeldApartErrors": "graphcal.pipeline.end_to_end.held_apart",
    "time_windows": "graphcal.pipeline.end_to_end.held_apart",
    "holding_apart": "graphcal.pipeline.end_to_end.held_apart",
    "time_window": "graphcal.pipeline.end_to_end.held_apart",
    # Fleets: many vehicles' daily logs on Dask (the ``fleet`` extra).
    "run_fleet": "graphcal.fleet.run",
    "FleetOptions": "graphcal.fleet.run",
    "FleetRun": "graphcal.fleet.run",
    "discover_fleet": "graphcal.fleet.sources",
    "simulate_fleet": "graphcal.simulate.fleet",
    "FleetChange": "graphcal.simulate.fleet",
    # Evaluation against a known truth (synthetic drives).
    "evaluate": "graphcal.evaluation",
    "Evaluation": "graphcal.evaluation",
    "Truth": "graphcal.evaluation",
    "cramer_rao_bound": "graphcal.evaluation",
    "cramer_rao_bounds": "graphcal.evaluation",
    "synthetic_truth": "graphcal.evaluation",  # a synthetic log's sidecar or manifest
    # Factors and values for your own GTSAM graphs.
    "PreintegratedWheelOdometry": "graphcal.factors",
    "WheelOdometryFactor": "graphcal.factors",
    "wheel_odometry_between_factor": "graphcal.factors",
    "preintegrate": "graphcal.factors",
    "keyframe_odometry_factor": "graphcal.localization.keyframe_odometry",
    "keyframe_odometry_factors": "graphcal.localization.keyframe_odometry",
    "OdometryNoise": "graphcal.localization.keyframe_odometry",
    "odometry_covariance": "graphcal.localization.keyframe_odometry",
    "segment_odometry_factor": "graphcal.factors",
    "pose_measurement_factor": "graphcal.factors",
    "theta_prior_factor": "graphcal.factors",
    "slip_prior_factor": "graphcal.graph.construction.slip",
    "slip_step_factor": "graphcal.graph.construction.slip",
    "insert_theta": "graphcal.localization.values",
    "theta_from_values": "graphcal.localization.values",
    "insert_states": "graphcal.localization.values",
    "states_from_values": "graphcal.localization.values",
    # Localization with calibration.
    "smooth_drive": "graphcal.localization.smoothing",
    "SmoothingSettings": "graphcal.localization.smoothing",
    "run_online": "graphcal.localization.online",
    "OnlineSettings": "graphcal.localization.online",
    "outage_errors": "graphcal.localization.dead_reckoning",
    "OutageSettings": "graphcal.localization.dead_reckoning",
    # Benchmark (`graphcal bench`; options: graphcal.cli.bench).
    "run_bench": "graphcal.bench.run",
    "write_bench_report": "graphcal.bench.run",
    # Units of theta as displayed: m, mm, m, mm·s²/m.
    "DISPLAY_SCALE": "graphcal.units",
    "DISPLAY_UNITS": "graphcal.units",
    # Errors and progress.
    "GraphcalError": "graphcal.errors",
    "Progress": "graphcal.progress",  # the type of every progress callback
    "first_line": "graphcal.errors",  # an error message's first line
    "remembering_interrupts": "graphcal.interrupt",  # Ctrl-C never dropped (the CLI's run)
}

__all__ = sorted(_PUBLIC)


def __getattr__(name: str) -> Any:
    """Load a public name from its module on first use (PEP 562)."""
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'graphcal' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
