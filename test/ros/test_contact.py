#!/usr/bin/env python3
"""Contact in the default scene: the bunny dropped onto the ground comes to rest with the ground
carrying its weight and no surface point below it; a sphere pressed into the resting bunny
through ~collider meets a reaction force that grows with the depth; a drag that lifts it carries
its weight on ~contact_wrenches."""

import math
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import Point, Quaternion
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2

from deformable_flsm.msg import ColliderCommand, ContactWrenches, DragCommand
from flsm_testing import FlsmClient

PKG = 'deformable_flsm'
GROUND_FRAME = 'flsm_collider/ground'


def spacing_of(x):
    """Lattice spacing from particle positions: the median nearest-neighbour distance (the
    lattice is a cubic grid, barely strained at rest)."""
    nearest = []
    for i in range(0, len(x), 256):
        d = np.linalg.norm(x[i:i + 256, None, :] - x[None, :, :], axis=2)
        d[d == 0.0] = np.inf
        nearest.append(d.min(axis=1))
    return float(np.median(np.concatenate(nearest)))


class ContactTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_contact')
        cls.flsm = FlsmClient()
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        cls.collider_pub = rospy.Publisher('/flsm_node/collider', ColliderCommand, queue_size=10)
        end = time.time() + 10.0
        while cls.collider_pub.get_num_connections() == 0 and time.time() < end:
            time.sleep(0.05)

    def wrench(self, collider_id, timeout=5.0):
        """(force, torque, contacts) on `collider_id` from the next ~contact_wrenches."""
        msg = rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches, timeout)
        k = list(msg.ids).index(collider_id)
        w = msg.wrenches[k]
        self.assertEqual(w.header.frame_id, 'flsm_collider/' + collider_id)
        f, t = w.wrench.force, w.wrench.torque
        return np.array([f.x, f.y, f.z]), np.array([t.x, t.y, t.z]), msg.contacts[k]

    def rest(self, timeout=90.0):
        # Awake first (a command was just sent), then at rest.
        steps = self.flsm.state().steps
        self.flsm.wait_state(lambda s: s.steps > steps, 5.0)
        s = self.flsm.wait_state(lambda s: s.idle, timeout)
        self.assertIsNotNone(s, 'the bunny did not come to rest')
        return s

    def test_drop_onto_the_ground(self):
        f = self.flsm
        s = f.wait_state(lambda s: s.idle, 90.0)
        self.assertIsNotNone(s, 'the dropped bunny did not come to rest')
        self.assertEqual(s.colliders, 1)
        self.assertGreater(s.max_displacement, 0.05, 'the bunny did not fall')
        weight = s.mass * 9.81
        force, torque, contacts = self.wrench('ground')
        # The object presses on the ground along -z (the ground's outward normal is +z).
        rospy.loginfo('drop: weight %.4f N, ground force (%.4f, %.4f, %.4f) N, %d contacts, '
                      'sim time %.2f s', weight, force[0], force[1], force[2], contacts,
                      s.sim_time)
        self.assertGreater(contacts, 0)
        self.assertAlmostEqual(-force[2] / weight, 1.0, delta=0.02)
        self.assertLess(math.hypot(force[0], force[1]), 0.02 * weight)
        # No surface point below the ground by more than 10 % of the spacing.
        ground = self.tf_buffer.lookup_transform('world', GROUND_FRAME, rospy.Time(0),
                                                 rospy.Duration(5.0))
        z_ground = ground.transform.translation.z
        surface = rospy.wait_for_message('/flsm_node/surface', PointCloud2, 10.0)
        z = np.array([p[0] for p in point_cloud2.read_points(surface, field_names=('z',))])
        h = spacing_of(f.particles())
        below = z_ground - z.min()
        rospy.loginfo('drop: spacing %.4f m, lowest surface point %.5f m below the ground '
                      '(%.1f %% of the spacing)', h, below, 100.0 * below / h)
        self.assertLess(below, 0.1 * h)
        particles = f.particles()
        self.assertGreater(particles[:, 2].min(), z_ground, 'a particle centre is below ground')

    def send(self, action, collider_id, position=(0, 0, 0), kind='sphere', radius=0.02):
        m = ColliderCommand()
        m.action = action
        m.id = collider_id
        m.type = kind
        m.pose.position = Point(*position)
        m.pose.orientation = Quaternion(0, 0, 0, 1)
        m.radius = radius
        m.static_friction = 0.6
        m.kinetic_friction = 0.5
        self.collider_pub.publish(m)

    def test_indent_with_a_sphere(self):
        f = self.flsm
        self.assertIsNotNone(f.wait_state(lambda s: s.idle, 90.0))
        x = f.particles()
        # Above the middle of the bunny's back: the highest particle within 2 cm of the centre.
        c = x.mean(axis=0)
        near = x[np.hypot(x[:, 0] - c[0], x[:, 1] - c[1]) < 0.02]
        top = near[np.argmax(near[:, 2])]
        radius = 0.02
        h = spacing_of(x)
        # The sphere starts touching the particles' contact spheres (radius h / 2).
        z0 = top[2] + 0.5 * h + radius
        accepted = f.state().accepted_commands
        self.send(ColliderCommand.ADD, 'indenter', (top[0], top[1], z0), radius=radius)
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders == 2, 5.0), 'ADD not applied')
        forces = []
        for depth in (0.01, 0.02, 0.03):
            self.send(ColliderCommand.MOVE, 'indenter', (top[0], top[1], z0 - depth))
            self.rest()
            force, _, contacts = self.wrench('indenter')
            forces.append(force[2])
            rospy.loginfo('indent: depth %.3f m, reaction force %.3f N (%d contacts)', depth,
                          force[2], contacts)
        self.assertEqual(f.state().accepted_commands, accepted + 4)
        # The object pushes the sphere up, harder the deeper it is pressed.
        self.assertGreater(forces[0], 0.0)
        self.assertGreater(forces[1], forces[0])
        self.assertGreater(forces[2], forces[1])
        self.send(ColliderCommand.REMOVE, 'indenter')
        self.assertIsNotNone(f.wait_state(lambda s: s.colliders == 1, 5.0), 'REMOVE not applied')
        self.rest()  # as found: the other test may come next

    def drag_wrench(self, drag_id, timeout=5.0):
        """(force, contacts) of the entry drag/<object>/<drag_id> of the next ~contact_wrenches,
        in ~frame_id, <object> the single object's ~object_frame_id; None when there is none."""
        msg = rospy.wait_for_message('/flsm_node/contact_wrenches', ContactWrenches, timeout)
        entry = 'drag/%s/%s' % (rospy.get_param('/flsm_node/object_frame_id', 'flsm_object'), drag_id)
        if entry not in msg.ids:
            return None
        k = list(msg.ids).index(entry)
        f = msg.wrenches[k].wrench.force
        return np.array([f.x, f.y, f.z]), msg.contacts[k]

    def test_lift_by_a_drag(self):
        """A hard drag lifts the resting bunny clear of the ground: its weight moves from the
        ground's entry of ~contact_wrenches to the drag's (statics: nothing else holds it)."""
        f = self.flsm
        s = f.wait_state(lambda s: s.idle, 90.0)
        self.assertIsNotNone(s)
        weight = s.mass * 9.81
        x = f.particles()
        # The middle of the bunny's back, as the sphere's: the highest particle within 2 cm of the
        # centre
        c = x.mean(axis=0)
        near = x[np.hypot(x[:, 0] - c[0], x[:, 1] - c[1]) < 0.02]
        top = near[np.argmax(near[:, 2])]
        target = (top[0], top[1], top[2] + 0.10)
        f.drag(DragCommand.GRAB, 'lift', point=tuple(top), count=40, target=target)
        # Settled when three readings a second apart agree within 1 % of the weight.
        readings, end = [], time.time() + 120.0
        while time.time() < end:
            time.sleep(1.0)
            w = self.drag_wrench('lift')
            if w is None:
                continue
            readings.append(w[0][2])
            if len(readings) >= 3 and np.ptp(readings[-3:]) < 0.01 * weight:
                break
        self.assertGreaterEqual(len(readings), 3, 'no drag entry on ~contact_wrenches')
        force, contacts = self.drag_wrench('lift')
        ground, _, ground_contacts = self.wrench('ground')
        rospy.loginfo('lift: weight %.4f N, on the hand (%.4f, %.4f, %.4f) N from %d particles, '
                      'on the ground %.4f N from %d contacts', weight, force[0], force[1], force[2],
                      contacts, -ground[2], ground_contacts)
        self.assertEqual(contacts, 40)
        self.assertEqual(ground_contacts, 0, 'the lifted bunny still touches the ground')
        # The bunny pulls the hand down with its weight.
        self.assertAlmostEqual(-force[2] / weight, 1.0, delta=0.02)
        self.assertLess(math.hypot(force[0], force[1]), 0.02 * weight)
        f.release('lift')
        self.rest()  # as found


if __name__ == '__main__':
    rostest.rosrun(PKG, 'contact', ContactTest)
