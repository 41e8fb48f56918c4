#!/usr/bin/env python3
"""Three cubes of ~objects stacked on the ground (config/stack.yaml) come to rest, and each
contact carries the weight of what lies above it: the entry object/<upper>/<lower> of
~contact_wrenches pushes the lower cube down with the weight of the cubes above, the reverse
entry pushes back, the ground carries all three. Each object has its tf frame, its marker on
~mesh (namespace = its name) and its clouds and state under ~objects/<name>/."""

import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from visualization_msgs.msg import Marker

from flsm_testing import ObjectsClient

PKG = 'deformable_flsm'
NAMES = ('bottom', 'middle', 'top')
G = 9.81  # config/flsm.yaml's gravity
# At rest a contact carries the weight above within the 2 %.
WEIGHT_TOLERANCE = 0.02
# m/s: at rest. A cube bouncing on its soft neighbour with amplitude A at angular frequency w
# moves at v = A w and its contact force swings by m w^2 A = m w v about the weight: for 1 % of
# m g at w up to 2 pi 30 Hz (the cubes' lowest modes are slower), v < 0.01 g / w = 0.5 mm/s.
REST_SPEED = 0.0005
# s of ~contact_wrenches averaged (at ~publish_rate): what the rest speed leaves of a swing
# averages out.
AVERAGE_S = 1.0


class StackTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_stack')
        cls.client = ObjectsClient(NAMES)

    def rested(self):
        # 4 s of simulated time, or less when the stack came to rest before
        self.assertTrue(self.client.wait_sim_time(4.0, 180.0, or_idle_after=1.0), 'the simulation does not run')
        end = time.time() + 180.0
        while time.time() < end:
            speeds = [self.client.object_state(n).max_speed for n in NAMES]
            if self.client.state().idle or max(speeds) < REST_SPEED:
                return
            time.sleep(0.1)
        self.fail('the stack does not rest: speeds %s m/s' % speeds)

    def mean_forces(self):
        """Force of each entry of ~contact_wrenches averaged over AVERAGE_S, the last message."""
        sums, n, last = {}, 0, None
        end = time.time() + AVERAGE_S
        while time.time() < end:
            w = self.client.wrenches()
            if w is not last:
                last = w
                n += 1
                for i, x in zip(w.ids, w.wrenches):
                    f = np.array([x.wrench.force.x, x.wrench.force.y, x.wrench.force.z])
                    sums[i] = sums.get(i, 0.0) + f
            time.sleep(0.005)
        return {i: f / n for i, f in sums.items()}, last

    def test_each_contact_carries_the_weight_above(self):
        self.rested()
        mass = {n: self.client.object_state(n).mass for n in NAMES}
        force, w = self.mean_forces()
        frames = dict(zip(w.ids, [x.header.frame_id for x in w.wrenches]))
        expected = {('top', 'middle'): mass['top'] * G,
                    ('middle', 'bottom'): (mass['top'] + mass['middle']) * G}
        for (upper, lower), weight in expected.items():
            down = 'object/%s/%s' % (upper, lower)
            up = 'object/%s/%s' % (lower, upper)
            self.assertIn(down, force, 'no entry %s in %s' % (down, w.ids))
            self.assertIn(up, force, 'no entry %s in %s' % (up, w.ids))
            self.assertEqual(frames[down], 'world')
            # force on `lower` from `upper`: down by the weight above, in the simulation frame
            self.assertAlmostEqual(-force[down][2], weight, delta=WEIGHT_TOLERANCE * weight,
                                   msg='%s carries %.3f N, the weight above is %.3f N'
                                   % (down, -force[down][2], weight))
            np.testing.assert_allclose(force[up], -force[down], atol=1e-9 * weight)
        # the top and the bottom cube do not touch
        self.assertNotIn('object/top/bottom', [i for i in w.ids
                                                if w.contacts[w.ids.index(i)] > 0])
        total = sum(mass.values()) * G
        ground = force['ground']  # on the ground, in its frame (+z its outward normal)
        self.assertAlmostEqual(-ground[2], total, delta=WEIGHT_TOLERANCE * total)

    def test_each_object_has_its_frame_marker_clouds_and_state(self):
        self.rested()
        buf = tf2_ros.Buffer()
        tf2_ros.TransformListener(buf)
        z = [buf.lookup_transform('world', n, rospy.Time(0), rospy.Duration(10.0))
             .transform.translation.z for n in NAMES]
        self.assertLess(z[0], z[1])
        self.assertLess(z[1], z[2])
        seen = {}

        def on_marker(m):
            seen[m.ns] = m.id
        sub = rospy.Subscriber('/flsm_node/mesh', Marker, on_marker, queue_size=100)
        end = time.time() + 20.0
        while time.time() < end and set(seen) != set(NAMES):
            time.sleep(0.1)
        sub.unregister()
        self.assertEqual(set(seen), set(NAMES), 'markers on ~mesh: %s' % seen)
        self.assertEqual(len(set(seen.values())), len(NAMES), 'marker ids not distinct: %s' % seen)
        total = 0
        for n in NAMES:
            x = self.client.particles(n)
            s = self.client.object_state(n)
            self.assertEqual(len(x), s.particles)
            self.assertTrue(np.all(np.isfinite(x)))
            total += s.particles
        self.assertEqual(self.client.state().particles, total)  # ~state sums the objects
        whole = self.client.state().mass
        self.assertAlmostEqual(whole, sum(self.client.object_state(n).mass for n in NAMES),
                               delta=1e-9 * whole)


if __name__ == '__main__':
    rostest.rosrun(PKG, 'stack', StackTest)
