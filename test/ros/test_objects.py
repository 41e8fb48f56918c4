#!/usr/bin/env python3
"""Commands address an object by its namespace: a drag on ~objects/right/drag moves the right
cube and leaves the left one where it rests; ~objects/right/pin_box pins the right cube's
particles only; the top-level ~drag addresses the first object (left). Of a robot's probe
links (test/ros/objects_probes.urdf), those that start inside either cube stay out, the one
beside them joins."""

import time
import unittest

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import Point

from deformable_flsm.msg import ContactWrenches, DragCommand
from flsm_testing import ObjectsClient

PKG = 'deformable_flsm'
NAMES = ('left', 'right')
# m: the drags lift a corner particle by this much (a quarter of the 8 cm cube)
LIFT = 0.02
# m: a hard drag holds its particle at the target to round-off; a cube left alone at rest
# moves by far less than this (its creep at rest is micrometres), a dragged one by LIFT.
HELD = 1e-6
UNTOUCHED = 2e-4


class ObjectsTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_objects')
        cls.client = ObjectsClient(NAMES)
        cls.top_drag = rospy.Publisher('/flsm_node/drag', DragCommand, queue_size=10)
        end = time.time() + 30.0
        while cls.top_drag.get_num_connections() == 0 and time.time() < end:
            time.sleep(0.05)
        cls.client.wait_sim_time(2.0, 120.0)

    def rest(self):
        """Waits until both cubes rest on the ground (the node idles; a release before has been
        seen in the objects' states, so this ~state is not older than it)."""
        end = time.time() + 120.0
        while time.time() < end and not self.client.state().idle:
            time.sleep(0.1)
        self.assertTrue(self.client.state().idle, 'the cubes do not rest')

    def lift_and_check(self, name, send):
        self.rest()
        other = [n for n in NAMES if n != name][0]
        x = self.client.particles(name)
        still = self.client.particles(other)
        p = int(np.argmax(x[:, 2] + 1e-3 * x[:, 0]))
        target = x[p] + np.array([0.0, 0.0, LIFT])
        send(p, target)
        end = time.time() + 30.0
        while time.time() < end:
            moved = self.client.particles(name)
            if np.linalg.norm(moved[p] - target) < HELD:
                break
        self.assertLess(np.linalg.norm(moved[p] - target), HELD, '%s was not dragged' % name)
        self.assertEqual(self.client.object_state(name).active_drags, 1)
        self.assertEqual(self.client.object_state(other).active_drags, 0)
        self.assertLess(np.abs(self.client.particles(other) - still).max(), UNTOUCHED,
                        '%s moved while %s was dragged' % (other, name))
        return p

    def release(self, name, publish):
        m = DragCommand()
        m.action = DragCommand.RELEASE
        m.id = 'test'
        publish(m)
        end = time.time() + 10.0
        while time.time() < end and self.client.object_state(name).active_drags != 0:
            time.sleep(0.05)
        self.assertEqual(self.client.object_state(name).active_drags, 0)

    def test_a_drag_in_an_objects_namespace_moves_that_object_only(self):
        self.lift_and_check('right', lambda p, t: self.client.drag(
            'right', DragCommand.GRAB, particle=p, target=tuple(t)))
        self.release('right', self.client.drag_pubs['right'].publish)

    def test_the_top_level_drag_addresses_the_first_object(self):
        def send(p, t):
            m = DragCommand()
            m.action = DragCommand.GRAB
            m.id = 'test'
            m.particle = p
            m.target = Point(*t)
            self.top_drag.publish(m)
        self.lift_and_check('left', send)
        self.release('left', self.top_drag.publish)

    def test_pin_box_in_an_objects_namespace_pins_that_object_only(self):
        x = self.client.particles('right')
        everywhere = (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)
        res = self.client.pin_box('right', *everywhere)
        self.assertTrue(res.success, res.message)
        self.assertEqual(res.particles, len(x))
        end = time.time() + 10.0
        while time.time() < end and self.client.object_state('right').pinned_particles != len(x):
            time.sleep(0.05)
        self.assertEqual(self.client.object_state('right').pinned_particles, len(x))
        self.assertEqual(self.client.object_state('left').pinned_particles, 0)
        res = self.client.pin_box('right', *everywhere, pin=False)
        self.assertTrue(res.success, res.message)

    def test_robot_links_inside_any_object_stay_out(self):
        # ~contact_wrenches lists every collider in the scene, touching or not; the probes' frames
        # come from robot_state_publisher's /tf_static, so 'beside' joins within a few steps.
        ids = set()
        end = time.time() + 30.0
        while time.time() < end and 'robot/beside' not in ids:
            ids.update(rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches,
                                              timeout=10.0).ids)
        for _ in range(30):  # a second more of messages
            ids.update(rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches,
                                              timeout=10.0).ids)
        self.assertIn('robot/beside', ids)
        self.assertNotIn('robot/in_left', ids, 'a link inside the first object joined')
        self.assertNotIn('robot/in_right', ids, 'a link inside the second object joined')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'objects', ObjectsTest)
