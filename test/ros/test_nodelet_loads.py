#!/usr/bin/python3
"""rostest: the mvis nodelet loads with the default config (config/sim_vi_rig), advertises its
topics, subscribes to every sensor, publishes the configured calibration, and counts good and
bad input in its diagnostics."""
import gzip
import math
import os
import time
import unittest

import rosgraph
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from mvis.msg import Calibration
from sensor_msgs.msg import Image, Imu

TIMEOUT_S = 30.0
BOARD = os.path.join(os.path.dirname(__file__), "..", "data", "board_cam1_752x480.pgm.gz")


def wait_for(predicate, timeout_s=TIMEOUT_S):
    deadline = time.time() + timeout_s
    while time.time() < deadline and not rospy.is_shutdown():
        if predicate():
            return True
        time.sleep(0.1)
    return False


def read_pgm(path):
    """(width, height, bytes) of a gzipped binary PGM."""
    data = gzip.open(path, "rb").read()
    fields, offset = [], 0
    while len(fields) < 4:  # magic, width, height, maxval
        while data[offset:offset + 1].isspace():
            offset += 1
        end = offset
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[offset:end])
        offset = end
    assert fields[0] == b"P5" and fields[3] == b"255"
    return int(fields[1]), int(fields[2]), data[offset + 1:]


def mono8(width, height, pixels, encoding="mono8", step=None):
    msg = Image()
    msg.header.stamp = rospy.Time.now()
    msg.header.frame_id = "cam1"
    msg.width, msg.height, msg.encoding = width, height, encoding
    msg.step = width if step is None else step
    msg.data = pixels
    return msg


class DiagnosticsWatch:
    """The latest key/values of one diagnostics status."""

    def __init__(self, name):
        self.values = {}
        self.name = name
        self.sub = rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_array)

    def on_array(self, array):
        for status in array.status:
            if status.name == self.name:
                self.values = {kv.key: int(kv.value) for kv in status.values}

    def close(self):
        self.sub.unregister()


class NodeletLoads(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_nodelet_loads")

    def test_advertises_its_topics(self):
        expected = {
            "/mvis/odometry": "nav_msgs/Odometry",
            "/mvis/path": "nav_msgs/Path",
            "/mvis/calibration": "mvis/Calibration",
            "/diagnostics": "diagnostic_msgs/DiagnosticArray",
        }

        def advertised():
            topics = dict(rospy.get_published_topics())
            return all(topics.get(name) == kind for name, kind in expected.items())

        self.assertTrue(wait_for(advertised), "not advertised: %s" % rospy.get_published_topics())

    def test_subscribes_to_every_sensor(self):
        sensors = ["/imu0", "/imu1", "/imu2", "/cam0/image_raw", "/cam1/image_raw",
                   "/cam2/image_raw"]
        master = rosgraph.Master("/test_nodelet_loads")

        def subscribed():
            subscribers = dict(master.getSystemState()[1])
            return all("/manager" in subscribers.get(topic, []) for topic in sensors)

        self.assertTrue(wait_for(subscribed), str(master.getSystemState()[1]))

    def test_calibration_is_the_configured_one(self):
        msg = rospy.wait_for_message("/mvis/calibration", Calibration, timeout=TIMEOUT_S)
        self.assertEqual(msg.header.frame_id, "imu0")
        self.assertEqual([s.name for s in msg.inertial], ["imu0", "imu1", "imu2"])
        self.assertEqual([s.sensor_type for s in msg.inertial], ["imu", "imu", "gyroscope"])
        self.assertEqual([c.name for c in msg.cameras], ["cam0", "cam1", "cam2"])
        cam1 = msg.cameras[1]
        self.assertEqual(list(cam1.intrinsics), [612.4, 611.8, 376.2, 241.5])
        self.assertEqual(cam1.distortion_model, "radtan")
        self.assertEqual(list(cam1.resolution), [752, 480])
        t = msg.cameras[0].T_cam_imu.translation
        # config/sim_vi_rig/kalibr_imucam_chain.yaml, cam0, last column of T_cam_imu
        self.assertAlmostEqual(t.x, 0.029990875402274186, places=12)
        self.assertAlmostEqual(t.z, -0.10061414513020023, places=12)
        # No estimate has run yet: uncertainty not known.
        self.assertTrue(all(math.isnan(v) for v in cam1.intrinsics_std))

    def test_counts_good_and_rejects_bad_imu_samples(self):
        pub = rospy.Publisher("/imu0", Imu, queue_size=100)
        self.assertTrue(wait_for(lambda: pub.get_num_connections() > 0))
        good, bad = 20, 1
        for i in range(good + bad):
            msg = Imu()
            msg.header.stamp = rospy.Time.now()
            msg.linear_acceleration.z = 9.81 if i < good else float("nan")
            pub.publish(msg)
            time.sleep(0.005)
        counts = {}

        def on_diagnostics(array):
            for status in array.status:
                if status.name == "mvis: imu0":
                    counts.update({kv.key: int(kv.value) for kv in status.values})

        sub = rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics)
        ok = wait_for(lambda: counts.get("received") == good and counts.get("rejected") == bad)
        sub.unregister()
        self.assertTrue(ok, "diagnostics counts: %s" % counts)

    def test_detects_tags_and_survives_corrupt_images(self):
        width, height, pixels = read_pgm(BOARD)
        pub = rospy.Publisher("/cam1/image_raw", Image, queue_size=10)
        debug = []
        debug_sub = rospy.Subscriber("/mvis/cam1/debug_image", Image, debug.append)
        self.assertTrue(wait_for(lambda: pub.get_num_connections() > 0 and
                                 debug_sub.get_num_connections() > 0))
        corrupt = [
            mono8(0, 0, b""),                                   # empty
            mono8(width, height, pixels, encoding="nonsense"),  # unknown encoding
            mono8(width, height, pixels[:100]),                 # data shorter than step x height
            mono8(376, 240, pixels[:376 * 240]),                # not the camera's resolution
        ]
        for msg in corrupt + [mono8(width, height, pixels)]:
            pub.publish(msg)
            time.sleep(0.05)
        watch = DiagnosticsWatch("mvis: cam1")
        ok = wait_for(lambda: watch.values.get("received") == 1 and
                      watch.values.get("rejected") == len(corrupt))
        watch.close()
        self.assertTrue(ok, "cam1 diagnostics: %s" % watch.values)
        # The rendered board shows all 36 tags of config/sim_vi_rig/aprilgrid.yaml.
        self.assertEqual(watch.values.get("tags_in_last_frame"), 36)
        self.assertEqual(watch.values.get("tags_rejected"), 0)
        self.assertTrue(wait_for(lambda: len(debug) > 0), "no debug image")
        debug_sub.unregister()
        self.assertEqual((debug[0].width, debug[0].height, debug[0].encoding),
                         (width, height, "bgr8"))


if __name__ == "__main__":
    rostest.rosrun("mvis", "nodelet_loads", NodeletLoads)
