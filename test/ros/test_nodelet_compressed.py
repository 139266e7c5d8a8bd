#!/usr/bin/python3
"""rostest: with camera_input: compressed the nodelet decodes sensor_msgs/CompressedImage on
<camera topic>/compressed (what rigs record; Debian has no compressed_image_transport) and finds
every tag of the rendered board in PNG and JPEG, 8 and 16 bit, mono and colour; a message it
cannot decode is counted as rejected."""
import io
import unittest

import rospy
import rostest
from PIL import Image as PilImage
from sensor_msgs.msg import CompressedImage

from test_nodelet_loads import BOARD, DiagnosticsWatch, read_pgm, wait_for


def encoded(image, fmt, **options):
    out = io.BytesIO()
    image.save(out, format=fmt, **options)
    return out.getvalue()


class NodeletCompressed(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_nodelet_compressed")

    def test_decodes_compressed_images(self):
        width, height, pixels = read_pgm(BOARD)
        gray = PilImage.frombytes("L", (width, height), pixels)
        # 16 bit: the 8-bit values times 257, which the nodelet scales back to the same pixels.
        deep = PilImage.frombytes("I;16", (width, height),
                                  b"".join((257 * p).to_bytes(2, "little") for p in pixels))
        images = [
            ("mono8; png compressed", encoded(gray, "PNG")),
            ("mono16; png compressed", encoded(deep, "PNG")),
            ("bgr8; jpeg compressed bgr8", encoded(gray.convert("RGB"), "JPEG", quality=95)),
            ("mono8; jpeg compressed", encoded(gray, "JPEG", quality=95)),
        ]
        pub = rospy.Publisher("/cam1/image_raw/compressed", CompressedImage, queue_size=10)
        self.assertTrue(wait_for(lambda: pub.get_num_connections() > 0))
        seen = []
        for fmt, data in images + [("png", b"\x89PNG not really")]:
            msg = CompressedImage()
            msg.header.stamp = rospy.Time.now()
            msg.header.frame_id = "cam1"
            msg.format, msg.data = fmt, data
            watch = DiagnosticsWatch("mvis: cam1")
            before = (len(seen), fmt)
            pub.publish(msg)
            # One at a time, so that each image's tag count can be read.
            ok = wait_for(lambda: watch.values.get("received", 0) +
                          watch.values.get("rejected", 0) == len(seen) + 1)
            watch.close()
            self.assertTrue(ok, "%s: diagnostics %s" % (before, watch.values))
            seen.append((fmt, dict(watch.values)))
        for fmt, values in seen[:-1]:
            # The rendered board shows all 36 tags of config/sim_vi_rig/aprilgrid.yaml.
            self.assertEqual(values.get("tags_in_last_frame"), 36, fmt)
        self.assertEqual(seen[-1][1].get("received"), len(images))
        self.assertEqual(seen[-1][1].get("rejected"), 1)


if __name__ == "__main__":
    rostest.rosrun("mvis", "nodelet_compressed", NodeletCompressed)
