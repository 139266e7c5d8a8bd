#!/usr/bin/python3
"""rostest: with camera_input tag_detections, mvis takes mvis/TagDetectionArray messages on
<camera rostopic>/tag_detections and applies the same checks as to detections from images."""
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from mvis.msg import TagDetection, TagDetectionArray

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


if __name__ == "__main__":
    rostest.rosrun("mvis", "tag_detections", TagDetections)
