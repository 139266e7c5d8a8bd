#!/usr/bin/python3
"""The calibration at the moment the rig was declared ready, against a simulation's truth.

Reads RESULT/calibration_status.csv (the rig's "ready" row that stayed), RESULT/calibration.csv
(the estimate after every solve: the last row at or before that stamp, per sensor) and TRUTH's
Kalibr files; prints per sensor the rotation error [deg], translation error [mm] and time-offset
error [ms]. Usage: errors_at_ready.py RESULT TRUTH  (exit 1 when the rig never became ready)."""
import csv
import math
import os
import sys

import numpy as np
import yaml


def rotation_vector_to_matrix(r):
    angle = np.linalg.norm(r)
    if angle < 1e-15:
        return np.eye(3)
    k = r / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def angle_deg(Ra, Rb):
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def ready_stamp(result):
    stamp = None
    with open(os.path.join(result, "calibration_status.csv")) as f:
        for row in csv.DictReader(f):
            if row["sensor"] == "rig":
                stamp = float(row["stamp"]) if row["status"] == "ready" else None
    return stamp


def errors_at(result, truth, stamp):
    """{sensor: (rotation deg, translation mm or nan, time offset ms)} at `stamp`."""
    with open(os.path.join(truth, "kalibr_imucam_chain.yaml")) as f:
        cams = yaml.safe_load(f)
    with open(os.path.join(truth, "kalibr_imu_chain.yaml")) as f:
        imus = yaml.safe_load(f)
    last = {}
    with open(os.path.join(result, "calibration.csv")) as f:
        for row in csv.DictReader(f):
            if float(row["stamp"]) <= stamp + 1e-6:
                last[row["sensor"]] = row
    out = {}
    for sensor, row in sorted(last.items()):
        if sensor in cams:
            T = np.array(cams[sensor]["T_cam_imu"])
            offset = cams[sensor]["timeshift_cam_imu"]
        elif sensor in imus and sensor != "imu0":
            T = np.array(imus[sensor]["T_i_b"])
            offset = imus[sensor]["time_offset"]
        else:
            continue
        r = np.array([float(row[k]) for k in ("rx", "ry", "rz")])
        p = np.array([float(row[k]) for k in ("px", "py", "pz")])
        gyroscope = imus.get(sensor, {}).get("sensor_type") == "gyroscope"
        out[sensor] = (angle_deg(rotation_vector_to_matrix(r), T[:3, :3]),
                       float("nan") if gyroscope else 1e3 * np.linalg.norm(p - T[:3, 3]),
                       1e3 * abs(float(row["time_offset"]) - offset))
    return out


def main(argv):
    result, truth = argv[1:3]
    stamp = ready_stamp(result)
    if stamp is None:
        print("never ready")
        return 1
    print("ready at %.3f" % stamp)
    for sensor, (rot, trans, dt) in errors_at(result, truth, stamp).items():
        print("%-5s rotation %.4f deg, translation %.3f mm, time offset %.4f ms"
              % (sensor, rot, trans, dt))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
