#!/usr/bin/python3
"""report.md against an independent reading of the same result directory, and --params taking
effect: a simulated small rig (10 s, tag detections) through mvis_offline --batch with a
parameter file that holds every camera's time offset (estimate_time_offsets: false).

- report.md in the result and in online/, naming the bag and the pass;
- each camera's corner statistics (count, RMS, median, largest) recomputed from
  corner_residuals.csv (the median to the report's 0.01 px bins);
- each camera's rotation change / sigma recomputed from the initial and result YAML files
  (the rotation's change in the estimate's tangent, over the *_std key per axis);
- the held time offsets: the result's timeshift_cam_imu equal to the configuration's, and the
  report saying why.

Usage: check_report.py MVIS_SIMULATE MVIS_OFFLINE RIG_DIR
"""
import csv
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
import yaml

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tools"))
from checks import Checks  # noqa: E402


def table(report, header):
    """The rows of the Markdown table whose header row starts with `header`, as cell lists."""
    lines = report.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header))
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append([c.strip() for c in line.strip("|").split("|")])
    return rows


def log_rotation(R):
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
    if angle < 1e-12:
        return np.zeros(3)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return angle / (2.0 * math.sin(angle)) * w


def main(argv):
    simulate, offline, rig = argv[1:4]
    check = Checks()

    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([simulate, "--rig", rig, "--sim", os.path.join(rig, "sim.yaml"), "--output",
                        tmp, "--detections"], check=True, capture_output=True)
        params = os.path.join(tmp, "params.yaml")
        with open(params, "w") as f:
            f.write("estimate_time_offsets: false\n")
        result = os.path.join(tmp, "result")
        subprocess.run([offline, "--config", os.path.join(tmp, "config"), "--params", params,
                        "--bag", os.path.join(tmp, "sim.bag"), "--output", result, "--batch"],
                       check=True, capture_output=True)
        with open(os.path.join(result, "report.md")) as f:
            report = f.read()
        with open(os.path.join(result, "online", "report.md")) as f:
            online = f.read()
        check("bag sim.bag" in report and "batch" in report, "the batch's report names bag, pass")
        check("online (sliding window)" in online, "online/report.md is the online pass's")

        residuals = {r[0]: r for r in table(report, "| sensor | kind | factors")}
        corners = {}
        with open(os.path.join(result, "corner_residuals.csv")) as f:
            for r in csv.DictReader(f):
                corners.setdefault(r["camera"], []).append(
                    math.hypot(float(r["du"]), float(r["dv"])))
        for cam, errors in sorted(corners.items()):
            errors.sort()
            row = residuals[cam]
            rms = math.sqrt(sum(e * e for e in errors) / len(errors))
            median = errors[len(errors) // 2]
            check(int(row[3]) == len(errors), "%s corners %s = %d" % (cam, row[3], len(errors)))
            check(abs(float(row[4]) - rms) <= 0.0006, "%s RMS %s ~ %.4f" % (cam, row[4], rms))
            check(0.0 <= float(row[5]) - median <= 0.0101,
                  "%s median %s is its 0.01 px bin of %.4f" % (cam, row[5], median))
            check(abs(float(row[6]) - errors[-1]) <= 0.006,
                  "%s max %s ~ %.4f" % (cam, row[6], errors[-1]))

        with open(os.path.join(tmp, "config", "kalibr_imucam_chain.yaml")) as f:
            initial = yaml.safe_load(f)
        with open(os.path.join(result, "kalibr_imucam_chain.yaml")) as f:
            estimate = yaml.safe_load(f)
        rows = {(r[0], r[1]): r for r in table(report, "| sensor | quantity")}
        for cam in sorted(estimate):
            T0 = np.array(initial[cam]["T_cam_imu"])
            T1 = np.array(estimate[cam]["T_cam_imu"])
            # initial = estimate Exp(delta): delta = Log(R1^T R0)
            delta = log_rotation(T1[:3, :3].T @ T0[:3, :3])
            sigma = np.array(estimate[cam]["T_cam_imu_std"]["rotation"], dtype=float)
            expected = max(abs(delta / sigma))
            row = rows[(cam, "rotation of T_cam_imu [deg]")]
            check(abs(float(row[5]) - expected) <= 0.05 + 0.002 * expected,
                  "%s rotation change/sigma %s ~ %.2f" % (cam, row[5], expected))
            check(estimate[cam]["timeshift_cam_imu"] == initial[cam]["timeshift_cam_imu"],
                  "%s time offset held by --params" % cam)
        check("every camera's time offset: estimate_time_offsets false" in report,
              "the report says why the time offsets were held")
    return check.status()


if __name__ == "__main__":
    sys.exit(main(sys.argv))
