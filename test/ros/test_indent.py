#!/usr/bin/env python3
"""The material under a finger through the node: a frictionless sphere sent on ~collider and
pressed 2 mm into the top of a block held by its base; the force on ~contact_wrenches against
Hertz's on a layer bonded to its base (indent.test)."""

import math
import time
import unittest

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import Point, Quaternion

from deformable_flsm.analytic import hertz_on_bonded_layer
from deformable_flsm.msg import ColliderCommand, ContactWrenches
from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
E, NU = 20000.0, 0.3      # indent.test
SPACING = 0.0025
TOP = 0.03                # the block's top face (m)
RADIUS = 0.02
DEPTH = 0.002


class IndentTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_indent')
        cls.flsm = FlsmClient()
        cls.pub = cls.flsm.collider_publisher()

    def send(self, action, z):
        m = ColliderCommand()
        m.action = action
        m.id = 'finger'
        m.type = 'sphere'
        m.radius = RADIUS
        m.pose.position = Point(0.0, 0.0, z)
        m.pose.orientation = Quaternion(0, 0, 0, 1)
        m.static_friction = 0.0
        m.kinetic_friction = 0.0
        self.pub.publish(m)

    def test_sphere_force_follows_hertz(self):
        f = self.flsm
        s = f.wait_state(lambda s: s.idle, 60.0)
        self.assertIsNotNone(s, 'the block did not come to rest')
        self.assertEqual(s.particles, 21 * 21 * 12)
        self.assertFalse(s.stiffness_saturated)
        # The sphere starts 0.5 mm above the top and is lowered by 0.25 mm a command (less than a
        # particle's radius: pressed in, not placed inside), 10 Hz, to DEPTH.
        z0 = TOP + RADIUS + 0.0005
        self.send(ColliderCommand.ADD, z0)
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders >= 1, 5.0), 'ADD not applied')
        travel = 0.0005 + DEPTH
        moves = int(round(travel / 0.00025))
        for k in range(1, moves + 1):
            self.send(ColliderCommand.MOVE, z0 - travel * k / moves)
            time.sleep(0.1)
        steps = f.state().steps
        f.wait_state(lambda s: s.steps > steps + 30, 10.0)
        self.assertIsNotNone(f.wait_state(lambda s: s.idle, 60.0), 'the pressed block did not rest')
        msg = rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches, 5.0)
        k = list(msg.ids).index('finger')
        force = msg.wrenches[k].wrench.force
        thickness = TOP - 0.5 * SPACING   # from the pinned centres to the top face
        hertz = hertz_on_bonded_layer(RADIUS, DEPTH, thickness, E, NU)
        rospy.loginfo('indent: %.4f N on %d particles; Hertz on the bonded layer %.4f N (%+.1f %%)',
                      force.z, msg.contacts[k], hertz, 100.0 * (force.z / hertz - 1.0))
        self.assertGreater(msg.contacts[k], 9)
        self.assertAlmostEqual(force.z / hertz, 1.0, delta=0.15)
        self.assertLess(math.hypot(force.x, force.y), 0.02 * force.z)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'indent', IndentTest)
