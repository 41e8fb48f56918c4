#!/usr/bin/env python3
"""flsm_node with ~republish_at_rest: true keeps its heavy topics at ~publish_rate at rest
(copies of the last state) while the solver itself stays idle."""

import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import Marker, MarkerArray

from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
RATE = 30.0


class RepublishAtRestTest(unittest.TestCase):

    def test_heavy_topics_stay_at_rate_while_idle(self):
        rospy.init_node('test_republish_at_rest')
        f = FlsmClient()
        self.assertIsNotNone(f.settle(), 'the node did not come to rest')
        counts = {}

        def counter(name):
            counts[name] = 0

            def on_msg(_):
                counts[name] += 1
            return on_msg

        subs = [rospy.Subscriber('/flsm_node/' + name, msg_type, counter(name), queue_size=50)
                for name, msg_type in (('mesh', Marker), ('surface', PointCloud2),
                                       ('particles', PointCloud2), ('lattice', MarkerArray))]
        time.sleep(1.0)  # connections made
        steps = f.state().steps
        before, t0 = dict(counts), time.time()
        time.sleep(3.0)
        elapsed = time.time() - t0
        for s in subs:
            s.unregister()
        self.assertTrue(f.state().idle, 'the node should still be at rest')
        self.assertEqual(f.state().steps, steps, 'the solver stepped at rest')
        for name in counts:
            rate = (counts[name] - before[name]) / elapsed
            # 20 %: as the other rate checks of the suite; rospy's delivery jitters under load
            self.assertAlmostEqual(rate, RATE, delta=0.2 * RATE, msg='~%s at %.1f Hz' % (name, rate))


if __name__ == '__main__':
    rostest.rosrun(PKG, 'republish_at_rest', RepublishAtRestTest)
