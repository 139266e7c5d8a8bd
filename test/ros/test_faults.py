#!/usr/bin/python3
"""rostest: a simulated VI-Rig bag with faults (a 0.3 s hole in imu0 at 11 s, the bag
restarted at 13 s with its first 3 s, garbled and repeated messages) replayed through the
nodelet: odometry keeps coming after every fault, the calibration message and the diagnostics
say that the estimate started over and why, and the final calibration of every camera and
auxiliary sensor is inside 3 sigma of the truth."""
import math
import os
import time
import unittest

import rospy
import rostest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from mvis.msg import Calibration
from nav_msgs.msg import Odometry

TIMEOUT_S = 90.0
BAG_S = 19.0  # 16 s of data and the 3 s replayed
START_S = 1700000000.0  # the data's first stamp (start_time_s in faults_sim.yaml)


def quaternion_matrix(q):
    x, y, z, w = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def rotation_error(R_hat, R):
    """Log(R_hat^T R) as a vector (small angles): the right perturbation of the std."""
    M = [[sum(R_hat[k][i] * R[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    return [0.5 * (M[2][1] - M[1][2]), 0.5 * (M[0][2] - M[2][0]), 0.5 * (M[1][0] - M[0][1])]


class Faults(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_faults")
        cls.data = rospy.get_param("~data")

    def test_faults(self):
        odometry, calibrations, diagnostics = [], [], []
        subs = [
            rospy.Subscriber("/mvis/odometry", Odometry,
                             lambda m: odometry.append(m.header.stamp.to_sec())),
            rospy.Subscriber("/mvis/calibration", Calibration, calibrations.append),
            rospy.Subscriber("/diagnostics", DiagnosticArray, diagnostics.append),
        ]
        start = time.time()
        while time.time() < start + TIMEOUT_S and (
                time.time() < start + BAG_S + 2.0 or
                not calibrations or calibrations[-1].restarts < 2):
            time.sleep(0.2)
        time.sleep(2.0)  # the last covariance after the bag's end
        for s in subs:
            s.unregister()
        self.assertTrue(odometry)
        self.assertTrue(calibrations)
        cal = calibrations[-1]
        # The hole and the replay each started the window over; the message says why.
        self.assertGreaterEqual(cal.restarts, 2)
        self.assertIn("starts over from the", cal.last_restart_reason)
        # Odometry came again after the replay jumped back (stamps of the bag's first seconds
        # after later ones), and again after the jump forward to the data's last 3 s (13-16 s
        # after START_S), once the window started over there (1.5 s of clock check, then its
        # first batch): odometry is live, so what arrived before that gets none.
        jumped = any(b < a - 5.0 for a, b in zip(odometry, odometry[1:]))
        self.assertTrue(jumped, "no odometry after the bag restarted")
        self.assertGreater(max(odometry) - START_S, 14.5)
        keys = {}
        for array in diagnostics:
            for status in array.status:
                for kv in status.values:
                    keys[kv.key] = kv.value
        self.assertIn("restarts", keys)
        self.assertGreaterEqual(int(keys["restarts"]), 2)
        self.assertIn("last_restart", keys)

        print("restarts %d, last: %s" % (cal.restarts, cal.last_restart_reason))
        with open(os.path.join(self.data, "truth", "kalibr_imucam_chain.yaml")) as f:
            truth = yaml.safe_load(f)
        for cam in cal.cameras:
            T = truth[cam.name]["T_cam_imu"]
            R = [row[:3] for row in T[:3]]
            q = cam.T_cam_imu.rotation
            R_hat = quaternion_matrix((q.x, q.y, q.z, q.w))
            for e, s in zip(rotation_error(R_hat, R), cam.rotation_std):
                self.assertLess(abs(e), 3.0 * s, cam.name + " rotation")
            p = cam.T_cam_imu.translation
            for e, s in zip((p.x - T[0][3], p.y - T[1][3], p.z - T[2][3]), cam.translation_std):
                self.assertLess(abs(e), 3.0 * s, cam.name + " translation")
            dt = cam.timeshift_cam_imu - truth[cam.name]["timeshift_cam_imu"]
            print("%s: time offset %.4f ms off, %.2f sigma" %
                  (cam.name, dt * 1e3, abs(dt) / cam.timeshift_cam_imu_std))
            self.assertLess(abs(dt), 3.0 * cam.timeshift_cam_imu_std, cam.name + " time offset")
        with open(os.path.join(self.data, "truth", "kalibr_imu_chain.yaml")) as f:
            imu_truth = yaml.safe_load(f)
        for s in cal.inertial[1:]:
            dt = s.time_offset - imu_truth[s.name]["time_offset"]
            self.assertLess(abs(dt), 3.0 * s.time_offset_std, s.name + " time offset")
            T = imu_truth[s.name]["T_i_b"]
            q = s.T_i_b.rotation
            R_hat = quaternion_matrix((q.x, q.y, q.z, q.w))
            for e, sd in zip(rotation_error(R_hat, [row[:3] for row in T[:3]]), s.rotation_std):
                self.assertLess(abs(e), 3.0 * sd, s.name + " rotation")


if __name__ == "__main__":
    rostest.rosrun("mvis", "faults", Faults)
