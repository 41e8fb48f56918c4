#!/usr/bin/env python3
"""flsm_node with ~republish_at_rest: true keeps the markers ~mesh and ~lattice at ~publish_rate
at rest too (copies of the last state), besides the clouds ~surface and ~particles that keep it
in any case, while the solver itself stays idle."""

import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import Marker, MarkerArray

from flsm_testing import Counter, FlsmClient

PKG = 'deformable_flsm'
RATE = 30.0


class RepublishAtRestTest(unittest.TestCase):

    def test_heavy_topics_stay_at_rate_while_idle(self):
        rospy.init_node('test_republish_at_rest')
        f = FlsmClient()
        self.assertIsNotNone(f.settle(), 'the node did not come to rest')
        topics = [Counter('/flsm_node/mesh', Marker), Counter('/flsm_node/surface', PointCloud2),
                  Counter('/flsm_node/particles', PointCloud2),
                  Counter('/flsm_node/lattice', MarkerArray)]
        time.sleep(1.0)  # connections made
        steps = f.state().steps
        before, t0 = [t.count for t in topics], time.time()
        time.sleep(3.0)
        elapsed = time.time() - t0
        for t in topics:
            t.close()
        self.assertTrue(f.state().idle, 'the node should still be at rest')
        self.assertEqual(f.state().steps, steps, 'the solver stepped at rest')
        for t, b in zip(topics, before):
            rate = (t.count - b) / elapsed
            # 20 %: as the other rate checks of the suite; rospy's delivery jitters under load
            self.assertAlmostEqual(rate, RATE, delta=0.2 * RATE,
                                   msg='%s at %.1f Hz' % (t.sub.name, rate))


if __name__ == '__main__':
    rostest.rosrun(PKG, 'republish_at_rest', RepublishAtRestTest)
