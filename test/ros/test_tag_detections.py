#!/usr/bin/python3
"""rostest: with camera_input tag_detections, mvis takes mvis/TagDetectionArray messages on
<camera rostopic>/tag_detections and applies the same checks as to detections from images."""
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from mvis.msg import TagDetection, TagDetectionArray
from sensor_msgs.msg import Image
from visualization_msgs.msg import MarkerArray

TIMEOUT_S = 30.0


def detection(tag_id, u, v, side=40.0):
    """An upright square tag with its bottom-left corner at (u, v)."""
    d = TagDetection()
    d.id = tag_id
    d.corners = [u, v, u + side, v, u + side, v - side, u, v - side]
    return d


class TagDetections(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_tag_detections")

    def test_same_checks_as_images(self):
        pub = rospy.Publisher("/cam0/image_raw/tag_detections", TagDetectionArray, queue_size=10)
        deadline = time.time() + TIMEOUT_S
        while pub.get_num_connections() == 0 and time.time() < deadline:
            time.sleep(0.1)
        msg = TagDetectionArray()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = "cam0"
        nan = detection(2, 300, 300)
        nan.corners[3] = float("nan")
        msg.detections = [detection(0, 100, 300), detection(1, 200, 300), nan,
                          detection(99, 400, 300)]  # id 99 is not on the 6x6 board
        pub.publish(msg)
        values = {}

        def on_diagnostics(array):
            for status in array.status:
                if status.name == "mvis: cam0":
                    values.update({kv.key: int(kv.value) for kv in status.values})

        sub = rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics)
        deadline = time.time() + TIMEOUT_S
        while values.get("received") != 1 and time.time() < deadline:
            time.sleep(0.1)
        sub.unregister()
        self.assertEqual(values.get("received"), 1, values)
        self.assertEqual(values.get("rejected"), 0, values)
        self.assertEqual(values.get("tags_in_last_frame"), 2, values)
        self.assertEqual(values.get("tags_rejected"), 2, values)

    def test_shows_in_rviz(self):
        """(Runs after test_same_checks_as_images, which counts cam0's messages.) rviz's displays
        on a replay of detections: the camera's debug image is its kept tags
        drawn on a canvas of its size, and the board's markers come again (frame-locked) after
        the first, latched ones, which rviz drops while the board frame does not exist yet."""
        images, markers = [], []
        image_sub = rospy.Subscriber("/mvis/cam0/debug_image", Image, images.append)
        marker_sub = rospy.Subscriber("/mvis/tags", MarkerArray, markers.append)
        pub = rospy.Publisher("/cam0/image_raw/tag_detections", TagDetectionArray, queue_size=10)
        deadline = time.time() + TIMEOUT_S
        while ((pub.get_num_connections() == 0 or image_sub.get_num_connections() == 0)
               and time.time() < deadline):
            time.sleep(0.1)
        time.sleep(0.5)  # the node sees the image subscription
        msg = TagDetectionArray()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = "cam0"
        msg.detections = [detection(0, 100, 300), detection(1, 200, 300)]
        pub.publish(msg)
        while (not images or len(markers) < 3) and time.time() < deadline:
            time.sleep(0.1)
        image_sub.unregister()
        marker_sub.unregister()
        self.assertTrue(images, "no debug image")
        # cam0 of config/sim_vi_rig is 848 x 800.
        self.assertEqual((images[0].width, images[0].height), (848, 800))
        self.assertEqual(images[0].encoding, "bgr8")
        self.assertGreaterEqual(len(markers), 3)
        self.assertTrue(all(m.frame_locked for m in markers[-1].markers))
        self.assertEqual(len(markers[-1].markers), 36 + 1)  # an id per tag, the squares


if __name__ == "__main__":
    rostest.rosrun("mvis", "tag_detections", TagDetections)
