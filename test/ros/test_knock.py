#!/usr/bin/python3
"""rostest: a simulated VI-Rig bag whose cam1 is turned by 1.2 deg and moved by 5 mm at 9 s,
replayed through the nodelet from the calibration before the knock. The change is declared for
cam1 alone within 3 s of the knock (the estimator measures 1.2-1.6 s on such runs), and it is
said on the calibration topic, /diagnostics and in calibration_changes.csv; at the end cam1's
calibration is its new mount's."""
import csv
import math
import os
import time
import unittest

import numpy
import rospy
import rostest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from mvis.msg import Calibration
from std_srvs.srv import Trigger

TIMEOUT_S = 60.0
KNOCK_S = 1700000000.0 + 9.0  # base clock


def quaternion_angle_deg(q, R):
    """The angle between a geometry_msgs quaternion and a rotation matrix [deg]."""
    x, y, z, w = q.x, q.y, q.z, q.w
    Q = numpy.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    c = (numpy.trace(Q.T @ R) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


class Knock(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_knock")
        cls.data = rospy.get_param("~data")

    def test_knock_is_declared_for_cam1(self):
        calibrations, counts = [], []

        def on_diagnostics(msg):
            for status in msg.status:
                for kv in status.values:
                    if kv.key == "calibration_changes":
                        counts.append(int(kv.value))
        subs = [rospy.Subscriber("/mvis/calibration", Calibration, calibrations.append),
                rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics)]
        # The bag lasts 16 s after a 2 s delay: wait for its end and for the change.
        start = time.time()
        while time.time() - start < TIMEOUT_S and not (
                time.time() - start > 22.0 and any(c.changes for c in calibrations)):
            time.sleep(0.2)
        for s in subs:
            s.unregister()
        with_changes = [c for c in calibrations if c.changes]
        self.assertTrue(with_changes, "no change declared")
        last = with_changes[-1]
        print("declared: %s" % list(zip([s.to_sec() for s in last.change_stamps], last.changes)))
        self.assertEqual(len(last.changes), 1, last.changes)
        self.assertTrue(last.changes[0].startswith("cam1 moved"), last.changes[0])
        declared = last.change_stamps[0].to_sec()
        self.assertGreater(declared, KNOCK_S)
        self.assertLess(declared, KNOCK_S + 3.0)
        self.assertTrue(counts)
        self.assertEqual(counts[-1], 1)

        # The result directory: a row per quantity of cam1 in calibration_changes.csv, and cam1's
        # calibration its new mount's.
        rospy.wait_for_service("/mvis/save_calibration", 10)
        reply = rospy.ServiceProxy("/mvis/save_calibration", Trigger)()
        self.assertTrue(reply.success, reply.message)
        result = reply.message[len("saved to "):]
        with open(os.path.join(result, "calibration_changes.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertTrue(rows)
        self.assertEqual({r["sensor"] for r in rows}, {"cam1"})
        self.assertIn("rotation", {r["quantity"] for r in rows})
        for r in rows:
            self.assertGreater(float(r["size_sigma"]), 3.0)
        with open(os.path.join(self.data, "truth", "kalibr_imucam_chain.yaml")) as f:
            truth = yaml.safe_load(f)
        T = numpy.array(truth["cam1"]["T_cam_imu"])
        cam1 = calibrations[-1].cameras[1]
        angle = quaternion_angle_deg(cam1.T_cam_imu.rotation, T[:3, :3])
        t = cam1.T_cam_imu.translation
        offset_mm = 1e3 * numpy.linalg.norm(numpy.array([t.x, t.y, t.z]) - T[:3, 3])
        print("cam1 at the end: %.4f deg, %.3f mm from its new mount" % (angle, offset_mm))
        # 7 s after the knock on the 0.5 px rig; the estimator's own test ends within 0.005 deg
        # and 0.1 mm after 18 s.
        self.assertLess(angle, 0.1)
        self.assertLess(offset_mm, 2.0)


if __name__ == "__main__":
    rostest.rosrun("mvis", "test_knock", Knock)
