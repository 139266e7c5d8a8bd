#!/usr/bin/python3
"""rostest: a simulated bag of the VI-Rig with two auxiliary IMUs and a gyroscope replayed
through the nodelet gives odometry close to the truth, for every base-IMU reading and without a
pause while the estimator solves, TF for the world, board, base IMU, every camera and every
auxiliary sensor, a calibration message with finite standard deviations for the cameras and the
auxiliary sensors, and a result directory on ~save_calibration."""
import bisect
import csv
import math
import os
import shutil
import time
import unittest

import rospy
import rostest
from mvis.msg import Calibration, CalibrationStatus
from mvis.srv import SaveCalibration
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage

TIMEOUT_S = 60.0
# The 8 s bag's base IMU gives 4000 readings; odometry starts after the initialization (1.5 s of
# clock check, then the first batch), about 3250 of them.
MIN_ODOMETRY = 2500
IMU_PERIOD_S = 1.0 / 500.0


def read_tum(path):
    stamps, positions = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            values = line.split()
            stamps.append(float(values[0]))
            positions.append(tuple(float(v) for v in values[1:4]))
    return stamps, positions


class Replay(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_replay")
        cls.data = rospy.get_param("~data")

    def test_replay(self):
        odometry, frames, calibrations, diagnostics, statuses = [], set(), [], [], []
        odometry_arrival, imu_arrival = {}, {}

        def on_odometry(msg):
            odometry_arrival[msg.header.stamp.to_nsec()] = time.monotonic()
            odometry.append(msg)

        def on_diagnostics(msg):
            for status in msg.status:
                if status.name == "mvis: odometry":
                    diagnostics.append({kv.key: float(kv.value) for kv in status.values})
        subs = [
            rospy.Subscriber("/mvis/odometry", Odometry, on_odometry),
            rospy.Subscriber("/imu0", Imu, lambda m: imu_arrival.setdefault(
                m.header.stamp.to_nsec(), time.monotonic())),
            rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics),
            rospy.Subscriber("/tf", TFMessage, lambda m: frames.update(
                (t.header.frame_id, t.child_frame_id) for t in m.transforms)),
            rospy.Subscriber("/mvis/calibration", Calibration, calibrations.append),
            rospy.Subscriber("/mvis/calibration_status", CalibrationStatus, statuses.append),
        ]
        deadline = time.time() + TIMEOUT_S
        # The bag lasts 8 s; initialization takes 1.5 s (clock check), odometry comes at the
        # base IMU's 500 Hz and the calibration covariance every 30 solves.
        while time.time() < deadline and (
                len(odometry) < MIN_ODOMETRY or not any(
                    all(math.isfinite(x) for x in c.cameras[0].rotation_std)
                    for c in calibrations)):
            time.sleep(0.2)
        for s in subs:
            s.unregister()
        self.assertGreaterEqual(len(odometry), MIN_ODOMETRY)
        stamps_out = [m.header.stamp.to_sec() for m in odometry]
        self.assertEqual(stamps_out, sorted(stamps_out))  # IMU rate, in order
        self.check_odometry_flows(odometry, odometry_arrival, imu_arrival, diagnostics)
        last = odometry[-1]
        self.assertEqual(last.header.frame_id, "odom")
        self.assertEqual(last.child_frame_id, "imu0")

        # The board lies flat in the simulation, so the gravity-aligned world is the board
        # frame: positions compare directly with the truth (imu0 in the board frame).
        stamps, positions = read_tum(os.path.join(self.data, "truth", "trajectory.tum"))
        errors = []
        first = odometry[0].header.stamp.to_sec()
        for msg in odometry:
            t = msg.header.stamp.to_sec()
            if t < first + 3.0:  # converging from the perturbed guess
                continue
            i = min(bisect.bisect_left(stamps, t), len(stamps) - 1)
            if abs(stamps[i] - t) > 0.0005:
                continue
            p = msg.pose.pose.position
            errors.append(math.dist((p.x, p.y, p.z), positions[i]))
        # At least a second of it after the 3 s of converging: the wait above can end at
        # MIN_ODOMETRY (5 s), leaving exactly 1000 (a clean-clone run once stopped there).
        self.assertGreater(len(errors), 500)
        # Measured ~2-5 mm a few seconds into the run; 3 cm catches a wrong frame or clock.
        self.assertLess(max(errors), 0.03, max(errors))
        self.assertTrue(all(math.isfinite(v) for v in last.pose.covariance))
        # Twist covariance filled: linear from the state's velocity covariance (mm/s-level on
        # this rig), angular at least one gyroscope reading's white noise.
        twist = last.twist.covariance
        self.assertTrue(all(math.isfinite(v) for v in twist))
        for i in range(6):
            self.assertGreater(twist[7 * i], 0.0, i)
        self.assertLess(max(twist[7 * i] for i in range(3)), 0.1 ** 2)

        for parent, child in [("odom", "board"), ("board", "imu0"), ("imu0", "cam0"),
                              ("imu0", "cam1"), ("imu0", "cam2"), ("imu0", "imu1"),
                              ("imu0", "imu2"), ("imu0", "imu3")]:
            self.assertIn((parent, child), frames)

        good = [c for c in calibrations
                if all(math.isfinite(x) for x in c.cameras[0].rotation_std)]
        self.assertTrue(good)
        cal = good[-1]
        self.assertEqual([c.name for c in cal.cameras], ["cam0", "cam1", "cam2"])
        for cam in cal.cameras:
            self.assertLess(max(cam.rotation_std), math.radians(0.5))
            self.assertLess(max(cam.translation_std), 0.02)
            self.assertLess(cam.timeshift_cam_imu_std, 0.005)
        self.assertEqual([(s.name, s.sensor_type) for s in cal.inertial],
                         [("imu0", "imu"), ("imu1", "imu"), ("imu2", "gyroscope"),
                          ("imu3", "imu")])
        # After the 8 s bag from about 2 deg / 1 cm / 5 ms off (mvis_offline on the same bag:
        # std per axis ~0.012 deg, ~0.9 mm, ~0.05 ms; errors 0.02 deg, 1.3-1.9 mm, 0.08 ms);
        # the bounds catch an aux sensor left out of the window, which keeps its prior
        # (0.1 rad, 0.1 m, 50 ms).
        for s in cal.inertial[1:]:
            self.assertLess(max(s.rotation_std), math.radians(0.2), s.name)
            self.assertLess(s.time_offset_std, 0.002, s.name)
            if s.sensor_type == "imu":
                self.assertLess(max(s.translation_std), 0.01, s.name)
            else:
                self.assertEqual(max(s.translation_std), 0.0, s.name)  # not calibrated

        # Guided calibration: one entry per calibrated quantity, each with a status and (while
        # not done) its sigma against its target.
        self.assertTrue(statuses)
        status = statuses[-1]
        quantities = {(q.sensor, q.quantity): q for q in status.quantities}
        for cam in ["cam0", "cam1", "cam2"]:
            for quantity in ["rotation", "translation", "time_offset"]:
                self.assertIn((cam, quantity), quantities)
        self.assertIn(("imu2", "rotation"), quantities)
        self.assertNotIn(("imu2", "translation"), quantities)  # a gyroscope
        for q in status.quantities:
            self.assertIn(q.status, ["converged", "improving", "unobservable", "held"])
            self.assertTrue(math.isfinite(q.sigma), (q.sensor, q.quantity))
            self.assertGreater(q.target, 0.0)
        # 8 s from 2 deg / 1 cm / 5 ms off cannot make the rig ready at the defaults' targets.
        self.assertFalse(status.ready)
        self.assertTrue(any(q.status == "improving" and q.advice for q in status.quantities))

        rospy.wait_for_service("/mvis/save_calibration", 10)
        reply = rospy.ServiceProxy("/mvis/save_calibration", Trigger)()
        self.assertTrue(reply.success, reply.message)
        self.assertTrue(reply.message.startswith("saved to "), reply.message)
        result = reply.message[len("saved to "):]
        self.assertEqual(os.path.dirname(result), os.path.join(self.data, "result"))
        self.assertEqual(os.path.realpath(os.path.join(self.data, "result", "latest")),
                         os.path.realpath(result))
        for name in ["kalibr_imu_chain.yaml", "kalibr_imucam_chain.yaml", "trajectory.tum",
                     "report.md", "calibration_status.csv"]:
            self.assertTrue(os.path.isfile(os.path.join(result, name)), name)
        with open(os.path.join(result, "calibration_status.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertTrue(any(r["sensor"] == "rig" and r["quantity"] == "all" for r in rows))
        self.assertTrue(any(r["sensor"] == "cam0" and r["quantity"] == "rotation" for r in rows))
        with open(os.path.join(result, "report.md")) as f:
            report = f.read()
        self.assertIn("## Status", report)
        self.assertIn("## Residuals", report)
        self.assertIn("mvis nodelet /mvis", report)
        # Every camera's corners counted, with an RMS near the rig's 0.5 px noise.
        for cam in ["cam0", "cam1", "cam2"]:
            row = [line for line in report.splitlines() if line.startswith("| %s | camera" % cam)]
            self.assertEqual(len(row), 1, cam)
            cells = [c.strip() for c in row[0].split("|")]
            self.assertGreater(int(cells[4]), 1000, row[0])
            self.assertLess(float(cells[5]), 2.0, row[0])
        # A second save is a new directory; save_calibration_to refuses a non-empty one.
        again = rospy.ServiceProxy("/mvis/save_calibration", Trigger)()
        self.assertTrue(again.success, again.message)
        self.assertNotEqual(again.message, reply.message)
        rospy.wait_for_service("/mvis/save_calibration_to", 10)
        save_to = rospy.ServiceProxy("/mvis/save_calibration_to", SaveCalibration)
        refused = save_to(result)
        self.assertFalse(refused.success)
        self.assertIn("never overwritten", refused.message)
        named = os.path.join(self.data, "named_result")
        shutil.rmtree(named, ignore_errors=True)  # a previous run's, when the test is run again
        written = save_to(named)
        self.assertTrue(written.success, written.message)
        self.assertEqual(written.directory, named)
        self.assertEqual(written.message, "saved to " + named)
        self.assertTrue(os.path.isfile(os.path.join(named, "report.md")))
        with open(os.path.join(result, "kalibr_imucam_chain.yaml")) as f:
            self.assertIn("T_cam_imu_std", f.read())
        with open(os.path.join(result, "kalibr_imu_chain.yaml")) as f:
            text = f.read()
        self.assertIn("T_i_b_std", text)
        self.assertIn("time_offset_std", text)

    def check_odometry_flows(self, odometry, odometry_arrival, imu_arrival, diagnostics):
        """Odometry for every base reading once it started, and never held up by a solve. The
        nodelet measures it (from a reading's receipt to its odometry message, and the
        intervals between odometry messages against those between their readings' arrivals):
        before the IMU callback stopped waiting for the estimator, solves held odometry up by
        up to 61 ms. This node's own view (the two messages' arrivals here) is
        printed; a Python subscriber to /tf at 500 Hz is too slow to time single milliseconds,
        so only its median is asserted, and within the nodelet's bound (10 IMU periods): on this
        shared machine it was 10.4 ms once in a clean-clone run (0.13 ms alone right after)."""
        stamps = [m.header.stamp.to_nsec() for m in odometry]
        expected = sorted(s for s in imu_arrival if stamps[0] <= s <= stamps[-1])
        self.assertEqual(stamps, expected)  # none missing, none extra
        delays = sorted(odometry_arrival[s] - imu_arrival[s] for s in stamps)
        print("odometry after its reading, at the test node: median %.2f ms, p99 %.2f ms, "
              "max %.2f ms over %d" % (1e3 * delays[len(delays) // 2],
                                       1e3 * delays[int(0.99 * (len(delays) - 1))],
                                       1e3 * delays[-1], len(delays)))
        self.assertTrue(diagnostics)
        nodelet = diagnostics[-1]
        print("nodelet: latency median %.2f ms, p99 %.2f ms, worst %.2f ms; worst interval "
              "%.2f ms (readings' %.2f ms); estimator backlog %.3f s"
              % (nodelet["latency_p50_ms_since_start"], nodelet["latency_p99_ms_since_start"],
                 nodelet["worst_latency_ms"], nodelet["worst_interval_ms"],
                 nodelet["worst_reading_interval_ms"], nodelet["estimator_backlog_s"]))
        bound_ms = 10 * IMU_PERIOD_S * 1e3
        self.assertLess(1e3 * delays[len(delays) // 2], bound_ms)
        self.assertLess(nodelet["worst_latency_ms"], bound_ms)
        # An interval is the readings' own plus what the latency changed between them.
        self.assertLess(nodelet["worst_interval_ms"],
                        max(bound_ms, nodelet["worst_reading_interval_ms"] + bound_ms / 2))

if __name__ == "__main__":
    rostest.rosrun("mvis", "replay", Replay)
