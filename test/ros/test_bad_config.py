#!/usr/bin/python3
"""rostest: with a broken config (test/data/bad_rig), mvis_node reports the exact problem in
diagnostics (and logs it once), subscribes to nothing, and stays up instead of crashing."""
import time
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rosgraph_msgs.msg import Log

TIMEOUT_S = 30.0
EXPECTED = ("test/data/bad_rig/kalibr_imu_chain.yaml: imu1: gyroscope_noise_density: "
            "must be positive, got -0.00016968")


class BadConfig(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_bad_config")

    def error_statuses(self, timeout_s):
        """Configuration errors seen on /diagnostics: waits for the first, up to timeout_s."""
        seen = []

        def on_diagnostics(array):
            seen.extend(s for s in array.status if s.name == "mvis: configuration"
                        and s.level == DiagnosticStatus.ERROR)

        sub = rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics)
        deadline = time.time() + timeout_s
        while not seen and time.time() < deadline and not rospy.is_shutdown():
            time.sleep(0.1)
        sub.unregister()
        return seen

    def test_reports_the_exact_problem_and_stays_up(self):
        first = self.error_statuses(TIMEOUT_S)
        self.assertTrue(first, "no configuration error on /diagnostics")
        self.assertTrue(first[0].message.endswith(EXPECTED), first[0].message)
        # Still alive a while later: the errors keep coming, and the node answers.
        time.sleep(1.0)
        self.assertTrue(self.error_statuses(2.0), "mvis_node went down")
        master = rosgraph.Master("/test_bad_config")
        node = xmlrpc.client.ServerProxy(master.lookupNode("/mvis"))
        pid = node.getPid("/test_bad_config")
        self.assertEqual(pid[0], 1, "mvis_node does not answer: %s" % (pid,))

    def test_subscribes_to_nothing(self):
        time.sleep(2.0)
        subscribers = dict(rosgraph.Master("/test_bad_config").getSystemState()[1])
        for topic in ["/imu0", "/imu1", "/imu2", "/cam0/image_raw"]:
            self.assertNotIn("/mvis", subscribers.get(topic, []), topic)


if __name__ == "__main__":
    rostest.rosrun("mvis", "bad_config", BadConfig)
